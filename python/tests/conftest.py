"""Shared fixtures: the repository's files, the `moe-touch` tool, and small ROS 2 recordings
written here byte by byte (MCAP records of CDR messages), so that bad recordings can be made
without a ROS installation."""

import os
import struct
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
EPISODE = REPO / "fixtures/episodes/plate_tip_front_small.mcap"
ROS2_EPISODE = REPO / "fixtures/episodes/plate_tip_front_small_ros2"
OCCLUDING = REPO / "fixtures/physics/occluding-contact.toml"
MODEL = REPO / "models/contact-two-finger.safetensors"
DATASET = REPO / "fixtures/contact/heldout"


@pytest.fixture(scope="session")
def moe_touch_bin():
    """The `moe-touch` tool to compare against: $MOE_TOUCH_BIN, else the workspace's build.
    CI sets it; elsewhere a missing tool skips the comparisons."""
    given = os.environ.get("MOE_TOUCH_BIN")
    candidates = [Path(given)] if given else [
        REPO / "target/release/moe-touch",
        REPO / "target/debug/moe-touch",
    ]
    for c in candidates:
        if c.is_file():
            return c
    if given or os.environ.get("CI"):
        pytest.fail(f"the moe-touch tool is not at {candidates}")
    pytest.skip("no moe-touch build (cargo build -p moe-touch-cli) to compare against")


# --- CDR (little endian, with the 4-byte encapsulation header) --------------------------------


class Cdr:
    def __init__(self):
        self.b = bytearray()

    def _align(self, n):
        while len(self.b) % n:
            self.b.append(0)

    def u8(self, v):
        self.b += struct.pack("<B", v)
        return self

    def u32(self, v):
        self._align(4)
        self.b += struct.pack("<I", v)
        return self

    def i32(self, v):
        self._align(4)
        self.b += struct.pack("<i", v)
        return self

    def f64(self, v):
        self._align(8)
        self.b += struct.pack("<d", v)
        return self

    def string(self, s):
        data = s.encode() + b"\0"
        self.u32(len(data))
        self.b += data
        return self

    def f64s(self, values, sequence=True):
        if sequence:
            self.u32(len(values))
        for v in values:
            self.f64(v)
        return self

    def header(self, stamp_ns, frame):
        return self.i32(stamp_ns // 1_000_000_000).u32(stamp_ns % 1_000_000_000).string(frame)

    def finish(self):
        return b"\x00\x01\x00\x00" + bytes(self.b)


def image(stamp_ns, frame, encoding, width, height, pixel_bytes, data):
    c = Cdr().header(stamp_ns, frame).u32(height).u32(width).string(encoding).u8(0)
    c.u32(width * pixel_bytes).u32(len(data))
    c.b += data
    return c.finish()


def camera_info(stamp_ns, frame, width, height, f=100.0):
    c = Cdr().header(stamp_ns, frame).u32(height).u32(width).string("plumb_bob")
    c.f64s([0.0] * 5)
    cx, cy = (width - 1) / 2, (height - 1) / 2
    c.f64s([f, 0, cx, 0, f, cy, 0, 0, 1], sequence=False)
    c.f64s([1, 0, 0, 0, 1, 0, 0, 0, 1], sequence=False)
    c.f64s([f, 0, cx, 0, 0, f, cy, 0, 0, 0, 1, 0], sequence=False)
    c.u32(0).u32(0).u32(0).u32(0).u32(0).u32(0).u8(0)
    return c.finish()


def tf(transforms):
    """transforms: (stamp_ns, parent, child, xyz) with the identity rotation."""
    c = Cdr().u32(len(transforms))
    for stamp, parent, child, xyz in transforms:
        c.header(stamp, parent).string(child)
        c.f64s(list(xyz), sequence=False).f64s([0.0, 0.0, 0.0, 1.0], sequence=False)
    return c.finish()


def joints(stamp_ns, names, positions):
    c = Cdr().header(stamp_ns, "").u32(len(names))
    for n in names:
        c.string(n)
    return c.f64s(positions).f64s([]).f64s([]).finish()


# --- MCAP (uncompressed, no summary) and the rosbag2 directory --------------------------------


def _record(op, content):
    return struct.pack("<BQ", op, len(content)) + content


def _s(text):
    data = text.encode()
    return struct.pack("<I", len(data)) + data


def write_bag(directory, messages):
    """A rosbag2 directory with one MCAP file of `messages`: (topic, type, log_ns, cdr)."""
    directory.mkdir(parents=True)
    out = bytearray(b"\x89MCAP0\r\n")
    out += _record(0x01, _s("ros2") + _s("moe-touch tests"))
    channels = {}
    for seq, (topic, type_name, t, data) in enumerate(messages):
        if topic not in channels:
            cid = len(channels) + 1
            out += _record(0x03, struct.pack("<H", cid) + _s(type_name) + _s("ros2msg") + _s(""))
            out += _record(
                0x04, struct.pack("<HH", cid, cid) + _s(topic) + _s("cdr") + struct.pack("<I", 0)
            )
            channels[topic] = cid
        out += _record(0x05, struct.pack("<HIQQ", channels[topic], seq, t, t) + data)
    out += _record(0x0F, struct.pack("<I", 0))
    out += _record(0x02, struct.pack("<QQI", 0, 0, 0))
    out += b"\x89MCAP0\r\n"
    (directory / "rec_0.mcap").write_bytes(bytes(out))
    (directory / "metadata.yaml").write_text(
        "rosbag2_bagfile_information:\n  version: 9\n  storage_identifier: mcap\n"
        "  relative_file_paths:\n    - rec_0.mcap\n  duration:\n    nanoseconds: 1\n"
    )
    return directory


COLOR = "/camera/camera/color/image_raw"
DEPTH = "/camera/camera/aligned_depth_to_color/image_raw"
INFO = "/camera/camera/color/camera_info"
W, H = 4, 3
MS = 1_000_000
TENDONS = [f"finger{f}_tendon{t}" for f in range(2) for t in range(4)]


def recording(color_encoding="rgb8", depth_size=(W, H), late_second_frame=False):
    """Two frames of a two-finger hand as `realsense2_camera` and a robot publish them."""
    img = "sensor_msgs/msg/Image"
    m = [
        ("/tf_static", "tf2_msgs/msg/TFMessage", 0, tf([(0, "hand", "cam", (0, 0, 0.1))])),
        (INFO, "sensor_msgs/msg/CameraInfo", 0, camera_info(0, "cam", W, H)),
        ("/tf", "tf2_msgs/msg/TFMessage", 0, tf([(0, "world", "hand", (1, 0, 0))])),
        ("/hand/tendons", "sensor_msgs/msg/JointState", 0, joints(0, TENDONS, [0.001] * 8)),
    ]
    for k, t in enumerate([100 * MS, 200 * MS]):
        stamp = 50 * MS if (late_second_frame and k == 1) else t
        colour = np.full((H, W, 3), 10 * k, np.uint8).tobytes()
        m.append((COLOR, img, t, image(stamp, "cam", color_encoding, W, H, 3, colour)))
        dw, dh = depth_size
        depth = np.full((dh, dw), 500 + k, "<u2").tobytes()
        m.append((DEPTH, img, t + 5 * MS, image(stamp + 5 * MS, "cam", "16UC1", dw, dh, 2, depth)))
        m.append(("/tf", "tf2_msgs/msg/TFMessage", t, tf([(t, "world", "hand", (1, k, 0))])))
    return m
