"""Long calls release the GIL: another Python thread runs while the pipeline works."""

import threading
import time

import moe_touch as mt
from conftest import EPISODE, OCCLUDING


def test_a_thread_keeps_running_during_a_pipeline_call():
    episode = mt.read_episode(EPISODE)
    pipeline = mt.Pipeline.physics(mt.Hand.preset("two-finger"), episode.camera, config=OCCLUDING)
    f = episode[3]
    ticks = []
    stop = threading.Event()

    def tick():
        while not stop.is_set():
            ticks.append(time.perf_counter())

    thread = threading.Thread(target=tick)
    thread.start()
    try:
        time.sleep(0.01)
        start = time.perf_counter()
        result = pipeline.process(f.color, f.depth, f.world_from_hand, f.pulls)
        end = time.perf_counter()
    finally:
        stop.set()
        thread.join()
    inside = [t for t in ticks if start < t < end]
    # Holding the GIL for the call would leave the other thread no tick inside it.
    assert result.timings.total_ms > 1.0
    assert len(inside) > 100, f"{len(inside)} ticks during a {1e3 * (end - start):.0f} ms call"


def test_asking_a_busy_pipeline_for_its_settings_does_not_wait():
    episode = mt.read_episode(EPISODE)
    pipeline = mt.Pipeline.physics(mt.Hand.preset("two-finger"), episode.camera, config=OCCLUDING)
    f = episode[3]
    started, times = threading.Event(), {}

    def process():
        started.set()
        pipeline.process(f.color, f.depth, f.world_from_hand, f.pulls)
        times["processed"] = time.perf_counter()

    thread = threading.Thread(target=process)
    thread.start()
    started.wait()
    time.sleep(0.005)
    method, threshold = pipeline.method, pipeline.threshold
    times["asked"] = time.perf_counter()
    thread.join()
    assert method == "physics" and 0 < threshold <= 1
    # The answers came while the frame was still being processed.
    assert times["asked"] < times["processed"]
