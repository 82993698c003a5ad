//! Integration tests of the `moe-touch` binary: one module per subcommand.

mod arap;
mod args;
mod common;
mod contact;
mod episode;
mod fuzz_boundaries;
mod hand;
mod markers;
mod models;
mod physics;
mod pipeline;
mod plane;
mod ros2;
mod sim;
mod surface;
