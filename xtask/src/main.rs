//! Project automation, run as `cargo xtask <command>`: the checks CI runs and the golden
//! fixtures; `gen-data`, `train`, `eval` and `heldout-shard` are the `moe-touch` tool's commands
//! of the same names (`moe_touch_cli`), reachable here too.

use std::ffi::OsString;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod ci;

#[derive(Debug, Parser)]
#[command(name = "xtask", about = "MOE-Touch project automation")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run every check, cheapest first: fmt, clippy, tests (golden fixtures among them), docs,
    /// cargo-deny.
    Ci(ci::CiArgs),
    /// Check the golden fixtures against freshly computed results, or rewrite them.
    Fixtures(FixturesArgs),
    /// `moe-touch gen-data`, `train`, `eval` or `heldout-shard` with the same arguments.
    #[command(external_subcommand)]
    Tool(Vec<OsString>),
}

/// Arguments of `cargo xtask fixtures`.
#[derive(Debug, clap::Args)]
struct FixturesArgs {
    /// Recompute every golden fixture and fail on any difference.
    #[arg(long, conflicts_with = "update", required_unless_present = "update")]
    check: bool,
    /// Recompute every golden fixture and overwrite the committed files.
    #[arg(long)]
    update: bool,
}

/// The tool's commands that `cargo xtask` forwards.
const FORWARDED: [&str; 4] = ["gen-data", "train", "eval", "heldout-shard"];

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Ci(args) => ci::run(&args),
        Command::Fixtures(args) => moe_touch_cli::golden::run(if args.update {
            moe_touch_cli::golden::Mode::Update
        } else {
            moe_touch_cli::golden::Mode::Check
        }),
        Command::Tool(args) => {
            let known = args
                .first()
                .and_then(|a| a.to_str())
                .is_some_and(|a| FORWARDED.contains(&a));
            if !known {
                eprintln!(
                    "xtask: error: unknown command {:?} (ci, fixtures, or one of the tool's {})",
                    args.first().cloned().unwrap_or_default(),
                    FORWARDED.join(", ")
                );
                return ExitCode::FAILURE;
            }
            return moe_touch_cli::main_with(std::iter::once("moe-touch".into()).chain(args));
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("xtask: error: {}", moe_touch::error::one_line(err.as_ref()));
            ExitCode::FAILURE
        }
    }
}
