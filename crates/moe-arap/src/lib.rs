//! Smoothed as-rigid-as-possible (SR-ARAP) shape estimation of soft fingers from tracked keypoints.
//!
//! This crate will hold the SR-ARAP solver (Levi & Gotsman) for closed triangle meshes with hard
//! handle constraints, and the multi-finger shape estimator of the paper (§4.2, App. B, App. C).
//!
//! Architecture invariant: depends only on `moe-geom` (vocabulary types, cotangent weights) and
//! faer (sparse Cholesky). No file IO, no candle, no simulator.
