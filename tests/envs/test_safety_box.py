"""The client's safety box (``safety_box``): the TCP kept inside a workspace box by a bound
on the commanded velocity toward each wall, before libfranka's rate limiter
(envs/commands.py, envs/cartesian_filters.box_velocity_core; docs/env.md "The safety
box"). Not a robot rule: the robot's own checks judge the stream it produces.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.envs.cartesian_filters import BOX_DECELERATION, box_velocity_core
from franka_sim_gym.envs.commands import CommandGenerator
from franka_sim_gym.envs.tasks.push import Push

LOWER, UPPER = np.array([0.3, -0.2, 0.05]), np.array([0.7, 0.2, 0.5])


def test_the_bound_toward_a_wall_is_the_speed_that_brakes_to_a_stop_at_it():
    a = BOX_DECELERATION
    p = np.array([[0.5, 0.0, 0.07], [0.5, 0.0, 0.07], [0.5, 0.0, 0.04], [0.69, 0.0, 0.3]])
    v = np.array([[0.0, 0.0, -1.0], [0.1, -0.1, 0.3], [0.0, 0.0, -0.2], [0.3, 0.0, 0.0]])
    out = box_velocity_core(v, p, np.zeros((4, 3)), LOWER, UPPER)
    assert out[0, 2] == pytest.approx(-np.sqrt(2 * a * 0.02))  # 2 cm over the floor
    np.testing.assert_array_equal(out[1], v[1])  # inside its bounds: unchanged
    assert out[2, 2] == 0.0  # below the floor: no further down ...
    up = box_velocity_core(-v[2:3], p[2:3], np.zeros((1, 3)), LOWER, UPPER)
    assert up[0, 2] == 0.2  # ... but back up
    assert out[3, 0] == pytest.approx(np.sqrt(2 * a * 0.01))


def test_while_braking_is_due_the_other_axes_hold_their_last_velocity():
    """The limiter shares one acceleration norm among the axes: braking gets all of it."""
    p = np.array([[0.5, 0.0, 0.06]])  # 1 cm over the floor: bound 0.1 m/s down
    v_last = np.array([[0.05, 0.0, -0.2]])  # past it
    out = box_velocity_core(np.array([[0.3, 0.3, -0.3]]), p, v_last, LOWER, UPPER)
    np.testing.assert_allclose(out, [[0.05, 0.0, -0.1]])
    calm = box_velocity_core(np.array([[0.3, 0.3, -0.3]]), p, 0.4 * v_last, LOWER, UPPER)
    np.testing.assert_allclose(calm, [[0.3, 0.3, -0.1]])  # not past: the others are free


def press_into_the_table(
    env_id: str, box, n: int = 8, steps: int = 30, seed: int = 0, action_filter="limit_rate"
):
    """A policy that moves the hand away from the block for 0.4 s, then drives it down
    into the table at full speed while it drifts on sideways with seeded jitter (10 Hz,
    3 s: into the side walls too). Returns the reflex reasons and the lowest and highest
    measured TCP positions over the live steps."""
    envs = gym.make_vec(
        env_id,
        num_envs=n,
        vectorization_mode="vector_entry_point",
        policy_hz=10,
        max_episode_steps=steps,
        safety_box=box,
        action_filter=action_filter,
    )
    obs, _ = envs.reset(seed=seed)
    rng = np.random.default_rng(seed)
    o = obs["observation"]
    away = o[:, 14:16] - o[:, 23:25]  # the TCP from the block
    away /= np.linalg.norm(away, axis=1, keepdims=True)
    reasons, ended = [], np.zeros(n, dtype=bool)
    low, high = np.full(3, np.inf), np.full(3, -np.inf)
    for t in range(steps):
        action = np.zeros((n, 3), dtype=np.float32)
        action[:, :2] = 0.3 * away + rng.uniform(-0.3, 0.3, (n, 2))
        action[:, 2] = -1.0 if t >= 4 else 0.0
        obs, _, terminated, truncated, info = envs.step(action)
        live = ~ended & ~terminated
        if live.any():
            tcp = obs["observation"][live, 14:17]
            low, high = np.minimum(low, tcp.min(0)), np.maximum(high, tcp.max(0))
        reasons += [info["reflex_reason"][i] for i in np.flatnonzero(terminated & ~ended)]
        ended |= terminated | truncated
    envs.close()
    return reasons, low, high


@pytest.mark.parametrize("action_filter", ["limit_rate", "interpolate_limit_rate"])
@pytest.mark.parametrize("env_id", ["FrankaFCIPush-v0", "FrankaFCIPushCartesianPose-v0"])
def test_a_policy_pressing_into_the_table_stops_at_the_floor_without_a_reflex(
    env_id, action_filter
):
    lower, upper = (np.array(c) for c in Push.safety_box)
    reasons, low, high = press_into_the_table(env_id, "task", action_filter=action_filter)
    assert reasons == []
    # The measured TCP (the twist interface brakes on it; the pose one on the commanded
    # pose, which the arm follows within its tracking error): within 1 mm of the walls.
    assert (low >= lower - 1e-3).all() and (high <= upper + 1e-3).all(), (low, high)
    assert low[2] < lower[2] + 2e-3  # it did reach the floor


def test_without_the_box_the_same_policy_presses_the_hand_onto_the_table():
    reasons, _, _ = press_into_the_table("FrankaFCIPush-v0", None, n=4, steps=14)
    assert len(reasons) == 4 and all("cartesian_reflex" in r for r in reasons)


def test_a_box_that_never_binds_changes_no_bit():
    def trajectory(box):
        env = gym.make("FrankaFCIPush-v0", safety_box=box)
        obs, _ = env.reset(seed=3)
        rng = np.random.default_rng(3)
        out = [obs["observation"]]
        for _ in range(10):
            obs, *_ = env.step(rng.uniform(-1, 1, 3).astype(np.float32))
            out.append(obs["observation"])
        return np.array(out)

    np.testing.assert_array_equal(trajectory(None), trajectory([[-5, -5, -5], [5, 5, 5]]))


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (dict(safety_box=[[0, 0, 0], [1, 1]]), "two corners"),
        (dict(safety_box=[[0, 0, 0], [1, np.nan, 1]]), "two corners"),
        (dict(safety_box=[[0, 0, 0.5], [1, 1, 0.5]]), "below the upper"),
        (dict(safety_box=[[0, 0, 0], [1, 1, 1]], interface="joint_position"), "Cartesian"),
        (dict(safety_box=[[0, 0, 0], [1, 1, 1]], action_filter="none"), "limit_rate"),
    ],
)
def test_a_bad_box_is_a_value_error_naming_it(kwargs, message):
    args = {"interface": "cartesian_velocity", "action_filter": "limit_rate", **kwargs}
    with pytest.raises(ValueError, match=message):
        CommandGenerator(args.pop("interface"), args.pop("action_filter"), 40, **args)


def test_the_task_box_of_a_task_without_one_is_a_value_error():
    with pytest.raises(ValueError, match="Reach declares no box"):
        gym.make("FrankaFCICartesianVelocity-v0", safety_box="task")
