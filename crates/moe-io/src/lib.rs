//! The artefact formats of MOE-Touch: meshes, configs, hand models, numeric tables, training
//! shards and model files. Recordings (MCAP episodes, run results for Foxglove, ROS 2 bags) are
//! `moe-record`'s; it builds on this crate's error type and atomic writes.
//!
//! # Formats
//! | what | read | write |
//! |---|---|---|
//! | meshes | OBJ ([`read_obj`]), PLY ([`read_ply`]), STL ascii/binary ([`read_stl`]), by extension ([`read_mesh`]) | OBJ, PLY ([`write_mesh`]) |
//! | coloured / scalar point data | PLY ascii, binary LE/BE, float or double ([`PlyData`]) | PLY binary LE, double |
//! | configs | JSON ([`read_json`]), TOML or JSON by extension ([`read_config`]) | JSON ([`write_json`]), TOML ([`write_toml`]) |
//! | hand models | [`load_hand_config`] (TOML/JSON, [`HandConfig`]) | — |
//! | numeric tables, points | CSV with optional header ([`read_csv`], [`read_points_csv`]) | CSV ([`write_csv`]) |
//!
//! # Units and frames
//! Lengths are metres, angles radians. A file carries no frame tag: a mesh is in the frame it
//! was written in (the CLI names it in the file name or in the accompanying JSON). Finger meshes
//! referenced by a hand config are in the finger frame (base disk at z = 0, +z along the finger,
//! +x toward the camera-facing marker side); the config gives each finger's `hand_from_finger`
//! pose.
//!
//! # Exactness
//! - OBJ: coordinates are written in the shortest decimal form that parses back to the same
//!   `f64`, so write → read is bit-exact, with the same faces in the same order. The reader
//!   keeps the file's vertex order (vertex ids in configs refer to it) even though `tobj`
//!   renumbers vertices by first use — see [`obj`]. Polygons are fan-triangulated.
//! - PLY: written as binary little-endian with `double` coordinates and `float` scalars, so
//!   points, faces, colours and scalars round-trip bit-exactly.
//! - STL: `f32` coordinates widened exactly to `f64`, then welded (tolerance
//!   [`STL_WELD_RELATIVE_TOLERANCE`] × bounding-box diagonal).
//! - JSON: serde_json prints the shortest round-trip form of every `f64`.
//!
//! # Error policy
//! Every reader returns [`IoError`] — never panics — on truncated, corrupt or inconsistent input;
//! each error names the file and, where the format says, the line, column, element or row.
//! Meshes are validated by [`moe_geom::TriMesh::new`] (non-finite coordinates, bad indices,
//! degenerate faces, non-manifold edges) and the geometric error names the vertex, face or edge.
//! (So a deformed mesh that squashes a triangle to zero area can be written but not read back as
//! a mesh; read it as [`PlyData`] instead.) `tobj` reports no positions; the OBJ reader finds the
//! line itself (by checking face indices, or by bisecting on the number of lines parsed).
//! The mesh parser crates (`tobj`, `ply-rs-bw`, `stl_io`) are fuzzed by the integration tests
//! with every prefix of valid files, byte flips and random bytes, and did not panic; as a second
//! line of defence each call into them is wrapped in `std::panic::catch_unwind`, which turns a
//! panic into [`IoError::ParserPanic`]. serde_json and toml are called directly (they are
//! fuzzed upstream, and the same tests cover them here).
//!
//! Every writer goes through [`write_atomic`]: the bytes go to a hidden temporary file in the
//! target's directory, are flushed to disk, and the file is renamed over the target. A failed
//! write leaves no file behind and never a half-written one under the final name. Writers do not
//! create directories: a missing directory is [`IoError::MissingDirectory`].

/// Atomic file replacement.
pub mod atomic;
/// JSON and TOML documents.
pub mod config;
/// Numeric CSV tables.
pub mod csv;
/// Training data sets: safetensors shards and the data set card.
pub mod dataset;
/// The crate's error type.
pub mod error;
/// Shared file helpers.
pub mod files;
/// Hand-model configs.
pub mod hand_config;
/// Mesh reading and writing by extension.
pub mod mesh_io;
/// Contact model files (weights and card) as bytes and text.
pub mod model;
/// Wavefront OBJ.
pub mod obj;
/// Stanford PLY.
pub mod ply;
/// STL.
pub mod stl;

pub use atomic::{AtomicFile, write_atomic};
pub use config::{parse_json, parse_toml, read_config, read_json, write_json, write_toml};
pub use csv::{
    CsvTable, csv_bytes, read_csv, read_csv_from, read_points_csv, read_points_csv_from, write_csv,
};
pub use dataset::{
    DatasetCard, DatasetFrame, DatasetLayout, DatasetReader, LabelledFrames, Split, SplitFractions,
    read_shard, split_of, write_shard,
};
pub use error::IoError;
pub use files::{MEMORY, guarded, read_bytes};
pub use hand_config::{FingerConfig, HandConfig, TendonConfig, load_hand_config};
pub use mesh_io::{read_mesh, write_mesh};
pub use model::{ModelFiles, read_model_files, write_model_files};
pub use obj::{obj_bytes, read_obj, read_obj_from, write_obj};
pub use ply::{PlyData, ply_bytes, read_ply, read_ply_from, write_ply};
pub use stl::{STL_WELD_RELATIVE_TOLERANCE, read_stl, read_stl_from};
