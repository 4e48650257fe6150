"""Reality profiles (franka_sim_gym/reality): the shipped ones, a user's own from a mapping
or a JSON file, a bad one refused with its entry named, and the draws a seed gives."""

from __future__ import annotations

import copy
import json
import pickle

import numpy as np
import pytest

from franka_sim_gym.reality import (
    ENTRIES,
    PROFILES,
    DrawBatch,
    draw,
    episode_seed,
    load_profile,
    stream,
    streams,
)
from franka_sim_gym.reality.draw import STREAMS
from franka_sim_gym.reality.profile import entries


def test_the_shipped_profiles_load_and_only_ideal_is_ideal():
    assert set(PROFILES) == {"ideal", "fr3", "randomized"}
    assert load_profile("ideal").is_ideal
    assert load_profile(None).is_ideal
    assert load_profile({}).is_ideal
    fr3, randomized = load_profile("fr3"), load_profile("randomized")
    assert not fr3.is_ideal and fr3.randomized == ()
    assert fr3.link_is_ideal  # franka_ros #322: an FR3 answers every cycle
    assert "model.mass_scale" in randomized.randomized
    assert not randomized.link_is_ideal


def test_fr3_is_the_datasheet_robot():
    fr3 = load_profile("fr3")
    np.testing.assert_array_equal(fr3.low["sensors.tau_J_noise"], np.full(7, 0.005))
    np.testing.assert_array_equal(fr3.low["friction.compensation"], np.ones(7))


def test_randomized_draws_around_fr3_inside_its_ranges():
    fr3, randomized = load_profile("fr3"), load_profile("randomized")
    for key in randomized.randomized:
        low, high = randomized.low[key], randomized.high[key]
        assert np.all(low <= fr3.low[key]) and np.all(fr3.low[key] <= high), key
    for seed in range(20):
        d = draw(randomized, seed)
        for key, _ in entries():
            assert np.all(randomized.low[key] <= d[key]) and np.all(d[key] <= randomized.high[key])


def test_a_user_profile_from_a_mapping_with_a_base():
    p = load_profile({"base": "fr3", "sensors": {"tau_J_noise": 0.01}})
    np.testing.assert_array_equal(p.low["sensors.tau_J_noise"], np.full(7, 0.01))
    # the rest is fr3's
    np.testing.assert_array_equal(
        p.low["model.mass_scale"], load_profile("fr3").low["model.mass_scale"]
    )
    np.testing.assert_array_equal(
        p.low["sensors.q_noise"], load_profile("fr3").low["sensors.q_noise"]
    )


def test_a_user_profile_from_a_json_file(tmp_path):
    path = tmp_path / "mine.json"
    path.write_text(json.dumps({"model": {"mass_scale": {"uniform": [0.9, 1.1]}}}))
    p = load_profile(str(path))
    assert p.name == "mine" and p.randomized == ("model.mass_scale",)
    assert load_profile(path).randomized == ("model.mass_scale",)


def test_a_user_profile_from_json_text():
    p = load_profile('{"base": "fr3", "communication": {"loss": 0.01}}')
    np.testing.assert_array_equal(p.low["communication.loss"], 0.01)
    with pytest.raises(ValueError, match="not JSON"):
        load_profile('{"base": ')


def test_a_profile_reads_back_from_its_spec_and_survives_copies():
    randomized = load_profile("randomized")
    again = load_profile(randomized.spec())
    for key, _ in entries():
        np.testing.assert_array_equal(again.low[key], randomized.low[key])
        np.testing.assert_array_equal(again.high[key], randomized.high[key])
    assert copy.deepcopy(randomized) is randomized
    pickled = pickle.loads(pickle.dumps(randomized))
    assert pickled.randomized == randomized.randomized and pickled.name == "randomized"
    assert draw(pickled, 5) == draw(randomized, 5)


@pytest.mark.parametrize(
    ("spec", "named"),
    [
        ({"sensors": {"tau_J_noise": -0.1}}, "sensors.tau_J_noise must be >= 0"),
        ({"model": {"mass_scale": 0.0}}, "model.mass_scale must be > 0"),
        ({"model": {"mass_scale": {"uniform": [-1.0, 1.0]}}}, "model.mass_scale must be > 0"),
        ({"model": {"mass_scal": 1.0}}, "unknown key(s) ['model.mass_scal']"),
        ({"modell": {}}, "unknown section(s) ['modell']"),
        (
            {"model": {"com_offset": [0.0, 0.0]}},
            "model.com_offset: expected a number or shape (7, 3)",
        ),
        ({"model": {"mass_scale": {"uniform": [1.2, 1.1]}}}, "model.mass_scale: low"),
        ({"communication": {"loss": 1.5}}, "communication.loss must be in [0, 1]"),
        ({"communication": {"jitter_cycles": 2.5}}, "communication.jitter_cycles must be a whole"),
        ({"sensors": {"q_noise": float("nan")}}, "sensors.q_noise must be finite"),
        ({"sensors": {"q_noise": "loud"}}, "sensors.q_noise: not a number"),
        ({"sensors": {"q_noise": {"normal": [0, 1]}}}, "sensors.q_noise: a range is"),
        ({"base": "fr4"}, "base 'fr4' is not a shipped profile"),
        ("fr4", "'fr4': neither a shipped profile"),
        (42, "expected a mapping, got int"),
    ],
)
def test_a_bad_profile_is_a_value_error_naming_it(spec, named):
    with pytest.raises(ValueError) as error:
        load_profile(spec)
    assert named in str(error.value)


def test_a_file_that_is_not_json_is_named(tmp_path):
    path = tmp_path / "broken.json"
    path.write_text("{model:")
    with pytest.raises(ValueError, match="broken.json.*not JSON"):
        load_profile(str(path))


def test_every_entry_has_its_ideal_value_in_the_ideal_profile():
    ideal = load_profile("ideal")
    for section, names in ENTRIES.items():
        for name, entry in names.items():
            np.testing.assert_array_equal(ideal.low[f"{section}.{name}"], entry.ideal)


def test_the_same_seed_draws_the_same_robot_and_another_seed_another():
    randomized = load_profile("randomized")
    a, b, c = draw(randomized, 7), draw(randomized, 7), draw(randomized, 8)
    for key, _ in entries():
        np.testing.assert_array_equal(a[key], b[key])
    assert not np.array_equal(a["model.mass_scale"], c["model.mass_scale"])
    assert a.json() == b.json() != c.json()
    # a fixed entry is its value exactly, whatever the seed
    fr3 = load_profile("fr3")
    np.testing.assert_array_equal(draw(fr3, 1)["model.com_offset"], fr3.low["model.com_offset"])


def test_a_draw_is_immutable_and_reports_itself():
    d = draw(load_profile("randomized"), 3)
    assert copy.deepcopy(d) is d
    with pytest.raises(ValueError):
        d["model.mass_scale"][0] = 2.0
    report = d.as_dict()
    assert report["profile"] == "randomized" and report["seed"] == 3
    assert report["model"]["mass_scale"] == d["model.mass_scale"].tolist()
    assert not d.robot_is_ideal and not d.link_is_ideal
    assert draw(load_profile("ideal"), 3).robot_is_ideal
    assert draw(load_profile("fr3"), 3).link_is_ideal
    batch = DrawBatch.stack([d, draw(load_profile("randomized"), 4)])
    assert batch["model.com_offset"].shape == (2, 7, 3)


def test_an_episode_seed_reads_the_generator_and_draws_nothing_from_it():
    rng = np.random.default_rng(11)
    twin = np.random.default_rng(11)
    seed = episode_seed(rng)
    assert seed == episode_seed(twin)
    assert rng.random() == twin.random()  # nothing was drawn
    assert episode_seed(rng) != seed  # the next episode's state, the next seed
    mt = np.random.Generator(np.random.MT19937(5))
    assert episode_seed(mt) == episode_seed(np.random.Generator(np.random.MT19937(5)))


def test_one_seed_feeds_independent_streams():
    s = streams(5)
    values = {name: g.random() for name, g in s.items()}
    assert len(set(values.values())) == len(values)
    assert streams(5)["sensors"].random() == values["sensors"]
    # Each is the seed's SeedSequence child of its purpose, built alone or with the rest.
    children = np.random.SeedSequence(5).spawn(len(STREAMS))
    for name, child in zip(STREAMS, children, strict=True):
        assert stream(5, name).random() == values[name]
        assert np.random.Generator(np.random.PCG64(child)).random() == values[name]


def test_a_draw_takes_each_entry_uniform_from_the_draw_stream_in_entry_order():
    """Entry by entry, ``low + (high - low) u`` with u the draw stream's next uniforms of
    the entry's shape (cycles floored, fixed entries exact): what one call for every
    entry's uniforms must give."""
    randomized = load_profile("randomized")
    for seed in (0, 5, 2**70 + 1):
        rng = stream(seed, "draw")
        d = draw(randomized, seed)
        for key, entry in entries():
            u = rng.random(entry.shape)
            low, high = randomized.low[key], randomized.high[key]
            expected = np.where(low == high, low, low + (high - low) * u)
            if entry.bound == "cycles":
                expected = np.floor(expected)
            np.testing.assert_array_equal(d[key], expected, err_msg=key)
