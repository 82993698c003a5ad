//! The MOE-Touch pipeline: ties shape estimation, contact estimation and the applications
//! together, and hosts the `moe-touch` command-line tool (`src/main.rs`).
//!
//! Architecture invariant: the pipeline is library code that takes and returns in-memory values;
//! the binary only parses arguments, reads and writes files through `moe-io`, and reports.
