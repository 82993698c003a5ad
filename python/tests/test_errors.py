"""Bad input raises a MoeTouchError with the line the tool prints, and writes nothing: a missing
file is a FileNotFoundError, another failure to read one an OSError, bad values and malformed
input a ValueError; wrong types stay TypeError."""

import errno
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


def test_the_exception_classes_derive_from_one_base_and_a_builtin():
    for cls, builtin in [(mt.MoeTouchFileNotFoundError, FileNotFoundError),
                         (mt.MoeTouchOSError, OSError),
                         (mt.MoeTouchValueError, ValueError)]:
        assert issubclass(cls, mt.MoeTouchError) and issubclass(cls, builtin), cls
        assert cls.__module__ == "moe_touch" and cls.__doc__
    assert issubclass(mt.MoeTouchError, Exception)
    assert not issubclass(mt.MoeTouchError, (ValueError, OSError))
    assert not issubclass(mt.MoeTouchValueError, OSError)
    assert not issubclass(mt.MoeTouchOSError, ValueError)
    # As FileNotFoundError is an OSError, a missing file is a MoeTouchOSError too.
    assert issubclass(mt.MoeTouchFileNotFoundError, mt.MoeTouchOSError)


def test_a_bad_value_is_a_value_error():
    with pytest.raises(mt.MoeTouchValueError, match="unknown hand preset 'four-finger'"):
        mt.Hand.preset("four-finger")
    # Neither a preset nor a file: a bad value (it may be a misspelt preset), not a missing file.
    with pytest.raises(mt.MoeTouchValueError, match="neither a preset"):
        mt.Hand.load("no/such/hand.toml")


def missing_file_calls(tmp_path):
    """(what, call, the file the message names) for files that do not exist."""
    hand = mt.Hand.preset("two-finger")
    camera = mt.read_episode(EPISODE).camera
    missing = tmp_path / "missing"
    return [
        ("episode", lambda: mt.read_episode(missing / "nope.mcap"), "nope.mcap"),
        ("model", lambda: mt.ContactModel(missing / "nope.safetensors", hand), "nope.safetensors"),
        ("paper model", lambda: mt.Pipeline.paper(hand, camera, missing / "nope.safetensors"),
         "nope.safetensors"),
        ("data set", lambda: mt.Dataset(tmp_path), "card.json"),
        ("hand", lambda: mt.Hand.from_file(missing / "hand.toml"), "hand.toml"),
        ("physics config", lambda: mt.Pipeline.physics(hand, camera, config=missing / "c.toml"),
         "c.toml"),
        ("material", lambda: mt.PhysicsEstimator(hand, material=str(missing / "m.json")),
         "m.json"),
        ("detector", lambda: mt.Pipeline.physics(hand, camera, detector=missing / "d.toml"),
         "d.toml"),
        ("ros config", lambda: mt.read_episode(EPISODE, ros=missing / "ros.toml"), "ros.toml"),
    ]


def test_a_missing_file_is_a_file_not_found_error(tmp_path):
    for what, call, name in missing_file_calls(tmp_path):
        with pytest.raises(FileNotFoundError) as raised:
            call()
        e = raised.value
        assert isinstance(e, mt.MoeTouchFileNotFoundError), what
        assert isinstance(e, mt.MoeTouchError) and not isinstance(e, ValueError), what
        assert name in str(e), (what, str(e))
        assert e.errno == errno.ENOENT, (what, e.errno)


def test_a_directory_where_a_file_belongs_is_an_os_error(tmp_path):
    folder = tmp_path / "hand.toml"
    folder.mkdir()
    with pytest.raises(mt.MoeTouchOSError, match="hand.toml") as raised:
        mt.Hand.from_file(folder)
    assert isinstance(raised.value, OSError) and not isinstance(raised.value, FileNotFoundError)
    assert raised.value.errno == errno.EISDIR


def test_a_malformed_file_is_a_value_error(tmp_path):
    bad_toml = tmp_path / "bad.toml"
    bad_toml.write_text("hidden_marker_prior = [\n")
    unknown = tmp_path / "unknown.toml"
    unknown.write_text("no_such_setting = 1\n")
    bad_mcap = tmp_path / "bad.mcap"
    bad_mcap.write_bytes(b"\x89MCAP0\r\n" + b"\xff" * 40)
    bad_card = tmp_path / "set"
    bad_card.mkdir()
    (bad_card / "card.json").write_text("{")
    hand = mt.Hand.preset("two-finger")
    for call, says in [
        (lambda: mt.PhysicsEstimator(hand, config=bad_toml), "bad.toml"),
        (lambda: mt.PhysicsEstimator(hand, config=unknown), "unknown field `no_such_setting`"),
        (lambda: mt.PhysicsEstimator(hand, config=tmp_path / "c.yaml"), "unsupported extension"),
        (lambda: mt.read_episode(bad_mcap), "bad.mcap"),
        (lambda: mt.Dataset(bad_card), "card.json"),
        (lambda: mt.Hand.from_file(bad_toml), "bad.toml"),
    ]:
        with pytest.raises(ValueError, match=says) as raised:
            call()
        assert isinstance(raised.value, mt.MoeTouchValueError), says
        assert not isinstance(raised.value, OSError), says


def test_wrong_types_stay_type_errors():
    hand = mt.Hand.preset("two-finger")
    with pytest.raises(TypeError):
        mt.Hand.preset(2)
    with pytest.raises(TypeError, match="config: expected a path to a TOML or JSON file or a dict"):
        mt.PhysicsEstimator(hand, config=42)
    with pytest.raises(TypeError, match=r'material\["material"\]: a set is not a setting'):
        mt.PhysicsEstimator(hand, material={"material": {1, 2}})
    with pytest.raises(TypeError, match="key 3 is not a string"):
        mt.PhysicsEstimator(hand, config={3: 1.0})
    with pytest.raises(TypeError):
        mt.PhysicsEstimator(hand).estimate(hand.rest_keypoints(), np.zeros((2, 4), np.int64))


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
