"""numpy in and out: shapes, dtypes, layouts and round trips."""

import numpy as np
import pytest

import moe_touch as mt
from conftest import DATASET, EPISODE, OCCLUDING


@pytest.fixture(scope="module")
def hand():
    return mt.Hand.preset("two-finger")


def test_the_hand_arrays_agree_with_each_other(hand):
    assert hand.num_fingers == 2 and hand.tendons_per_finger == 4
    assert sum(hand.rest_vertices(f).shape[0] for f in range(2)) == hand.num_vertices
    for f, keypoints in enumerate(hand.rest_keypoints()):
        rest = hand.rest_vertices(f)
        assert rest.dtype == np.float64 and rest.shape[1] == 3
        faces = hand.faces(f)
        assert faces.dtype == np.uint32 and faces.max() < rest.shape[0]
        # The markers at rest are the rest surface at the marker vertices.
        np.testing.assert_array_equal(keypoints, rest[hand.marker_vertices(f)])
        T = hand.hand_from_finger(f)
        np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-12)
    with pytest.raises(IndexError):
        hand.rest_vertices(2)


def test_a_camera_round_trips(hand):
    T = np.eye(4)
    c, s = np.cos(0.3), np.sin(0.3)
    T[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    T[:3, 3] = [0.01, -0.02, 0.05]
    cam = mt.Camera(320, 240, 190.0, 191.0, 159.5, 119.5, T)
    assert (cam.width, cam.height) == (320, 240)
    assert cam.intrinsics == (190.0, 191.0, 159.5, 119.5)
    np.testing.assert_allclose(cam.hand_from_camera, T, atol=1e-15)


def test_sr_arap_holds_rest_and_follows_a_rigid_motion(hand):
    rest = hand.rest_vertices(0)
    faces = hand.faces(0)
    base = np.flatnonzero(rest[:, 2] < rest[:, 2].min() + 0.002)
    tip = np.array([int(np.argmax(rest[:, 2]))])
    solver = mt.ArapSolver(rest, faces, base, tip)
    assert solver.num_vertices == rest.shape[0] and solver.num_parts == 1
    np.testing.assert_allclose(solver.solve(rest[base], rest[tip]), rest, atol=1e-9)
    # Every target moved by one translation: the whole mesh moves with it.
    t = np.array([0.01, 0.02, -0.03])
    np.testing.assert_allclose(solver.solve(rest[base] + t, rest[tip] + t), rest + t, atol=1e-9)
    # A rigid motion of the whole mesh is a solution: started there, the solve stays there.
    c, s = np.cos(0.4), np.sin(0.4)
    R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    moved = rest @ R.T + t
    np.testing.assert_allclose(solver.solve(moved[base], moved[tip], start=moved), moved,
                               atol=1e-9)
    # A NaN handle row leaves the handle free: the mesh stays at rest.
    free = solver.solve(rest[base], np.full((1, 3), np.nan))
    np.testing.assert_allclose(free, rest, atol=1e-9)


def test_the_shape_of_markers_at_rest_is_the_rest_surface(hand):
    estimator = mt.MultiShapeEstimator(hand)
    shape = estimator.estimate(hand.rest_keypoints())
    for f, vertices in enumerate(shape):
        np.testing.assert_allclose(vertices, hand.rest_vertices(f), atol=1e-9)


def test_episode_frames_are_c_contiguous_arrays_and_other_layouts_give_the_same_result(hand):
    episode = mt.read_episode(EPISODE)
    f = episode[3]
    assert f.color.dtype == np.uint8 and f.color.shape == (240, 320, 3)
    assert f.depth.dtype == np.float32 and f.depth.shape == (240, 320)
    assert f.color.flags.c_contiguous and f.depth.flags.c_contiguous
    assert f.pulls.shape == (2, 4) and f.world_from_hand.shape == (4, 4)
    assert [v.shape for v in f.true_vertices] == [(1024, 3), (1024, 3)]
    a = mt.Pipeline.physics(hand, episode.camera, config=OCCLUDING)
    b = mt.Pipeline.physics(hand, episode.camera, config=OCCLUDING)
    ra = a.process(f.color, f.depth, f.world_from_hand, f.pulls)
    rb = b.process(np.asfortranarray(f.color), np.asfortranarray(f.depth),
                   np.asfortranarray(f.world_from_hand), np.asfortranarray(f.pulls))
    assert ra.num_contacts == rb.num_contacts and ra.markers_found == rb.markers_found
    for x, y in zip(ra.shape, rb.shape):
        np.testing.assert_array_equal(x, y)
    assert ra.stream == "untimed"
    assert ra.timings.total_ms >= ra.timings.markers_ms >= 0


def test_a_data_set_reads_as_stacked_shards_and_as_frames():
    ds = mt.Dataset(DATASET)
    card = ds.card
    assert isinstance(card, mt.DatasetCard)
    assert ds.num_shards == len(card.shards) and len(ds) == card.totals.frames
    raw = card.to_dict()
    assert raw["totals"]["frames"] == card.totals.frames and raw["seed"] == card.seed
    assert [s["file"] for s in raw["shards"]] == [s.file for s in card.shards]
    assert sum(s.stats.frames for s in card.shards) == card.totals.frames
    assert set(card.families) == set(raw["families"])
    assert card.layout.finger_num_vertices == raw["layout"]["finger_num_vertices"]
    assert card.generator == raw["generator"]
    shard = ds.shard(0)
    n = shard["vertices"].shape[0]
    assert shard["vertices"].dtype == np.float32 and shard["contact"].dtype == np.uint8
    frames = list(ds.frames())
    assert len(frames) == len(ds)
    for i in range(n):
        for key, value in shard.items():
            if value is None:
                assert frames[i][key] is None
            else:
                np.testing.assert_array_equal(frames[i][key], value[i])
    splits = [list(ds.frames(s)) for s in ("train", "validation", "test")]
    assert sum(map(len, splits)) == len(ds)
    with pytest.raises(IndexError, match="of a data set of 1 shards"):
        ds.shard(ds.num_shards)
