//! Contact estimation on deformed soft-finger meshes.
//!
//! This crate will hold the contact estimators behind one `ContactEstimator` trait: the DGCNN of
//! the paper (§4.3.2, App. D; three EdgeConv layers of widths 64/128/256 with k = 30, a shared MLP
//! 512 → 256 → 2, weighted cross-entropy), built on candle, and a k-nearest-neighbour baseline
//! that looks up the training example with the closest keypoints (paper §5.1). Training and
//! evaluation live here as library code; `xtask train` is a thin command over them.
//!
//! Architecture invariant: this is the only crate that depends on candle. It takes and returns
//! in-memory values (meshes in the hand frame, per-vertex probabilities) and does no file IO;
//! dataset shards and model files are read and written by `moe-io`. It depends on `moe-geom` for
//! vocabulary types and on nothing else of this workspace.
