"""A long run from Python: two pipelines in two threads, each on the committed episode looped
for FRAMES frames with advancing times, a 2 s gap (a restart) every 350 frames, a reset every
1,001 and a refused frame (its time repeated) every 997, as `moe-touch eval soak` runs it.
Prints, per window of 1,000 frames and thread, the median and p99 frame time and the resident
memory, then one JSON line with the figures.

    python python/examples/soak.py [FRAMES] [WINDOW]
"""

import json
import sys
import threading
import time

import numpy as np

import moe_touch as mt

EPISODE = "fixtures/episodes/plate_tip_front_small.mcap"
GAP_EVERY, GAP_SECS, RESET_EVERY, REFUSE_EVERY = 350, 2.0, 1001, 997


def resident_mib():
    """The process's resident memory, MiB (Linux; None elsewhere)."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024
    except OSError:
        pass
    return None


def soak(pipeline, episode, frames, window, windows):
    """Runs one pipeline; appends per window (median ms, p99 ms, failures) to `windows`."""
    frames_list = list(episode)
    spacing = frames_list[1].time - frames_list[0].time
    offset, previous, times, failed, refused = 0.0, None, [], 0, 0
    for k in range(frames):
        if k and k % GAP_EVERY == 0:
            offset += GAP_SECS
        if k and k % RESET_EVERY == 0:
            pipeline.reset()
        f = frames_list[k % len(frames_list)]
        refuse = k > 0 and k % REFUSE_EVERY == 0 and previous is not None
        t = previous if refuse else frames_list[0].time + k * spacing + offset
        start = time.perf_counter()
        try:
            pipeline.process(f.color, f.depth, f.world_from_hand, f.pulls, time=t)
            previous = t
            times.append(1e3 * (time.perf_counter() - start))
        except mt.MoeTouchError as e:
            if refuse and e.stage == "input":
                refused += 1
            else:
                failed += 1
        if (k + 1) % window == 0 or k + 1 == frames:
            ms = np.array(times) if times else np.zeros(1)
            windows.append({
                "frames": k + 1,
                "median_ms": float(np.median(ms)),
                "p99_ms": float(np.percentile(ms, 99, method="inverted_cdf")),
                "failed": failed,
                "refused": refused,
                "resident_mib": resident_mib(),
            })
            times, failed, refused = [], 0, 0


def main(frames=20_000, window=1_000):
    episode = mt.read_episode(EPISODE)
    hand = mt.Hand.preset("two-finger")
    results = [[], []]
    threads = [
        threading.Thread(
            target=soak,
            args=(mt.Pipeline.physics(hand, episode.camera), episode, frames, window, results[i]),
        )
        for i in range(2)
    ]
    start = time.perf_counter()
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    seconds = time.perf_counter() - start
    for i, windows in enumerate(results):
        for w in windows:
            print(f"thread {i} frames {w['frames']:>6}: median {w['median_ms']:.1f} ms, "
                  f"p99 {w['p99_ms']:.1f} ms, {w['failed']} failed, {w['refused']} refused, "
                  f"{w['resident_mib']} MiB")
    first, last = results[0][0], results[0][-1]
    summary = {
        "frames_per_thread": frames,
        "seconds": seconds,
        "failed": sum(w["failed"] for r in results for w in r),
        "refused": sum(w["refused"] for r in results for w in r),
        "resident_growth": (last["resident_mib"] / first["resident_mib"] - 1)
        if first["resident_mib"] else None,
        "p99_drift": [r[-1]["p99_ms"] / r[0]["p99_ms"] - 1 for r in results if len(r) > 1],
    }
    print(json.dumps(summary))
    return summary


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
