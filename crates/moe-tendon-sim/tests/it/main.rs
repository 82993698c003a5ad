//! Integration tests of the simulator: mechanics against analytic solutions, tendons, contact,
//! scenes.

mod contact;
mod fixtures;
mod mechanics;
mod scene;
mod tangent;
mod tendons;
