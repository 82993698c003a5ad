"""What the Python binding costs per frame: the wall time of `Pipeline.process` from Python
against the Rust pipeline's own time for the same call (`FrameEstimate.timings.total_ms`, taken
inside Rust around every stage). The difference is the binding: argument checks, the GIL
released and taken back, the result converted to numpy.

    python python/examples/overhead.py [--passes N]

Build the package optimised first (`pip install ./python`); a dev build measures the dev build.
"""

import argparse
import statistics
import time
from pathlib import Path

import moe_touch as mt

REPO = Path(__file__).resolve().parents[2]
EPISODE = REPO / "fixtures/episodes/plate_tip_front_small.mcap"
SETTINGS = REPO / "fixtures/physics/occluding-contact.toml"
MODEL = REPO / "models/contact-two-finger.safetensors"


def measure(pipeline, episode, passes):
    wall, rust = [], []
    for _ in range(passes):
        pipeline.reset()
        for f in episode:
            t = time.perf_counter()
            r = pipeline.process(f.color, f.depth, f.world_from_hand, f.pulls, time=f.time)
            wall.append(1e3 * (time.perf_counter() - t))
            rust.append(r.timings.total_ms)
    extra = [w - r for w, r in zip(wall, rust)]
    return statistics.median(wall), statistics.median(rust), statistics.median(extra), sum(wall), sum(rust)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--passes", type=int, default=5)
    args = parser.parse_args()
    episode = mt.read_episode(EPISODE)
    hand = mt.Hand.preset("two-finger")
    pipelines = {
        "physics": mt.Pipeline.physics(hand, episode.camera, config=SETTINGS),
        "dgcnn": mt.Pipeline.paper(hand, episode.camera, MODEL),
    }
    print("pipeline  frames  median Python ms  median Rust ms  median binding ms  total overhead")
    for name, pipeline in pipelines.items():
        wall, rust, extra, wall_sum, rust_sum = measure(pipeline, episode, args.passes)
        print(f"{name:8s}  {args.passes * len(episode):6d}  {wall:16.2f}  {rust:14.2f}  "
              f"{extra:17.3f}  {100 * (wall_sum - rust_sum) / rust_sum:13.2f} %")


if __name__ == "__main__":
    main()
