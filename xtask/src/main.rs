//! Project automation, run as `cargo xtask <command>`: thin commands over library code.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod ci;
mod eval;
mod eval_contact;
mod eval_grasp;
mod eval_labels;
mod eval_markers;
mod eval_observability;
mod eval_patting;
mod eval_physics;
mod figure;
mod fixtures;
mod gen_data;
mod train;

#[derive(Debug, Parser)]
#[command(name = "xtask", about = "MOE-Touch project automation")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run every check, cheapest first: fmt, clippy, tests, docs, golden fixtures, cargo-deny.
    Ci(ci::CiArgs),
    /// Run an evaluation benchmark (`surface`: GPIS reconstruction on head and arm scenes).
    Eval(eval::EvalArgs),
    /// Generate a labelled training set with the tendon FEM simulator (sharded, resumable).
    GenData(gen_data::GenDataArgs),
    /// Train the contact network on a generated data set (checkpoints every epoch, resumable).
    Train(train::TrainArgs),
    /// Check the golden fixtures against freshly computed results, or rewrite them.
    Fixtures(fixtures::FixturesArgs),
    /// Write a small data set of held-out frames (the golden regression's input).
    HeldoutShard(eval_contact::HeldoutArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Ci(args) => ci::run(&args),
        Command::Eval(args) => eval::run(&args),
        Command::GenData(args) => gen_data::run(&args),
        Command::Fixtures(args) => fixtures::run(&args),
        Command::Train(args) => train::run(&args),
        Command::HeldoutShard(args) => eval_contact::write_heldout(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("xtask: error: {}", moe_touch::error::one_line(err.as_ref()));
            ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Options that size a run are refused outside their range when they are parsed, before any
    /// data is loaded.
    #[test]
    fn sizing_options_are_bounded_when_parsed() {
        let parse = |args: &[&str]| Cli::try_parse_from(["xtask"].iter().chain(args));
        let train = ["train", "--data", "d", "--out", "o"];
        let with = |extra: &[&'static str]| {
            let mut v: Vec<&str> = train.to_vec();
            v.extend_from_slice(extra);
            v
        };
        assert!(parse(&with(&["--epochs", "10000", "--batch-size", "4096"])).is_ok());
        assert!(parse(&with(&["--k", "256", "--edge-widths", "1,8192,3"])).is_ok());
        for bad in [
            &["--epochs", "0"][..],
            &["--epochs", "10001"],
            &["--batch-size", "0"],
            &["--batch-size", "4097"],
            &["--max-frames", "0"],
            &["--k", "0"],
            &["--k", "257"],
            &["--edge-widths", "64,0,256"],
            &["--head-widths", "512,8193"],
            &["--lr-step-epochs", "0"],
        ] {
            let err = parse(&with(bad)).unwrap_err();
            assert_eq!(
                err.kind(),
                clap::error::ErrorKind::ValueValidation,
                "{bad:?}"
            );
        }
        let heldout = |extra: &[&'static str]| {
            let mut v = vec!["heldout-shard", "--data", "d"];
            v.extend_from_slice(extra);
            parse(&v)
        };
        assert!(heldout(&["--trajectories", "1", "--frames", "1"]).is_ok());
        for (bad, arg) in [
            (
                &["--trajectories", "0"][..],
                "--trajectories <TRAJECTORIES>",
            ),
            (&["--frames", "0"], "--frames <FRAMES>"),
        ] {
            let err = heldout(bad).unwrap_err();
            assert_eq!(
                err.kind(),
                clap::error::ErrorKind::ValueValidation,
                "{bad:?}"
            );
            assert_eq!(
                err.get(clap::error::ContextKind::InvalidArg),
                Some(&clap::error::ContextValue::String(arg.into())),
                "{bad:?}: {err}"
            );
        }
    }
}
