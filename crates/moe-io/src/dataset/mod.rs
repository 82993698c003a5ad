//! Training data sets: safetensors shards of labelled frames plus a JSON data set card.
//!
//! A data set is a directory:
//!
//! ```text
//! DIR/card.json                 the DatasetCard: layout, counts, contact ratios, per-family statistics
//! DIR/shard-00000-of-00008.safetensors
//! ...
//! ```
//!
//! Each shard stacks its frames along the first axis of these tensors (`F` frames, `V` surface
//! vertices of the whole hand, `M` markers, `T` tendons, `P` object parameters, `N_fingers`
//! fingers):
//!
//! | tensor | dtype | shape | content |
//! |---|---|---|---|
//! | `trajectory_id` | U64 | `[F]` | trajectory the frame belongs to |
//! | `frame_index` | U32 | `[F]` | frame number within its trajectory |
//! | `vertices` | F32 | `[F, V, 3]` | deformed surface vertices, hand frame, metres, fingers concatenated |
//! | `contact` | U8 | `[F, V]` | 1 where the vertex is in contact, by the card's label rule |
//! | `contact_force_n` | F32 | `[F, V]` | normal magnitude of the obstacles' penalty force on the vertex, newtons |
//! | `obstacle_distance_m` | F32 | `[F, V]` | smallest signed distance to an obstacle, metres (+∞ without one) |
//! | `markers` | F32 | `[F, M, 3]` | ground-truth marker centres, hand frame |
//! | `world_from_hand` | F64 | `[F, 7]` | wrist pose: translation xyz, quaternion xyzw |
//! | `tendon_pull_m` | F32 | `[F, T]` | pulled length of every tendon, fingers concatenated |
//! | `object_family` | U8 | `[F]` | index into the layout's `object_families` |
//! | `object_params` | F32 | `[F, P]` | the object's family parameters (zero-padded) |
//! | `finger_force_n` | F32 | `[F, N_fingers, 3]` | net contact force on each finger, hand frame, newtons (format version 2) |
//!
//! `finger_force_n` is the vector sum of the penalty forces on a finger's vertices, so it is the
//! force the object exerts on the finger; the sum of the finger's `contact_force_n` magnitudes
//! overstates it where the vertices are pushed different ways (on an edge of the object, or
//! squeezed from two sides). Shards of format version 1 lack the tensor and read with
//! [`DatasetFrame::finger_force_n`](crate::dataset::DatasetFrame::finger_force_n) `None`;
//! [`DatasetCard::has_finger_force`](crate::dataset::DatasetCard::has_finger_force) says whether
//! every frame of a data set has it (the card counts those frames in
//! [`FrameStats::force_frames`](crate::dataset::FrameStats::force_frames)). The card's
//! `format_version` is the version of the writer
//! ([`FORMAT_VERSION`](crate::dataset::FORMAT_VERSION)).
//!
//! The shard's safetensors metadata holds the layout as JSON under `moe_touch_layout`. In Python:
//!
//! ```python
//! from safetensors.numpy import load_file
//! shard = load_file("DIR/shard-00000-of-00008.safetensors")
//! shard["vertices"].shape   # (F, V, 3), float32
//! ```
//!
//! Shards are written atomically (temporary file, then rename), so an interrupted generator
//! loses at most the shard in progress. A shard is one safetensors document, stored tensor by
//! tensor, so a damaged shard is rejected whole with an error naming the file. Splits into
//! training, validation and test sets are by trajectory, never by frame ([`split_of`]).

mod card;
mod frame;
mod reader;
mod shard;
mod split;
#[cfg(test)]
mod tests;

pub use card::{CARD_FILE, DatasetCard, FORMAT_VERSION, FrameStats, ShardEntry, shard_stats};
pub use frame::{DatasetFrame, DatasetLayout};
pub use reader::{DatasetFrames, DatasetReader, LabelledFrames};
pub use shard::{LAYOUT_KEY, parse_shard, read_shard, shard_bytes, shard_file_name, write_shard};
pub use split::{Split, SplitFractions, split_of};
