//! Gaussian-process implicit surfaces (GPIS) for reconstructing occluded surfaces from contacts.
//!
//! This crate will hold exact GP regression on signed-distance observations with constant, sphere
//! and prior-mesh mean functions, hyper-parameter fitting, dense grid queries, marching cubes and
//! the paper's baselines (§6.1, App. E).
//!
//! Architecture invariant: depends only on `moe-geom`, faer and parry3d-f64. No file IO.
