"""The pipeline from Python gives what the `moe-touch` tool gives on the same frames."""

import json
import subprocess

import numpy as np
import pytest

import moe_touch as mt
from conftest import EPISODE, MODEL, OCCLUDING, ROS2_EPISODE


def rust_report(tool, tmp_path, *extra):
    report = tmp_path / "report.json"
    subprocess.run(
        [str(tool), "run", "--episode", str(EPISODE), "--out", str(tmp_path / "r.mcap"),
         "--report", str(report), *extra],
        check=True, capture_output=True,
    )
    return json.loads(report.read_text())["per_frame"]


def python_run(pipeline, episode):
    return [pipeline.process(f.color, f.depth, f.world_from_hand, f.pulls, time=f.time)
            for f in episode]


def assert_frames_equal(ours, theirs, episode):
    assert len(ours) == len(theirs) == len(episode)
    for r, rep, f in zip(ours, theirs, episode):
        assert rep["time_ns"] == f.time_ns
        assert r.markers_found == rep["markers_found"]
        assert r.fingers_without_markers == rep["fingers_without_markers"]
        assert r.num_contacts == rep["contact_points"]
        assert r.stream == rep["stream"]["kind"]


def test_the_demo_episode_through_the_physics_pipeline_equals_the_tools_run(moe_touch_bin, tmp_path):
    theirs = rust_report(moe_touch_bin, tmp_path, "--physics-config", str(OCCLUDING))
    episode = mt.read_episode(EPISODE)
    pipeline = mt.Pipeline.physics(mt.Hand.preset("two-finger"), episode.camera, config=OCCLUDING)
    ours = python_run(pipeline, episode)
    assert_frames_equal(ours, theirs, episode)
    assert sum(r.num_contacts for r in ours) > 0, "the demo presses a finger"
    for r, rep in zip(ours, theirs):
        forces = np.array([f["force_n"] for f in rep["finger_forces"]])
        np.testing.assert_allclose(r.finger_force_n, forces, rtol=0, atol=1e-9)
        np.testing.assert_allclose(
            r.pressed_probability, [f["pressed_probability"] for f in rep["finger_forces"]],
            rtol=0, atol=1e-12)
        assert len(r.loads) == len(rep["loads"])
        for load, expected in zip(r.loads, rep["loads"]):
            assert load.finger == expected["finger"] and load.vertex == expected["vertex"]
            np.testing.assert_allclose(load.force, expected["force_n"], rtol=0, atol=1e-9)
        # Per-vertex forces sum to the finger's force; contact points sit on the surface.
        for f, vf in enumerate(r.vertex_force_n):
            np.testing.assert_allclose(vf.sum(axis=0), r.finger_force_n[f], atol=1e-9)
        for p, f, v in zip(r.contacts_in_hand, r.contact_finger, r.contact_vertex):
            np.testing.assert_array_equal(p, r.shape[f][v])


def test_the_demo_episode_through_the_paper_pipeline_equals_the_tools_run(moe_touch_bin, tmp_path):
    theirs = rust_report(moe_touch_bin, tmp_path, "--contact", "dgcnn", "--model", str(MODEL))
    episode = mt.read_episode(EPISODE)
    pipeline = mt.Pipeline.paper(mt.Hand.preset("two-finger"), episode.camera, MODEL)
    assert pipeline.method == "dgcnn" and 0 < pipeline.threshold < 1
    ours = python_run(pipeline, episode)
    assert_frames_equal(ours, theirs, episode)
    for r in ours:
        assert r.vertex_force_n is None and r.finger_force_n is None and r.loads == []
        for p in r.contact:
            assert p.shape == (1024,) and ((0 <= p) & (p <= 1)).all()
        # Contact points are the vertices at or above the threshold, in the world too.
        expected = sum(int((p >= pipeline.threshold).sum()) for p in r.contact)
        assert r.num_contacts == expected
        R, t = r.world_from_hand[:3, :3], r.world_from_hand[:3, 3]
        np.testing.assert_allclose(r.contacts_in_hand @ R.T + t, r.contacts_in_world, atol=1e-12)


def test_the_paper_pipeline_registered_to_depth_equals_the_tools_run(moe_touch_bin, tmp_path):
    shape = tmp_path / "shape.toml"
    shape.write_text("[depth]\nenabled = true\n")
    theirs = rust_report(moe_touch_bin, tmp_path, "--contact", "dgcnn", "--model", str(MODEL),
                         "--shape-config", str(shape))
    episode = mt.read_episode(EPISODE)
    hand = mt.Hand.preset("two-finger")
    as_file = mt.Pipeline.paper(hand, episode.camera, MODEL, shape=shape)
    as_dict = mt.Pipeline.paper(hand, episode.camera, MODEL, shape={"depth": {"enabled": True}})
    ours = python_run(as_file, episode)
    assert_frames_equal(ours, theirs, episode)
    for a, b in zip(ours, python_run(as_dict, episode)):
        for p, q in zip(a.shape, b.shape):
            np.testing.assert_array_equal(p, q)
    # The depth image moved the shape: not the markers-only pipeline's.
    plain = python_run(mt.Pipeline.paper(hand, episode.camera, MODEL), episode)
    assert any(not np.array_equal(p, q)
               for a, b in zip(ours, plain) for p, q in zip(a.shape, b.shape))
    with pytest.raises(mt.MoeTouchValueError, match="depth.weight"):
        mt.Pipeline.paper(hand, episode.camera, MODEL, shape={"depth": {"weight": -1.0}})


def test_a_rosbags_recording_decodes_to_its_source_episode():
    source = mt.read_episode(EPISODE)
    bag = mt.read_episode(ROS2_EPISODE)
    assert mt.is_ros2_recording(ROS2_EPISODE) and not mt.is_ros2_recording(EPISODE)
    assert len(bag) == len(source)
    assert bag.camera.intrinsics == source.camera.intrinsics
    np.testing.assert_allclose(bag.camera.hand_from_camera, source.camera.hand_from_camera,
                               atol=1e-12)
    for a, b in zip(bag, source):
        assert a.time_ns == b.time_ns
        np.testing.assert_array_equal(a.color, b.color)
        assert np.nanmax(np.abs(a.depth - b.depth)) <= 0.5e-3 + 1e-6
        np.testing.assert_allclose(a.world_from_hand, b.world_from_hand, atol=1e-12)
        np.testing.assert_array_equal(a.pulls, b.pulls)
        assert a.true_vertices is None and b.true_vertices is not None


def test_frames_out_of_time_order_are_refused_and_change_nothing():
    episode = mt.read_episode(EPISODE)
    pipeline = mt.Pipeline.physics(mt.Hand.preset("two-finger"), episode.camera, config=OCCLUDING)
    f = episode[0]
    first = pipeline.process(f.color, f.depth, f.world_from_hand, f.pulls, time=1.0)
    assert first.stream == "started" and first.gap_secs is None
    with pytest.raises(mt.MoeTouchError, match="is not after the previous frame"):
        pipeline.process(f.color, f.depth, f.world_from_hand, f.pulls, time=0.5)
    again = pipeline.process(f.color, f.depth, f.world_from_hand, f.pulls, time=1.1)
    assert again.stream == "continued" and again.gap_secs == pytest.approx(0.1)
    late = pipeline.process(f.color, f.depth, f.world_from_hand, f.pulls, time=100.0)
    assert late.stream == "restarted"


def test_a_failed_frame_reports_its_status_and_the_stream_goes_on():
    episode = mt.read_episode(EPISODE)
    pipeline = mt.Pipeline.physics(mt.Hand.preset("two-finger"), episode.camera, config=OCCLUDING)
    f, g, h = episode[0], episode[1], episode[2]
    pipeline.process(f.color, f.depth, f.world_from_hand, f.pulls, time=1.0)
    # Refused before the pipeline saw it: the input stage, nothing changed.
    with pytest.raises(mt.MoeTouchValueError) as refused:
        pipeline.process(f.color, f.depth, f.world_from_hand, f.pulls * np.nan, time=1.05)
    assert refused.value.stage == "input" and refused.value.stream is None
    assert refused.value.keypoints is None and refused.value.markers_found is None
    # The physics estimator needs the pulls: the estimate stage fails, with the markers found.
    with pytest.raises(mt.MoeTouchValueError, match="tendon pulls") as failed:
        pipeline.process(g.color, g.depth, g.world_from_hand, None, time=1.1)
    status = failed.value
    assert status.stage == "estimate"
    assert status.stream == "continued" and status.gap_secs == pytest.approx(0.1)
    assert status.markers_found > 0
    assert len(status.keypoints) == 2
    assert sum(int(np.isfinite(k[:, 0]).sum()) for k in status.keypoints) == status.markers_found
    # The next frame is estimated, the estimator started again from rest.
    after = pipeline.process(h.color, h.depth, h.world_from_hand, h.pulls, time=1.2)
    assert after.stream == "recovered" and after.gap_secs == pytest.approx(0.1)
    assert after.shape[0].shape[1] == 3


def test_the_physics_estimator_alone_gives_the_pipelines_estimate():
    """Fed the markers the pipeline found, the estimator gives the pipeline's shape and forces."""
    episode = mt.read_episode(EPISODE)
    hand = mt.Hand.preset("two-finger")
    pipeline = mt.Pipeline.physics(hand, episode.camera, config=OCCLUDING)
    alone = mt.PhysicsEstimator(hand, config=OCCLUDING)
    assert alone.threshold == pipeline.threshold
    for f in episode:
        r = pipeline.process(f.color, f.depth, f.world_from_hand, f.pulls, time=f.time)
        e = alone.estimate(r.keypoints, f.pulls, f.world_from_hand, time=f.time)
        for a, b in zip(e.shape, r.shape):
            np.testing.assert_array_equal(a, b)
        for a, b in zip(e.contact, r.contact):
            np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(e.finger_force_n, r.finger_force_n)
        assert len(e.loads) == len(r.loads)


def test_the_physics_estimator_at_rest_finds_no_press():
    hand = mt.Hand.preset("two-finger")
    estimator = mt.PhysicsEstimator(hand)
    e = estimator.estimate(hand.rest_keypoints(), np.zeros((2, 4)))
    assert e.loads == [] and e.finger_errors == [None, None]
    # The free shapes from rest take solves; nothing is searched, so nothing is cut short.
    assert len(e.solves) == 2 and all(n > 0 for n in e.solves)
    assert e.degraded == [False, False]
    np.testing.assert_array_equal(e.finger_force_n, np.zeros((2, 3)))
    assert (e.pressed_probability < 0.5).all()
    with pytest.raises(mt.MoeTouchError, match=r"pulls: expected shape \[2, 4\]"):
        estimator.estimate(hand.rest_keypoints(), np.zeros((2, 3)))
