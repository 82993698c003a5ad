//! Integration tests of the simulator: mechanics against analytic solutions, tendons, contact,
//! scenes.

mod contact;
mod fixtures;
mod mechanics;
mod reference;
mod scene;
mod static_presses;
mod tangent;
mod tendons;
