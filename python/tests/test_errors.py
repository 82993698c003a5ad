"""Bad input raises MoeTouchError (a ValueError) with the line the tool prints, and writes
nothing."""

import subprocess

import numpy as np
import pytest

import moe_touch as mt
from conftest import EPISODE, OCCLUDING, recording, write_bag


@pytest.fixture(scope="module")
def frame():
    episode = mt.read_episode(EPISODE)
    pipeline = mt.Pipeline.physics(mt.Hand.preset("two-finger"), episode.camera, config=OCCLUDING)
    return pipeline, episode[2]


def test_an_error_is_a_value_error():
    assert issubclass(mt.MoeTouchError, ValueError)
    with pytest.raises(ValueError, match="unknown hand preset 'four-finger'"):
        mt.Hand.preset("four-finger")
    with pytest.raises(ValueError, match="neither a preset"):
        mt.Hand.load("no/such/hand.toml")


@pytest.mark.parametrize("change, message", [
    (lambda c, d, T, p: (c[:, :-1], d, T, p), r"color: expected a \(240, 320, 3\)"),
    (lambda c, d, T, p: (c, d[:-1], T, p), r"depth: expected a \(240, 320\)"),
    (lambda c, d, T, p: (c, d, np.full((4, 4), np.nan), p), "not finite"),
    (lambda c, d, T, p: (c, d, 2 * T, p), "last row"),
    (lambda c, d, T, p: (c, d, np.diag([2.0, 1, 1, 1]), p), "not a rotation"),
    (lambda c, d, T, p: (c, d, T, p[:, :3]), r"pulls: expected shape \[2, 4\]"),
    (lambda c, d, T, p: (c, d, T, np.where(np.arange(8).reshape(2, 4) == 6, np.nan, p)),
     "pulls: finger 1, tendon 2 is not finite"),
])
def test_bad_frames_are_refused(frame, change, message):
    pipeline, f = frame
    with pytest.raises(mt.MoeTouchError, match=message):
        pipeline.process(*change(f.color, f.depth, f.world_from_hand, f.pulls))


def test_wrong_dtypes_are_type_errors(frame):
    pipeline, f = frame
    with pytest.raises(TypeError):
        pipeline.process(f.color.astype(np.float32), f.depth, f.world_from_hand, f.pulls)


def test_a_simulated_episode_refuses_another_hand():
    with pytest.raises(mt.MoeTouchError, match=r"hand 'three-finger': the hand has fingers of \[1024, 1024, 1024\] vertices, the episode"):
        mt.read_episode(EPISODE, hand=mt.Hand.preset("three-finger"))
    assert len(mt.read_episode(EPISODE, hand=mt.Hand.preset("two-finger"))) == 7


def test_bad_solver_input_names_the_item():
    hand = mt.Hand.preset("two-finger")
    rest = hand.rest_vertices(0)
    base = np.flatnonzero(rest[:, 2] < rest[:, 2].min() + 0.002)
    top = np.argsort(rest[:, 2])[-2:]
    solver = mt.ArapSolver(rest, hand.faces(0), base, top)
    bad = rest[top].copy()
    bad[1, 2] = np.inf
    with pytest.raises(mt.MoeTouchError, match="handle_targets: row 1 is neither finite"):
        solver.solve(rest[base], bad)
    with pytest.raises(mt.MoeTouchError, match=r"fixed targets: expected \d+ items, got \d+"):
        solver.solve(rest[base][:-1], rest[top])
    with pytest.raises(mt.MoeTouchError, match="handles: vertex id -1"):
        mt.ArapSolver(rest, hand.faces(0), base, [-1])


def test_missing_and_malformed_files_name_the_file(tmp_path):
    with pytest.raises(mt.MoeTouchError, match="nope.mcap"):
        mt.read_episode(tmp_path / "nope.mcap")
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"\x89MCAP0\r\n" + b"\xff" * 40)
    with pytest.raises(mt.MoeTouchError, match="bad.mcap"):
        mt.read_episode(bad)
    with pytest.raises(mt.MoeTouchError, match="card.json"):
        mt.Dataset(tmp_path)
    with pytest.raises(mt.MoeTouchError, match="nope.safetensors"):
        mt.ContactModel(tmp_path / "nope.safetensors", mt.Hand.preset("two-finger"))


def bad_recordings(tmp_path):
    """(name, directory, ros config or None, what the error says)."""
    without_colour = [m for m in recording() if m[0] != "/camera/camera/color/image_raw"]
    without_static = [m for m in recording() if m[0] != "/tf_static"]
    return [
        ("no colour", write_bag(tmp_path / "no-colour", without_colour), None,
         "no message on the colour topic"),
        ("depth size", write_bag(tmp_path / "depth-size", recording(depth_size=(2, 2))), None,
         "depth must be aligned to colour"),
        ("encoding", write_bag(tmp_path / "encoding", recording(color_encoding="yuv422")), None,
         "colour encoding 'yuv422' is not read"),
        ("no tf path", write_bag(tmp_path / "no-tf", without_static), None,
         "no transform path from 'hand' to 'cam'"),
        ("joints", write_bag(tmp_path / "joints", recording()),
         'tendon_joints = [["a", "b", "c", "d"], ["e", "f", "g", "h"]]\n', "has no joint 'a'"),
        ("order", write_bag(tmp_path / "order", recording(late_second_frame=True)), None,
         "timestamps out of order"),
    ]


def test_a_recording_written_here_reads(tmp_path):
    episode = mt.read_episode(write_bag(tmp_path / "good", recording()))
    assert len(episode) == 2 and episode.camera.width == 4
    assert episode[1].depth[0, 0] == pytest.approx(0.501)
    np.testing.assert_array_equal(episode[1].pulls, np.full((2, 4), 0.001))


def test_bad_recordings_raise_the_tools_error_line(tmp_path, moe_touch_bin):
    for name, bag, config, says in bad_recordings(tmp_path):
        ros = None
        if config is not None:
            ros = tmp_path / f"{bag.name}.toml"
            ros.write_text(config)
        with pytest.raises(mt.MoeTouchError) as raised:
            mt.read_episode(bag, ros=ros)
        message = str(raised.value)
        assert says in message, (name, message)
        out = tmp_path / f"{bag.name}.out.mcap"
        cmd = [str(moe_touch_bin), "run", "--episode", str(bag), "--out", str(out)]
        if ros is not None:
            cmd += ["--ros", str(ros)]
        tool = subprocess.run(cmd, capture_output=True, text=True)
        assert tool.returncode != 0, name
        assert tool.stderr.splitlines() == [f"error: {message}"], (name, tool.stderr)
        assert not out.exists(), name


def test_a_ros_config_may_be_a_dict(tmp_path):
    bag = write_bag(tmp_path / "joints", recording())
    with pytest.raises(mt.MoeTouchError, match="has no joint 'a'"):
        mt.read_episode(bag, ros={"tendon_joints": [list("abcd"), list("efgh")]})
    with pytest.raises(mt.MoeTouchError, match="unknown field"):
        mt.read_episode(bag, ros={"colour_topic": "/x"})
