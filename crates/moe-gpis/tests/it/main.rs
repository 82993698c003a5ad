//! Integration tests of `moe-gpis` through its public API.

mod bad_input;
mod benchmark;
mod scale;
