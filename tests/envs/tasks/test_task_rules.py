"""What every manipulation task owes the core: a clean Gymnasium env, episodes that are a
function of their seed and actions, and a native vector env equal to single envs, every
arm bit for bit, while objects are pushed, held and dropped (each arm steps its own
MjData of one one-arm world: sim/arm.py, docs/env.md "Native vector env")."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AutoresetMode, SyncVectorEnv

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.envs import IDS
from franka_sim_gym.envs.fci_env import FrankaFCIEnv
from franka_sim_gym.envs.vector_env import FrankaFCIVectorEnv
from tests.envs.test_vector_env import assert_same

TASK_IDS = ["FrankaFCIPush-v0", "FrankaFCIPickAndPlace-v0", "FrankaFCIPegInsertion-v0"]


def downward_actions(env_id: str, n: int, steps: int, seed: int = 0) -> np.ndarray:
    """Random actions biased down (z of the Cartesian ones): the hand meets the table,
    the objects and, on some arms, the robot's reflexes."""
    dim = gym.spec(env_id)
    shape = FrankaFCIEnv(**dim.kwargs).action_space.shape
    rng = np.random.default_rng(seed)
    a = rng.uniform(-0.6, 0.6, size=(steps, n, *shape))
    if dim.kwargs["action_interface"].startswith("cartesian"):
        a[..., 2] -= 0.4
    return np.clip(a, -1, 1).astype(np.float32)


@pytest.mark.parametrize("env_id", TASK_IDS)
def test_check_env_is_clean(env_id):
    env = gym.make(env_id)
    check_env(env.unwrapped, skip_render_check=True)


@pytest.mark.parametrize("env_id", TASK_IDS)
def test_an_episode_is_a_function_of_its_seed_and_actions(env_id):
    actions = downward_actions(env_id, 1, 30)[:, 0]
    env = gym.make(env_id)

    def episode(seed):
        out = [env.reset(seed=seed)[0]]
        for a in actions:
            obs, reward, terminated, truncated, _ = env.step(a)
            out.append({**obs, "reward": np.float64(reward)})
            if terminated or truncated:
                break
        return out

    first = episode(3)
    episode(4)  # another episode in between changes nothing
    again = episode(3)
    assert len(first) == len(again)
    for x, y in zip(first, again, strict=True):
        for key in x:
            assert np.asarray(x[key]).tobytes() == np.asarray(y[key]).tobytes(), key
    other = gym.make(env_id).reset(seed=4)[0]
    assert other["observation"].tobytes() != first[0]["observation"].tobytes()


def towards_the_objects(obs: dict, noise: np.ndarray) -> np.ndarray:
    """Cartesian velocity actions driving every hand at its object (the last 13
    observation entries start with its position; the EE position is entries 14:17) at up
    to 0.3 m/s, with ``noise`` (n, action size) on top: objects get pushed, knocked over,
    carried, and some arms trip reflexes."""
    o = obs["observation"].astype(np.float64)
    a = noise.copy()
    a[:, :3] += np.clip((o[:, -13:-10] - o[:, 14:17]) * 30.0, -1.0, 1.0)
    return np.clip(a, -1, 1).astype(np.float32)


@pytest.mark.parametrize("env_id", ["FrankaFCI-v0", *TASK_IDS])
def test_the_native_vector_env_equals_single_envs(env_id):
    scene = IDS[env_id]["task"] != "reach"
    n, steps, length = 3, (60 if scene else 30), (25 if scene else 12)
    actions = downward_actions(env_id, n, steps, seed=1)
    vec = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point",
                       max_episode_steps=length)  # fmt: skip
    assert isinstance(vec, FrankaFCIVectorEnv)
    kwargs = {**gym.spec(env_id).kwargs, "max_episode_steps": length}
    sync = SyncVectorEnv(
        [lambda: FrankaFCIEnv(**kwargs) for _ in range(n)], autoreset_mode=AutoresetMode.NEXT_STEP
    )
    a, b = vec.reset(seed=5), sync.reset(seed=5)
    assert_same(a, b)  # every arm, bit for bit
    ended = moved = 0
    for t in range(steps):
        action = towards_the_objects(a[0], actions[t] / 4) if scene else actions[t]
        a, b = vec.step(action), sync.step(action)
        assert_same(a, b)
        assert a[-1]["reflex_reason"].tolist() == b[-1]["reflex_reason"].tolist()
        ended += int(np.sum(a[2] | a[3]))
        if scene:  # the objects of arms 1, 2 moved: pushed, carried or dropped
            speed = np.abs(a[0]["observation"][1:, -6:-3]).max(axis=1)
            moved += int(np.count_nonzero(speed > 0.01))
    assert ended >= n  # autoresets happened on the way
    if scene:
        assert moved >= 3, moved


def test_rendering_shows_the_objects():
    env = gym.make("FrankaFCIPush-v0", render_mode="rgb_array", width=160, height=120)
    env.reset(seed=0)
    frame = env.render().astype(int)
    r, g, b = frame[..., 0], frame[..., 1], frame[..., 2]
    orange = (r > 150) & (g > 50) & (g < 130) & (b < 80)  # the block (scenes/block.xml)
    assert orange.sum() > 5
    env.close()
