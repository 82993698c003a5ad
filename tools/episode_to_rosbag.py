#!/usr/bin/env python3
"""Writes a simulated episode as a ROS 2 recording with the `rosbags` library (its own CDR
serialiser and MCAP writer), to check the project's ROS 2 reader against a writer it did not
write. Run by hand; the result is committed as a test fixture.

    cargo run -p moe-record --example export_episode -- fixtures/episodes/plate_tip_front_small.mcap /tmp/ep
    python3 -m venv /tmp/venv && /tmp/venv/bin/pip install rosbags numpy
    /tmp/venv/bin/python tools/episode_to_rosbag.py /tmp/ep fixtures/episodes/plate_tip_front_small_ros2

Topics are those `realsense2_camera` publishes (colour `rgb8`, depth aligned to colour `16UC1`
in millimetres, camera info), `/tf_static` (hand -> camera_color_optical_frame), `/tf`
(world -> hand) and `/hand/tendons` (sensor_msgs/JointState, the pulls as positions, joints
`finger{i}_tendon{j}`): the defaults of `moe_record::ros2::RosConfig`.
"""

import json
import sys
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

COLOR = "/camera/camera/color/image_raw"
DEPTH = "/camera/camera/aligned_depth_to_color/image_raw"
INFO = "/camera/camera/color/camera_info"
CAMERA_FRAME = "camera_color_optical_frame"


def main(src: Path, dst: Path) -> None:
    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    Time = T["builtin_interfaces/msg/Time"]
    Header = T["std_msgs/msg/Header"]
    Image = T["sensor_msgs/msg/Image"]
    CameraInfo = T["sensor_msgs/msg/CameraInfo"]
    RegionOfInterest = T["sensor_msgs/msg/RegionOfInterest"]
    JointState = T["sensor_msgs/msg/JointState"]
    TFMessage = T["tf2_msgs/msg/TFMessage"]
    TransformStamped = T["geometry_msgs/msg/TransformStamped"]
    Transform = T["geometry_msgs/msg/Transform"]
    Vector3 = T["geometry_msgs/msg/Vector3"]
    Quaternion = T["geometry_msgs/msg/Quaternion"]

    doc = json.loads((src / "frames.json").read_text())
    cam = doc["camera"]
    w, h = cam["width"], cam["height"]

    def header(t_ns: int, frame: str):
        return Header(stamp=Time(sec=t_ns // 10**9, nanosec=t_ns % 10**9), frame_id=frame)

    def transform(t_ns: int, parent: str, child: str, pose):
        (x, y, z), (qx, qy, qz, qw) = pose["translation"], pose["rotation_xyzw"]
        return TransformStamped(
            header=header(t_ns, parent),
            child_frame_id=child,
            transform=Transform(
                translation=Vector3(x=x, y=y, z=z),
                rotation=Quaternion(x=qx, y=qy, z=qz, w=qw),
            ),
        )

    fingers = len(doc["frames"][0]["tendon_pull_m"])
    tendons = len(doc["frames"][0]["tendon_pull_m"][0])
    names = [f"finger{i}_tendon{j}" for i in range(fingers) for j in range(tendons)]
    with Writer(dst, version=9, storage_plugin=StoragePlugin.MCAP) as bag:
        conns = {
            topic: bag.add_connection(topic, ty, typestore=ts)
            for topic, ty in [
                ("/tf_static", TFMessage.__msgtype__),
                (INFO, CameraInfo.__msgtype__),
                (COLOR, Image.__msgtype__),
                (DEPTH, Image.__msgtype__),
                ("/tf", TFMessage.__msgtype__),
                ("/hand/tendons", JointState.__msgtype__),
            ]
        }

        def put(topic, t_ns, msg):
            bag.write(conns[topic], t_ns, ts.serialize_cdr(msg, msg.__msgtype__))

        put("/tf_static", 0, TFMessage(transforms=[transform(0, "hand", CAMERA_FRAME, doc["hand_from_camera"])]))
        k_matrix = np.array([cam["fx"], 0, cam["cx"], 0, cam["fy"], cam["cy"], 0, 0, 1], dtype=np.float64)
        p_matrix = np.array([cam["fx"], 0, cam["cx"], 0, 0, cam["fy"], cam["cy"], 0, 0, 0, 1, 0], dtype=np.float64)
        for k, frame in enumerate(doc["frames"]):
            t = frame["time_ns"]
            info = CameraInfo(
                header=header(t, CAMERA_FRAME), height=h, width=w, distortion_model="plumb_bob",
                d=np.zeros(5), k=k_matrix, r=np.eye(3).reshape(9), p=p_matrix,
                binning_x=0, binning_y=0,
                roi=RegionOfInterest(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
            )
            put(INFO, t, info)
            color = np.fromfile(src / f"color_{k}.bin", dtype=np.uint8)
            put(COLOR, t, Image(header=header(t, CAMERA_FRAME), height=h, width=w, encoding="rgb8",
                                is_bigendian=0, step=3 * w, data=color))
            depth_m = np.fromfile(src / f"depth_{k}.bin", dtype="<f4")
            depth_mm = np.clip(np.rint(depth_m * 1000.0), 0, 65535).astype("<u2")
            put(DEPTH, t, Image(header=header(t, CAMERA_FRAME), height=h, width=w, encoding="16UC1",
                                is_bigendian=0, step=2 * w, data=depth_mm.view(np.uint8)))
            put("/tf", t, TFMessage(transforms=[transform(t, "world", "hand", frame["world_from_hand"])]))
            pulls = np.array([p for finger in frame["tendon_pull_m"] for p in finger], dtype=np.float64)
            put("/hand/tendons", t, JointState(header=header(t, ""), name=names, position=pulls,
                                               velocity=np.zeros(0), effort=np.zeros(0)))


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: episode_to_rosbag.py EXPORT_DIR BAG_DIR")
    main(Path(sys.argv[1]), Path(sys.argv[2]))
