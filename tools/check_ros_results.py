#!/usr/bin/env python3
"""Reads the results `moe-touch run --ros-out DIR` wrote with the `rosbags` library (its own
rosbag2 reader and CDR deserialiser, and ROS 2 Jazzy's message definitions), to check the
project's writer against a reader it did not write. Run by hand:

    moe-touch run --episode fixtures/episodes/plate_tip_front_small_ros2 --out /tmp/r.mcap \\
        --report /tmp/r.json --ros-out /tmp/results
    python3 -m venv /tmp/venv && /tmp/venv/bin/pip install rosbags numpy
    /tmp/venv/bin/python tools/check_ros_results.py /tmp/results /tmp/r.json

It deserialises every message with the Jazzy type store and with the definitions stored in the
file, checks that both agree, and compares each frame's contact points, load arrows and finger
forces with the run's report. Prints one line per frame and exits non-zero on a mismatch.
"""

import json
import sys
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore


def main(bag: Path, report_path: Path) -> int:
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    stored = get_typestore(Stores.EMPTY)
    report = json.loads(report_path.read_text())["per_frame"]
    by_time = {f["time_ns"]: f for f in report}
    failures = 0
    with Reader(bag) as reader:
        for conn in reader.connections:
            stored.register(get_types_from_msg(conn.msgdef.data, conn.msgtype))
        for conn, t, raw in reader.messages():
            a = jazzy.deserialize_cdr(raw, conn.msgtype)
            b = stored.deserialize_cdr(raw, conn.msgtype)
            if repr(a) != repr(b):
                print(f"{conn.topic} at {t}: the stored definition decodes differently")
                failures += 1
            frame = by_time[t]
            if conn.msgtype == "visualization_msgs/msg/MarkerArray":
                contacts = [m for m in a.markers if m.ns == "contacts"][0]
                loads = [m for m in a.markers if m.ns == "loads"]
                ok = len(contacts.points) == frame["contact_points"] and len(loads) == len(
                    frame["loads"]
                )
                print(f"{t} ns: {len(a.markers)} markers, {len(contacts.points)} contact points, "
                      f"{len(loads)} load arrows: {'ok' if ok else 'MISMATCH'}")
                failures += not ok
            else:
                finger = int(conn.topic.split("finger")[1].split("/")[0])
                force = np.array([a.wrench.force.x, a.wrench.force.y, a.wrench.force.z])
                expected = np.array(frame["finger_forces"][finger]["force_n"])
                if not np.allclose(force, expected, rtol=0, atol=1e-12):
                    print(f"{conn.topic} at {t}: {force} against {expected}")
                    failures += 1
    print("all messages decode and agree with the report" if not failures else
          f"{failures} mismatches")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(Path(sys.argv[1]), Path(sys.argv[2])))
