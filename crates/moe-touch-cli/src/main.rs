//! The `moe-touch` command-line tool (the commands are in the `moe_touch_cli` library).

use std::process::ExitCode;

fn main() -> ExitCode {
    moe_touch_cli::main_with(std::env::args_os())
}
