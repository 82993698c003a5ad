//! Integration tests of the physics estimator: known loads recovered from simulated markers,
//! no load reported as none, two loads told apart, and bad input refused.

mod bad_input;
mod calibration;
mod common;
mod depth;
mod large_press;
mod recovery;
