"""What every manipulation task owes the core: a clean Gymnasium env, episodes that are a
function of their seed and actions, and a native vector env equal to single envs while
objects are pushed, held and dropped: arm 0 bit for bit (the world's sparse constraint
Jacobian: sim/world.py), the others to ~1e-12 (MuJoCo computes contacts in world
coordinates, and arm i stands 2 i m from the origin: docs/env.md, "Native vector env")."""

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


@pytest.mark.parametrize("env_id", TASK_IDS)
def test_the_native_vector_env_equals_single_envs(env_id):
    n, steps = 3, 30
    actions = downward_actions(env_id, n, steps, seed=1)
    vec = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point",
                       max_episode_steps=12)  # fmt: skip
    assert isinstance(vec, FrankaFCIVectorEnv)
    kwargs = {**gym.spec(env_id).kwargs, "max_episode_steps": 12}
    sync = SyncVectorEnv(
        [lambda: FrankaFCIEnv(**kwargs) for _ in range(n)], autoreset_mode=AutoresetMode.NEXT_STEP
    )

    def first_arm(out):
        obs, *rest, info = out
        return (
            {key: value[:1] for key, value in obs.items()},
            *(np.asarray(x)[:1] for x in rest),
            {key: value[:1] for key, value in info.items()},
        )

    a, b = vec.reset(seed=5), sync.reset(seed=5)
    assert_same(first_arm(a), first_arm(b))
    ended = 0
    for t in range(steps):
        a, b = vec.step(actions[t]), sync.step(actions[t])
        assert_same(first_arm(a), first_arm(b))
        for key in a[0]:
            np.testing.assert_allclose(a[0][key], b[0][key], rtol=0, atol=1e-9)
        np.testing.assert_allclose(a[1], b[1], rtol=0, atol=1e-9)
        for x, y in zip(a[2:4], b[2:4], strict=True):
            assert np.array_equal(x, y)
        assert a[-1]["reflex_reason"].tolist() == b[-1]["reflex_reason"].tolist()
        ended += int(np.sum(a[2] | a[3]))
    assert ended >= n  # autoresets happened on the way
    assert IDS[env_id]["task"] != "reach"


def test_rendering_shows_the_objects():
    env = gym.make("FrankaFCIPush-v0", render_mode="rgb_array", width=160, height=120)
    env.reset(seed=0)
    frame = env.render().astype(int)
    r, g, b = frame[..., 0], frame[..., 1], frame[..., 2]
    orange = (r > 150) & (g > 50) & (g < 130) & (b < 80)  # the block (scenes/block.xml)
    assert orange.sum() > 5
    env.close()
