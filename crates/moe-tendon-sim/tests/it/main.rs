//! Integration tests of the simulator: mechanics against analytic solutions, tendons, contact,
//! scenes.

mod mechanics;
mod tendons;
