"""FrankaFCI-v0: Gymnasium conventions, reflexes as terminations, lost cycles in info."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.envs import IDS
from franka_sim_gym.envs.channel import Channel
from franka_sim_gym.envs.commands import FILTERS, INTERFACES


@pytest.mark.parametrize("env_id", list(IDS))
def test_check_env_passes_for_every_id(env_id):
    env = gym.make(env_id)
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


@pytest.mark.parametrize("interface", INTERFACES)
@pytest.mark.parametrize("action_filter", FILTERS)
def test_one_episode_per_interface_and_filter(interface, action_filter):
    env = gym.make(
        "FrankaFCI-v0",
        action_interface=interface,
        action_filter=action_filter,
        max_episode_steps=5,
        enforce_motion_limits=False,
    )
    obs, info = env.reset(seed=3)
    assert env.observation_space.contains(obs)
    assert info["robot_mode"] == "kMove"
    steps = 0
    terminated = truncated = False
    while not (terminated or truncated):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample() * 0.1)
        steps += 1
        assert env.observation_space.contains(obs)
        assert info["cycles"] > 0 and isinstance(info["violations"], tuple)
    assert steps == 5 and truncated and not terminated
    env.close()


def run(env, seed: int, actions: np.ndarray):
    obs, info = env.reset(seed=seed)
    out = [(obs, info)]
    for a in actions:
        obs, reward, terminated, truncated, info = env.step(a)
        out.append((obs, reward, terminated, truncated, info))
        if terminated or truncated:
            break
    return out


def same(a, b) -> bool:
    """Equal, looking into tuples, dicts and arrays (the infos hold contact arrays)."""
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, tuple | list):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
    return a == b


def assert_same_run(first, second) -> None:
    assert len(first) == len(second)
    for a, b in zip(first, second, strict=True):
        for key in ("observation", "achieved_goal", "desired_goal"):
            assert a[0][key].tobytes() == b[0][key].tobytes(), key
        assert same(a[1:], b[1:])  # rewards, terminations and infos alike


@pytest.mark.parametrize("env_id", list(IDS))
def test_reset_seed_makes_the_episode_reproducible_bit_for_bit(env_id):
    # The episode in between ends truncated while the arm still moves (the motion is
    # running at the reset): nothing of it may reach the next one, under every interface.
    kwargs = {"channel": "loss:0.05", "max_episode_steps": 12}
    env = gym.make(env_id, **kwargs)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-0.4, 0.4, size=(12, *env.action_space.shape)).astype(np.float32)
    first = run(gym.make(env_id, **kwargs), 123, actions)
    between = run(env, 999, actions)
    assert between[-1][3] and not between[-1][2]  # truncated, moving
    assert_same_run(first, run(env, 123, actions))


@pytest.mark.parametrize("env_id", ["FrankaFCICartesianVelocity-v0", "FrankaFCICartesianPose-v0"])
def test_a_reset_starts_the_commanded_twist_from_rest(env_id):
    # Observation indices 17-22 are the commanded twist O_dP_EE_c: a truncated episode's
    # last twist used to be the next episode's first observation.
    env = gym.make(env_id, max_episode_steps=5)
    env.reset(seed=0)
    for _ in range(5):
        obs, *_ = env.step(np.full(env.action_space.shape, 0.5, dtype=np.float32))
    assert np.abs(obs["observation"][17:23]).max() > 0.05  # moving when truncated
    obs, _ = env.reset(seed=0)
    assert obs["observation"][17:23].tolist() == [0.0] * 6


def naive_steps(env, n: int = 2):
    """Large actions held for the whole step (the first only sets where the motion starts:
    0.09 rad is inside the 0.1 rad start-pose tolerance)."""
    for _ in range(n):
        out = env.step(np.full(7, 0.9, dtype=np.float32))
        if out[2]:
            break
    return out


def test_a_naive_policy_under_enforcement_ends_with_a_named_reflex():
    env = gym.make("FrankaFCI-v0", action_filter="none")
    env.reset(seed=1)
    obs, reward, terminated, truncated, info = naive_steps(env)
    assert terminated and not truncated
    assert info["robot_mode"] == "kReflex"
    # a 0.1 rad step in one cycle: the robot names the velocity discontinuity
    assert "joint_motion_generator_velocity_discontinuity" in info["reflex_reason"]
    assert info["errors"] == info["reflex_reason"]


def test_the_same_policy_without_enforcement_runs_on_and_reports_the_violations():
    env = gym.make("FrankaFCI-v0", action_filter="none", enforce_motion_limits=False)
    env.reset(seed=1)
    obs, reward, terminated, truncated, info = naive_steps(env)
    assert not terminated
    assert info["robot_mode"] == "kMove" and info["errors"] == ()
    assert "joint_motion_generator_velocity_discontinuity" in info["violations"]


def test_the_rate_limited_policy_trips_nothing_where_the_naive_one_aborts():
    # libfranka's low-pass + rate limiter. (At full saturation near a shrinking
    # velocity envelope libfranka's limiter itself can exceed the jerk bound:
    # docs/env.md. Half actions stay clear of that.)
    env = gym.make("FrankaFCI-v0")
    env.reset(seed=2)
    for sign in (1, -1, 1, 1, -1):
        action = np.full(7, 0.5 * sign, dtype=np.float32)
        obs, reward, terminated, truncated, info = env.step(action)
        assert not terminated, info
        assert info["violations"] == ()


def test_a_reflex_is_never_a_shortcut_to_a_higher_return():
    env = gym.make("FrankaFCI-v0", action_filter="none", max_episode_steps=10)
    env.reset(seed=1)
    total = 0.0
    for _ in range(2):
        _, reward, terminated, _, _ = env.step(np.full(7, 0.9, dtype=np.float32))
        total += reward
        if terminated:
            break
    assert terminated
    # the worst full episode of sparse rewards returns -10
    assert total <= -10.0


def test_her_relabelling_a_reflex_step_keeps_the_charge():
    """compute_reward of a step's own transition is the step's reward; relabelled with the
    goal it reached (what HER's "future" does with an episode's last step), a reflex step
    is still charged the rest of the episode, never a free success."""
    env = gym.make("FrankaFCI-v0", action_filter="none", max_episode_steps=10)
    env.reset(seed=1)
    for _ in range(2):
        obs, reward, terminated, _, info = env.step(np.full(7, 0.9, dtype=np.float32))
        if terminated:
            break
    assert terminated and info["reflex_penalty"] < -1.0
    u = env.unwrapped
    assert u.compute_reward(obs["achieved_goal"], obs["desired_goal"], info) == reward
    relabelled = u.compute_reward(obs["achieved_goal"][None], obs["achieved_goal"][None], [info])
    assert relabelled[0] == info["reflex_penalty"] < -1.0
    quiet = {**info, "reflex_penalty": 0.0}
    assert u.compute_reward(obs["achieved_goal"], obs["achieved_goal"], quiet) == 0.0


class ScriptedChannel(Channel):
    """Drops the datagrams of cycles [start, stop) counted from the episode's first command."""

    def __init__(self, start: int, stop: int) -> None:
        self.start, self.stop = start, stop

    def reset(self, rng) -> None:
        super().reset(rng)
        self.k = 0

    def transmit(self, command):
        self.k += 1
        return [] if self.start <= self.k - 1 < self.stop else [command]


def test_a_scripted_lossy_channel_shows_lost_cycles_then_communication_violation():
    env = gym.make("FrankaFCI-v0", channel=ScriptedChannel(50, 60))
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.zeros(7, dtype=np.float32))  # cycles 0..39
    assert info["lost_cycles"] == 0
    _, _, terminated, _, info = env.step(np.zeros(7, dtype=np.float32))  # cycles 40..79
    assert info["lost_cycles"] == 10 and info["longest_lost_run"] == 10
    assert not terminated
    assert 0.8 < info["control_command_success_rate"] < 1.0
    env2 = gym.make("FrankaFCI-v0", channel=ScriptedChannel(50, 80))
    env2.reset(seed=0)
    env2.step(np.zeros(7, dtype=np.float32))
    _, _, terminated, _, info = env2.step(np.zeros(7, dtype=np.float32))
    assert terminated
    assert info["reflex_reason"] == ("communication_constraints_violation",)


def test_bad_arguments_are_clear_errors():
    with pytest.raises(ValueError, match="policy_hz"):
        gym.make("FrankaFCI-v0", policy_hz=30)
    with pytest.raises(ValueError, match="action_interface"):
        gym.make("FrankaFCI-v0", action_interface="cartesian_jazz")
    with pytest.raises(ValueError, match="action_filter"):
        gym.make("FrankaFCI-v0", action_filter="smooth")
    env = gym.make("FrankaFCI-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="finite"):
        env.step(np.full(7, np.nan, dtype=np.float32))


def test_rgb_array_renders_the_arm_and_the_goal():
    env = gym.make("FrankaFCI-v0", render_mode="rgb_array", width=160, height=120)
    env.reset(seed=0)
    env.step(np.zeros(7, dtype=np.float32))
    frame = env.render()
    assert frame.shape == (120, 160, 3) and frame.dtype == np.uint8
    assert frame.std() > 10  # not a blank image
    red = (frame[..., 0] > 150) & (frame[..., 1] < 80) & (frame[..., 2] < 80)
    assert red.sum() > 10  # the goal marker is in view
    env.close()


def test_the_gripper_dimension_drives_the_hand_at_its_speed():
    env = gym.make("FrankaFCI-v0", gripper=True, gripper_speed=0.1)
    assert env.action_space.shape == (8,)
    obs, _ = env.reset(seed=0)
    assert obs["observation"].shape == (24,)  # q, dq, EE position, twist, width
    assert obs["observation"][-1] == pytest.approx(0.08, abs=1e-3)  # open
    action = np.zeros(8, dtype=np.float32)
    action[7] = -1.0  # close
    for _ in range(5):  # 0.2 s at 0.1 m/s: 2 cm
        obs, _, terminated, _, info = env.step(action)
        assert not terminated, info
    assert obs["observation"][-1] == pytest.approx(0.06, abs=0.005)
    check_env(env.unwrapped, skip_render_check=True)


def test_the_mounted_hand_is_in_the_arm_dynamics():
    # docs/fr3-model.md §6 / the model's hand: joint 4 holds 18.96 Nm bare, ~22.26 Nm with the hand
    bare, hand = gym.make("FrankaFCI-v0"), gym.make("FrankaFCI-v0", gripper=True)
    torques = []
    for env in (bare, hand):
        env.reset(seed=0, options=None)
        env.unwrapped.reset_noise = 0.0
        env.reset(seed=0)
        _, _, _, _, _ = env.step(np.zeros(env.action_space.shape, dtype=np.float32))
        torques.append(float(env.unwrapped.controller.states[0]["tau_J"][3]))
    assert torques[0] == pytest.approx(18.96, abs=0.3)
    assert torques[1] - torques[0] == pytest.approx(3.3, abs=0.3)


def test_with_the_hand_the_achieved_goal_is_its_tcp():
    """gripper=True mounts the Franka Hand configured as Desk does (F_T_NE at its TCP):
    O_T_EE, and so the reach task's achieved goal, is the point between the fingertips."""
    env = gym.make("FrankaFCI-v0", gripper=True)
    obs, _ = env.reset(seed=0)
    physics = env.unwrapped.controller.physics
    tcp = physics.data.site_xpos[physics.layout.tcp_site[0]] - physics.base_pos[0]
    flange, _ = physics.flange_pose()
    np.testing.assert_allclose(obs["achieved_goal"], tcp, atol=1e-5)
    np.testing.assert_allclose(obs["observation"][14:17], tcp, atol=1e-5)
    assert np.linalg.norm(obs["achieved_goal"] - flange[0]) == pytest.approx(0.1034, abs=1e-5)
