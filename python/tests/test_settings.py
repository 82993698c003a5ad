"""Settings as files or as dicts: a dict is read as the file would be (same result, same checks),
and an unknown key is refused naming it."""

import tomllib

import numpy as np
import pytest

import moe_touch as mt
from conftest import EPISODE, OCCLUDING


@pytest.fixture(scope="module")
def episode():
    return mt.read_episode(EPISODE)


def run(pipeline, episode):
    return [pipeline.process(f.color, f.depth, f.world_from_hand, f.pulls, time=f.time)
            for f in episode]


def test_a_dict_gives_what_its_file_gives(episode):
    hand = mt.Hand.preset("two-finger")
    config = tomllib.loads(OCCLUDING.read_text())
    assert config, "the fixture sets something"
    from_file = run(mt.Pipeline.physics(hand, episode.camera, config=OCCLUDING), episode)
    from_dict = run(mt.Pipeline.physics(hand, episode.camera, config=config, material={},
                                        detector={}), episode)
    default = run(mt.Pipeline.physics(hand, episode.camera), episode)
    for a, b in zip(from_file, from_dict):
        np.testing.assert_array_equal(a.finger_force_n, b.finger_force_n)
        for x, y in zip(a.contact, b.contact):
            np.testing.assert_array_equal(x, y)
    # The setting was read, not dropped: without it the demo comes out otherwise.
    assert any(not np.array_equal(a.finger_force_n, d.finger_force_n)
               for a, d in zip(from_dict, default))
    # A detection threshold no press reaches: nothing is found.
    deaf = run(mt.Pipeline.physics(hand, episode.camera,
                                   config={**config, "detection_chi2": 1e12}), episode)
    assert sum(a.num_contacts for a in from_dict) > 0
    assert all(r.loads == [] and r.num_contacts == 0 for r in deaf)


def test_unknown_keys_are_refused_naming_the_key(episode):
    hand = mt.Hand.preset("two-finger")
    for call, key in [
        (lambda: mt.PhysicsEstimator(hand, config={"no_such_setting": 1.0}), "no_such_setting"),
        (lambda: mt.PhysicsEstimator(hand, material={"material": {"stiffness": 1.0}}),
         "stiffness"),
        (lambda: mt.Pipeline.physics(hand, episode.camera, detector={"red_ness": 3}), "red_ness"),
        (lambda: mt.Pipeline.physics(hand, episode.camera, material={"colour": "red"}),
         "colour"),
        (lambda: mt.read_episode(EPISODE, ros={"colour_topic": "/x"}), "colour_topic"),
    ]:
        with pytest.raises(mt.MoeTouchValueError, match=f"unknown field `{key}`") as raised:
            call()
        assert isinstance(raised.value, ValueError)


def test_a_dict_is_checked_as_its_file_is(tmp_path):
    hand = mt.Hand.preset("two-finger")
    bad = tmp_path / "bad.toml"
    bad.write_text("marker_sigma_m = -1.0\n")
    with pytest.raises(mt.MoeTouchValueError) as from_file:
        mt.PhysicsEstimator(hand, config=bad)
    with pytest.raises(mt.MoeTouchValueError) as from_dict:
        mt.PhysicsEstimator(hand, config={"marker_sigma_m": -1.0})
    assert str(from_dict.value) == str(from_file.value)
    assert "marker_sigma_m" in str(from_dict.value)
    with pytest.raises(mt.MoeTouchValueError, match="config: invalid type"):
        mt.PhysicsEstimator(hand, config={"marker_sigma_m": "small"})
    with pytest.raises(mt.MoeTouchValueError, match=r'config\["marker_sigma_m"\]: NaN is not a finite'):
        mt.PhysicsEstimator(hand, config={"marker_sigma_m": float("nan")})


def test_numpy_values_and_paths_are_settings(tmp_path):
    hand = mt.Hand.preset("two-finger")
    e = mt.PhysicsEstimator(hand, config={"marker_sigma_m": np.float32(3e-4),
                                          "static_max_iterations": np.int64(60),
                                          "max_loads_per_finger": np.uint8(1)})
    assert e.threshold == mt.PhysicsEstimator(hand).threshold
    config = tmp_path / "c.json"
    config.write_text('{"hidden_marker_prior": 20.0}')
    mt.PhysicsEstimator(hand, config=str(config))
    mt.PhysicsEstimator(hand, config=config)
    mt.PhysicsEstimator(hand, config=None)
