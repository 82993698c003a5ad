//! ROS 2 recordings in: a rosbag2 directory (its `metadata.yaml` and MCAP storage) or one MCAP
//! file whose messages are CDR, read into an [`Episode`](crate::Episode) the pipeline runs on.
//!
//! | what | message | default topic (`realsense2_camera`) |
//! |---|---|---|
//! | colour | `sensor_msgs/msg/Image`, `rgb8` or `bgr8` | `/camera/camera/color/image_raw` |
//! | depth, aligned to colour | `sensor_msgs/msg/Image`, `16UC1` (mm) or `32FC1` (m) | `/camera/camera/aligned_depth_to_color/image_raw` |
//! | intrinsics | `sensor_msgs/msg/CameraInfo` | `/camera/camera/color/camera_info` |
//! | poses | `tf2_msgs/msg/TFMessage` | `/tf`, `/tf_static` |
//! | tendon pulls | `sensor_msgs/msg/JointState` (position, metres) | `/hand/tendons` |
//!
//! Topics, frame names, the pairing tolerance and the joint name of every tendon come from a
//! [`RosConfig`](crate::ros2::RosConfig) (a small TOML file). A frame is a colour image and the
//! depth image nearest to it in time (within the tolerance), the hand's pose in the world from TF
//! at the colour image's stamp (interpolated between the stamped transforms around it, as tf2 does;
//! outside their span the nearest, where tf2 would refuse; static transforms always), and the
//! tendon pulls of the latest joint state at or before it. The camera's mounting on the hand is the
//! TF path from the hand frame to the colour image's frame. Recordings have no ground truth: the
//! frames' truth fields are empty. A frame's time is its colour image's stamp (nanoseconds since
//! the epoch), so that results written back
//! ([`write_ros2_results`](crate::ros2::write_ros2_results)) line up with the robot's own
//! recording.

/// CDR decoding of the messages.
pub mod cdr;

mod bag;
mod write;

pub use bag::{RosConfig, is_ros2_recording, read_ros2_bag};

/// Reads a robot log as an episode: a ROS 2 recording of `hand` when `ros` names its topics or
/// `path` is one (with `ros`, or the default topics), else an episode MCAP, which may be cut
/// short (then the frames before the cut, and the error at it).
///
/// # Errors
/// As [`read_ros2_bag`] and [`read_episode_prefix`](crate::read_episode_prefix).
pub fn read_recording(
    path: &std::path::Path,
    ros: Option<&RosConfig>,
    hand: &moe_geom::HandModel,
) -> Result<(crate::Episode, Option<moe_io::IoError>), moe_io::IoError> {
    if ros.is_some() || is_ros2_recording(path) {
        let default = RosConfig::default();
        return Ok((read_ros2_bag(path, ros.unwrap_or(&default), hand)?, None));
    }
    crate::read_episode_prefix(path)
}
pub use write::{
    CAMERA_FRAME, DepthEncoding, RESULT_MARKERS_TOPIC, result_wrench_topic, write_ros2_bag,
    write_ros2_results,
};
