"""The env under a reality profile (``reality=``, docs/reality.md): every id takes one, the
ideal one changes no bit, a seed gives the same episodes and the same draws (single, batched,
copied), each arm of a batch draws its own, the draw is in the info, the link loses what
its draw says, a bad profile is a ValueError naming it."""

from __future__ import annotations

import copy
import pickle

import gymnasium as gym
import numpy as np
import pytest

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.envs import IDS
from franka_sim_gym.reality import RealityDraw
from tests.envs.test_vector_env import assert_same, run_both

REACH = {"cartesian_dof": 3, "policy_hz": 10, "max_episode_steps": 6}


def episode(env_id="FrankaFCICartesianVelocity-v0", seed=3, steps=10, **kwargs):
    """Observations, rewards and infos of ``steps`` steps from reset(seed) (resets when an
    episode ends), random actions of a fixed seed."""
    env = gym.make(env_id, **kwargs)
    obs, info = env.reset(seed=seed)
    rng = np.random.default_rng(1)
    out = [(obs, info)]
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(
            rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
        )
        out.append((obs, reward, info))
        if terminated or truncated:
            out.append(env.reset())
    return out


def observations(run) -> bytes:
    return b"".join(step[0]["observation"].tobytes() for step in run)


def test_every_id_takes_a_profile_and_reports_its_draw():
    for env_id in IDS:
        env = gym.make(env_id, reality="fr3")
        obs, info = env.reset(seed=0)
        assert isinstance(info["reality"], RealityDraw) and info["reality"].profile == "fr3"
        obs, *_, info = env.step(env.action_space.sample() * 0.1)
        assert env.observation_space.contains(obs)
        assert info["reality"].profile == "fr3"


def test_the_ideal_profile_is_the_env_without_one_bit_for_bit():
    plain = episode(**REACH)
    for ideal in ("ideal", {}, None):
        run = episode(reality=ideal, **REACH)
        assert observations(run) == observations(plain)
        assert "reality" not in run[0][1] and "reality" not in run[1][2]


@pytest.mark.parametrize("profile", ["fr3", "randomized"])
def test_a_seed_gives_the_same_episodes_and_draws_and_another_seed_others(profile):
    a, b, c = (episode(seed=s, reality=profile, **REACH) for s in (3, 3, 4))
    assert observations(a) == observations(b) != observations(c)
    draws = [step[-1]["reality"] for step in a]
    assert draws == [step[-1]["reality"] for step in b]
    assert a[0][1]["reality"] != c[0][1]["reality"]  # another seed, another draw
    ideal = episode(seed=3, **REACH)
    assert observations(a) != observations(ideal)  # the profile changes what the robot reads
    # the start and the goal are the ideal episode's: the draw takes nothing of the env's stream
    assert a[0][0]["desired_goal"].tobytes() == ideal[0][0]["desired_goal"].tobytes()


def test_each_episode_draws_anew():
    run = episode(seed=3, steps=14, reality="randomized", **REACH)
    draws = {step[-1]["reality"].seed for step in run}
    assert len(draws) == 3  # three episodes of 6 steps in 14


def test_each_arm_of_a_batch_is_the_single_env_of_its_seed():
    """Under randomized (its lossy links included), through autoresets."""
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, size=(14, 3, 3)).astype(np.float32)
    ended, last = run_both(
        3,
        14,
        lambda t: actions[t],
        action_interface="cartesian_velocity",
        reality="randomized",
        **REACH,
    )
    assert ended >= 6
    draws = last[-1]["reality"]
    assert len({d.seed for d in draws}) == 3  # every arm its own draw


def test_a_copy_continues_exactly_as_the_original():
    env = gym.make("FrankaFCICartesianVelocity-v0", reality="randomized", **REACH)
    env.reset(seed=7)
    actions = np.random.default_rng(4).uniform(-1, 1, size=(12, 3)).astype(np.float32)
    for a in actions[:4]:
        env.step(a)
    clones = [copy.deepcopy(env), pickle.loads(pickle.dumps(env))]
    for a in actions[4:]:
        original = env.step(a)
        for clone in clones:
            copied = clone.step(a)
            assert_same(
                ({k: v[None] for k, v in original[0].items()}, *original[1:4], {}),
                ({k: v[None] for k, v in copied[0].items()}, *copied[1:4], {}),
            )
            assert original[-1]["reality"] == copied[-1]["reality"]
            assert copied[-1]["reality"].profile == "randomized"


def test_the_link_loses_what_its_draw_says():
    lossy = {"communication": {"loss": 0.2}}
    run = episode(reality=lossy, steps=6, **REACH)  # one episode
    lost = sum(step[-1]["lost_cycles"] for step in run[1:])
    assert 0.1 * 600 < lost < 0.3 * 600  # 6 steps of 100 cycles, about 20 % of them
    assert sum(step[-1]["lost_cycles"] for step in episode(**REACH)[1:]) == 0
    late = {"communication": {"jitter": 0.2, "jitter_cycles": 2}}
    run = episode(reality=late, steps=6, **REACH)
    assert sum(step[-1]["lost_cycles"] for step in run[1:]) > 30  # late answers nothing
    # the losses are the episode's: the same seed loses the same cycles, another others
    pattern = [
        [step[-1]["lost_cycles"] for step in episode(seed=s, reality=lossy, steps=6, **REACH)[1:]]
        for s in (3, 3, 4)
    ]
    assert pattern[0] == pattern[1] != pattern[2]


def test_a_held_up_datagram_is_a_lost_cycle_and_a_filtered_stream_runs_on():
    # docs/reality.md, "The link": a spike holds up a datagram and the ones behind it past
    # their window, which the FCI drops: runs of lost cycles, no late datagram. A smooth
    # joint stream through libfranka's filters (which read the state's q_d, the robot's
    # guess in a lost cycle) then runs to its time limit, as over the robot's network;
    # handed to the controller late, the same datagrams would be differenced against a
    # rewound history the client never saw, and abort with 14 / 15.
    spiky = {"communication": {"jitter": 0.05, "jitter_cycles": 3}}
    env = gym.make("FrankaFCIJointPosition-v0", reality=spiky, max_episode_steps=40)
    env.reset(seed=2)
    phase = np.random.default_rng(0).uniform(0, 2 * np.pi, 7)
    lost, longest = 0, 0
    for t in range(40):
        action = (0.1 * np.sin(2 * np.pi * t / 40 + phase)).astype(np.float32)
        _, _, terminated, truncated, info = env.step(action)
        assert not terminated, info["reflex_reason"]
        lost += info["lost_cycles"]
        longest = max(longest, info["longest_lost_run"])
    assert truncated
    assert 0.05 * 1600 < lost < 0.3 * 1600  # a spike of 1-3 cycles in ~5 % of them
    assert longest >= 2  # the datagrams behind a spike wait with it


def test_a_profile_and_a_lossy_channel_together_are_refused():
    with pytest.raises(ValueError, match="channel and reality's communication"):
        gym.make("FrankaFCI-v0", reality="randomized", channel="loss:0.01")
    gym.make("FrankaFCI-v0", reality="fr3", channel="loss:0.01")  # fr3's link is perfect


def test_a_bad_profile_is_a_value_error_naming_it():
    with pytest.raises(ValueError, match="sensors.tau_J_noise must be >= 0"):
        gym.make("FrankaFCI-v0", reality={"sensors": {"tau_J_noise": -1}})
    with pytest.raises(ValueError, match="'moon'"):
        gym.make("FrankaFCI-v0", reality="moon")
