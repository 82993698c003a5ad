//! Robot logs in and out: recorded episodes, pipeline results for Foxglove, ROS 2 bags.
//!
//! | what | read | write |
//! |---|---|---|
//! | episodes (the wrist camera's RGB-D, poses, tendon pulls, ground truth) | MCAP with Foxglove schemas ([`read_episode`], [`read_episode_prefix`] for a file cut short; [`ros2::read_recording`] for either kind of log) | [`write_episode`], streaming [`EpisodeWriter`] |
//! | pipeline results over an episode | — | MCAP for Foxglove ([`write_run`], streaming [`RunWriter`]) |
//! | ROS 2 recordings (rosbag2, MCAP storage, CDR messages) | [`ros2::read_ros2_bag`] with a TF buffer and time sync | [`ros2::write_ros2_bag`], [`ros2::write_ros2_results`] |
//!
//! The episode types ([`Episode`], [`EpisodeFrame`], [`EpisodeInfo`]) are plain data and need
//! no feature; everything that reads or writes MCAP is behind the default `mcap` feature, so a
//! runtime that decodes its own frames builds without the MCAP, zstd and Foxglove crates.
//!
//! Errors are `moe-io`'s [`IoError`](moe_io::IoError): they name the file and, where the format
//! says, the message or item at fault. Writers go through `moe-io`'s atomic writes: a failed
//! write leaves no file behind.

/// Recorded episodes: MCAP with Foxglove schemas.
pub mod episode;
/// ROS 2 recordings (rosbag2 with MCAP storage, CDR messages): recordings in, episodes and
/// pipeline results out.
#[cfg(feature = "mcap")]
pub mod ros2;
/// Pipeline results over an episode, as MCAP for Foxglove.
#[cfg(feature = "mcap")]
pub mod run_output;

pub use episode::{CameraInfo, Episode, EpisodeFrame, EpisodeInfo, ObstacleMesh};
#[cfg(feature = "mcap")]
pub use episode::{
    EpisodeWriter, create_episode, parse_episode, parse_episode_prefix, read_episode,
    read_episode_prefix, write_episode,
};
#[cfg(feature = "mcap")]
pub use run_output::{
    FingerForceMessage, FingerForcesMessage, JsonTime, RUN_TOPICS, RunForces, RunFrame, RunInfo,
    RunLoad, RunTruth, RunWriter, probability_colour, viridis_colour, write_run,
};
