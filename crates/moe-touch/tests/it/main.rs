//! Integration tests of the `moe-touch` binary: one module per subcommand.

mod common;
mod hand;
mod sim;
mod arap;
mod surface;
mod episode;
