"""The native vector env: N arms in one world behave exactly as N single envs."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode, SyncVectorEnv

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.envs import IDS
from franka_sim_gym.envs.fci_env import FrankaFCIEnv
from franka_sim_gym.envs.vector_env import FrankaFCIVectorEnv


def make_vec(n: int, **kwargs) -> FrankaFCIVectorEnv:
    env = gym.make_vec(
        "FrankaFCI-v0", num_envs=n, vectorization_mode="vector_entry_point", **kwargs
    )
    assert isinstance(env, FrankaFCIVectorEnv)
    return env


def make_sync(n: int, channels=None, autoreset_mode="next_step", **kwargs) -> SyncVectorEnv:
    def single(i):
        extra = {} if channels is None else {"channel": channels[i]}
        return lambda: FrankaFCIEnv(**kwargs, **extra)

    mode = AutoresetMode[autoreset_mode.upper()]
    return SyncVectorEnv([single(i) for i in range(n)], autoreset_mode=mode)


def same_value(x, y) -> bool:
    """Equal bit for bit, through the dicts and object arrays of final_obs / final_info."""
    if isinstance(x, dict):
        return set(x) == set(y) and all(same_value(x[k], y[k]) for k in x)
    if isinstance(x, np.ndarray) and x.dtype == object:
        return len(x) == len(y) and all(same_value(a, b) for a, b in zip(x, y, strict=True))
    if isinstance(x, np.ndarray):
        return x.dtype == np.asarray(y).dtype and x.tobytes() == np.asarray(y).tobytes()
    return x == y


def assert_same(a, b) -> None:
    """Bit for bit: observations, rewards, terminations and every info entry."""
    obs_a, obs_b = a[0], b[0]
    for key in ("observation", "achieved_goal", "desired_goal"):
        assert obs_a[key].dtype == obs_b[key].dtype == np.float32
        assert obs_a[key].tobytes() == obs_b[key].tobytes(), key
    for x, y in zip(a[1:-1], b[1:-1], strict=True):
        assert np.asarray(x).tobytes() == np.asarray(y).tobytes()
    info_a, info_b = a[-1], b[-1]
    assert set(info_a) == set(info_b)
    for key in info_a:
        assert same_value(info_a[key], info_b[key]), key


def run_both(n, steps, actions_of, channels=None, **kwargs):
    """Step the native vector env and a SyncVectorEnv of single envs side by side."""
    vec = make_vec(n, channel=channels, **kwargs)
    sync = make_sync(n, channels, **kwargs)
    out_vec, out_sync = vec.reset(seed=11), sync.reset(seed=11)
    assert_same(out_vec, out_sync)
    ended = 0
    for t in range(steps):
        actions = actions_of(t)
        out_vec, out_sync = vec.step(actions), sync.step(actions)
        assert_same(out_vec, out_sync)
        ended += int(np.sum(out_vec[2] | out_vec[3]))
    return ended, out_vec


def test_vector_env_equals_single_envs_with_per_arm_channels():
    rng = np.random.default_rng(0)
    channels = ["loss:0.05", None, "delay:0-3", "bursty"]
    actions = rng.uniform(-0.7, 0.7, size=(45, 4, 7)).astype(np.float32)
    ended, _ = run_both(4, 45, lambda t: actions[t], channels, max_episode_steps=12)
    assert ended >= 8  # autoresets happened on the way (45 steps, episodes of 12)


def test_vector_env_equals_single_envs_through_reflexes():
    # A naive client on odd arms trips reflexes (and autoresets) while even arms hold.
    rng = np.random.default_rng(1)

    def actions(t):
        a = rng.uniform(-0.9, 0.9, size=(4, 7)).astype(np.float32)
        a[::2] = 0.0
        return a

    ended, last = run_both(4, 12, actions, action_filter="none", max_episode_steps=50)
    assert ended >= 4


@pytest.mark.parametrize(
    "interface", ["joint_velocity", "torque", "cartesian_pose", "cartesian_velocity"]
)
@pytest.mark.parametrize("autoreset_mode", ["next_step", "same_step"])
def test_vector_env_equals_single_envs_for_the_other_interfaces(interface, autoreset_mode):
    # Through autoresets of episodes truncated in motion (every 5 steps): the reset is
    # where a Cartesian motion's twist used to leak into the single env's next episode.
    rng = np.random.default_rng(2)
    dim = 6 if interface.startswith("cartesian") else 7
    actions = rng.uniform(-0.3, 0.3, size=(12, 3, dim)).astype(np.float32)
    ended, _ = run_both(
        3,
        12,
        lambda t: actions[t],
        action_interface=interface,
        max_episode_steps=5,
        autoreset_mode=autoreset_mode,
    )
    assert ended >= 6


def test_vector_env_with_gripper_equals_single_envs():
    rng = np.random.default_rng(3)
    actions = rng.uniform(-1, 1, size=(6, 2, 8)).astype(np.float32)
    actions[:, :, :7] *= 0.3
    run_both(2, 6, lambda t: actions[t], gripper=True, max_episode_steps=4)


def test_make_vec_works_for_every_id_and_sets_next_step_autoreset():
    for env_id in IDS:
        env = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point")
        assert isinstance(env, FrankaFCIVectorEnv)
        assert env.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
        obs, info = env.reset(seed=0)
        assert env.observation_space.contains(obs)
        obs, *_ = env.step(env.action_space.sample() * 0.1)
        assert env.observation_space.contains(obs)


def test_next_step_autoreset_resets_the_ended_arm_and_ignores_its_action():
    env = make_vec(2, max_episode_steps=3)
    obs, _ = env.reset(seed=5)
    zero = np.zeros((2, 7), dtype=np.float32)
    for _ in range(3):
        obs, reward, terminated, truncated, info = env.step(zero)
    assert truncated.all() and not terminated.any()
    goals = obs["desired_goal"].copy()
    actions = zero.copy()
    actions[:] = np.nan  # the arms waiting for their reset ignore their actions
    obs, reward, terminated, truncated, info = env.step(actions)
    assert not (terminated | truncated).any()
    assert reward.tolist() == [0.0, 0.0]
    assert info["cycles"].tolist() == [0, 0] and info["robot_mode"].tolist() == ["kMove"] * 2
    assert not np.array_equal(obs["desired_goal"], goals)  # new episodes, new goals
    obs, reward, terminated, truncated, info = env.step(zero)
    assert info["cycles"].tolist() == [40, 40]


def test_same_step_autoreset_returns_the_final_observation_in_info():
    env = make_vec(2, max_episode_steps=2, autoreset_mode="same_step")
    env.reset(seed=5)
    zero = np.zeros((2, 7), dtype=np.float32)
    env.step(zero)
    obs, reward, terminated, truncated, info = env.step(zero)
    assert truncated.all()
    assert info["_final_obs"].all()
    final = info["final_obs"][0]
    assert final["desired_goal"].tobytes() != obs["desired_goal"][0].tobytes()
    # Gymnasium's layout (SyncVectorEnv's): final_info is a vector info of its own
    assert info["final_info"]["cycles"].tolist() == [80, 80] and info["cycles"].tolist() == [0, 0]
    assert info["final_info"]["_cycles"].all()


def test_a_reflex_on_one_arm_does_not_disturb_the_others():
    channels = ["delay:2", None, "loss:0.1"]
    calm = np.zeros((3, 7), dtype=np.float32)
    wild = calm.copy()
    wild[1] = 0.9  # a 0.09 rad jump held: a velocity discontinuity
    runs = []
    for actions in (calm, wild):
        env = make_vec(3, channel=channels, action_filter="none", max_episode_steps=50)
        out = [env.reset(seed=3)]
        for _ in range(5):  # the start, the reflex, the autoreset, and steps after it
            out.append(env.step(actions))
        runs.append(out)
    # The first step's jump is inside the start-pose tolerance; the second trips.
    reflexed = runs[1][2]
    assert reflexed[2].tolist() == [False, True, False]
    assert "joint_motion_generator_velocity_discontinuity" in reflexed[4]["reflex_reason"][1]
    assert runs[1][3][4]["cycles"][1] == 0  # arm 1 was reset
    for a, b in zip(runs[0], runs[1], strict=True):
        for key in a[0]:
            assert a[0][key][[0, 2]].tobytes() == b[0][key][[0, 2]].tobytes()
        for key in ("lost_cycles", "cycles", "control_command_success_rate", "robot_mode"):
            assert a[-1][key][[0, 2]].tolist() == b[-1][key][[0, 2]].tolist()


def test_bad_actions_are_clear_errors():
    env = make_vec(2)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros((3, 7)))
    bad = np.zeros((2, 7))
    bad[1, 2] = np.nan
    with pytest.raises(ValueError, match=r"finite: arm\(s\) \[1\]"):
        env.step(bad)
