//! Project automation, run as `cargo xtask <command>`: thin commands over library code.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod ci;
mod eval;
mod eval_contact;
mod eval_grasp;
mod eval_labels;
mod eval_markers;
mod eval_patting;
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
            eprintln!("xtask: error: {err:#}");
            ExitCode::FAILURE
        }
    }
}
