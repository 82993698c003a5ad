"""Loads and cards are typed objects with the Rust names; `to_dict()` gives a card's raw form."""

import math

import numpy as np
import pytest

import moe_touch as mt
from conftest import EPISODE, MODEL, OCCLUDING


def test_loads_are_contact_loads():
    episode = mt.read_episode(EPISODE)
    pipeline = mt.Pipeline.physics(mt.Hand.preset("two-finger"), episode.camera, config=OCCLUDING)
    loads = []
    for f in episode:
        r = pipeline.process(f.color, f.depth, f.world_from_hand, f.pulls, time=f.time)
        loads += [(r, load) for load in r.loads]
    assert loads, "the demo presses a finger"
    for r, load in loads:
        assert isinstance(load, mt.ContactLoad)
        assert load.finger in (0, 1) and 0 <= load.vertex < 1024
        for v in (load.location_rest, load.location, load.force):
            assert isinstance(v, np.ndarray) and v.dtype == np.float64 and v.shape == (3,)
        assert load.magnitude == pytest.approx(float(np.linalg.norm(load.force)), rel=1e-9)
        assert load.magnitude_sd >= 0
        assert load.location_sd_along is None or load.location_sd_along >= 0
        # The loaded place sits on the estimated surface near the load's vertex.
        assert np.linalg.norm(load.location - r.shape[load.finger][load.vertex]) < 0.01
        assert sum(share for _, share in load.patch) == pytest.approx(1.0)
        assert "ContactLoad(finger=" in repr(load)


def test_the_model_card_is_typed_and_matches_its_file():
    card = mt.ContactModel(MODEL, mt.Hand.preset("two-finger")).card
    assert isinstance(card, mt.ModelCard)
    raw = card.to_dict()
    assert raw == mt.ContactModel(MODEL, mt.Hand.preset("two-finger")).card.to_dict()
    assert card.format_version == raw["format_version"] and card.threshold == raw["threshold"]
    assert card.features == raw["architecture"]["input"]["features"] and card.features
    assert card.architecture == raw["architecture"]
    assert isinstance(card.hand, mt.CardHand)
    assert card.hand.name == raw["hand"]["name"]
    assert card.hand.finger_num_vertices == [1024, 1024]
    assert card.hand.finger_digests == raw["hand"]["finger_digests"]
    assert isinstance(card.training, mt.CardTraining)
    assert card.training.command == raw["training"]["command"]
    assert card.training.config == raw["training"]["config"]
    assert card.training.train_sets == raw["training"]["train_sets"]
    assert isinstance(card.dataset, mt.CardDataset)
    assert [s.dir for s in card.dataset.sets] == [s["dir"] for s in raw["dataset"]["sets"]]
    assert all(isinstance(s, mt.CardDataSource) for s in card.dataset.sets)
    assert card.dataset.train_frames == raw["dataset"]["train_frames"]
    assert isinstance(card.metrics, mt.CardMetrics)
    epochs = raw["metrics"]["epochs"]
    assert [e.epoch for e in card.metrics.epochs] == [e["epoch"] for e in epochs]
    for typed, e in zip(card.metrics.epochs, epochs):
        assert isinstance(typed, mt.EpochRecord)
        for key, value in e.items():
            got = getattr(typed, key)
            assert got == value or (value is None and math.isnan(got)), key
