//! Tetrahedral corotational FEM simulation of tendon-driven soft fingers pressed against rigid
//! obstacles: the source of training data and ground truth (paper §4.3.1).
//!
//! Architecture invariant: depends only on `moe-geom`, faer and parry3d-f64. No file IO; scene
//! files are parsed by `moe-io`, and results are returned as in-memory values.
