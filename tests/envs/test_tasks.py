"""The task protocol: a task is injected into the batched core, draws from the env's
random stream, adds observation entries and its own achieved goal."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.utils.env_checker import check_env

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.envs import IDS, task_ids
from franka_sim_gym.envs.fci_env import FrankaFCIEnv
from franka_sim_gym.envs.tasks import TASKS, Reach, Task, make_task
from franka_sim_gym.envs.tasks.base import charged
from franka_sim_gym.envs.vector_env import FrankaFCIVectorEnv


class Height(Task):
    """A toy task: bring the end effector's (x, z) to a goal; observes its height and a
    number drawn at reset (what an object's pose would be)."""

    id_name = "Height"
    goal_dim = 2

    def sample_goal(self, rng):
        return rng.uniform([0.3, 0.2], [0.6, 0.6])

    def reset(self, arms, rngs, physics):
        goals = super().reset(arms, rngs, physics)
        if not hasattr(self, "drawn"):
            self.drawn = np.zeros(physics.n)
        self.drawn[arms] = [rngs[i].uniform() for i in arms.tolist()]
        return goals

    def extra_space(self):
        return spaces.Box(np.float32([-2.0, 0.0]), np.float32([2.0, 1.0]))

    def observe(self, physics, ee):
        return ee[:, [0, 2]], np.stack([ee[:, 2], self.drawn], axis=1)

    def compute_reward(self, achieved_goal, desired_goal, info=None):
        d = np.linalg.norm(np.asarray(achieved_goal) - np.asarray(desired_goal), axis=-1)
        return charged(-d.astype(np.float32), info)

    def is_success(self, achieved_goal, desired_goal):
        d = np.linalg.norm(np.asarray(achieved_goal) - np.asarray(desired_goal), axis=-1)
        return d < 0.05

    @property
    def worst_step_reward(self):
        return -2.0


def test_a_task_adds_observation_entries_and_its_own_goal():
    env = FrankaFCIEnv(task=Height(), action_interface="cartesian_velocity")
    assert env.observation_space["observation"].shape == (23 + 2,)
    assert env.observation_space["desired_goal"].shape == (2,)
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    ee = obs["observation"][14:17]
    assert obs["achieved_goal"].tolist() == ee[[0, 2]].tolist()
    assert obs["observation"][23] == ee[2] and 0 <= obs["observation"][24] < 1
    obs, reward, *_ = env.step(np.full(6, 0.3, np.float32))
    expected = env.compute_reward(obs["achieved_goal"], obs["desired_goal"], info)
    assert reward == pytest.approx(float(expected))
    check_env(env, skip_render_check=True)


def test_a_task_draws_from_the_env_stream_after_the_start_pose():
    # Reach draws the start pose, then the goal, from the arm's stream (draw_episode):
    # a task's own draws follow, so the same seed gives the same episode.
    a, b = FrankaFCIEnv(task=Height()), FrankaFCIEnv(task=Height())
    first, second = a.reset(seed=4)[0], b.reset(seed=4)[0]
    assert first["observation"].tobytes() == second["observation"].tobytes()
    reach = FrankaFCIEnv().reset(seed=4)[0]
    assert first["observation"][:7].tobytes() == reach["observation"][:7].tobytes()


def test_the_vector_env_runs_a_task_as_single_envs_do():
    vec = FrankaFCIVectorEnv(3, task=Height(), action_interface="cartesian_velocity")
    singles = [FrankaFCIEnv(task=Height(), action_interface="cartesian_velocity") for _ in range(3)]
    obs, _ = vec.reset(seed=9)
    for i, env in enumerate(singles):
        assert env.reset(seed=9 + i)[0]["observation"].tobytes() == obs["observation"][i].tobytes()
    actions = np.random.default_rng(0).uniform(-0.5, 0.5, size=(3, 6)).astype(np.float32)
    obs, reward, *_ = vec.step(actions)
    for i, env in enumerate(singles):
        single = env.step(actions[i])
        assert single[0]["observation"].tobytes() == obs["observation"][i].tobytes()
        assert single[1] == reward[i]


def test_every_task_of_TASKS_is_registered_per_interface():
    ids = task_ids()
    assert set(ids) == set(IDS)
    for name in TASKS:
        assert any(kwargs["task"] == name for kwargs in ids.values())
    assert IDS["FrankaFCI-v0"] == {"task": "reach", "action_interface": "joint_position"}
    assert IDS["FrankaFCICartesianVelocity-v0"]["action_interface"] == "cartesian_velocity"
    assert all(gym.spec(env_id).kwargs == kwargs for env_id, kwargs in IDS.items())


def test_task_arguments_and_errors():
    env = gym.make("FrankaFCI-v0", reward_type="dense", distance_threshold=0.1)
    assert isinstance(env.unwrapped.task, Reach) and env.unwrapped.task.reward_type == "dense"
    with pytest.raises(ValueError, match="unknown task 'stack'"):
        make_task("stack")
    with pytest.raises(ValueError, match="reward_type"):
        make_task("reach", reward_type="shaped")
    with pytest.raises(TypeError, match="colour"):
        FrankaFCIEnv(colour="red")

    class WithScene(Height):
        scene = "<mujoco/>"

    with pytest.raises(ValueError, match="'<mujoco/>' is not a shipped scene"):
        FrankaFCIEnv(task=WithScene())
    with pytest.raises(ValueError, match="has its own scene .* scene must be None"):
        FrankaFCIEnv(task=WithScene(), scene="block")


def test_a_reflex_freezes_the_tasks_observation_at_its_cycle():
    # Arm 1 of the vector env trips a reflex mid-step (a held jump, tests/envs/test_env.py);
    # its extras and achieved goal are those of the cycle it stopped at, as a single
    # env's, while arm 0 runs on.
    kwargs = {"task": Height(), "action_filter": "none"}
    vec = FrankaFCIVectorEnv(2, **kwargs)
    single = FrankaFCIEnv(**{**kwargs, "task": Height()})
    vec.reset(seed=3)
    single.reset(seed=4)
    actions = np.zeros((2, 7), np.float32)
    actions[1] = 0.9
    for _ in range(2):
        obs, reward, terminated, _, info = vec.step(actions)
        expected = single.step(actions[1])
    assert terminated.tolist() == [False, True] and expected[2]
    assert obs["observation"][1].tobytes() == expected[0]["observation"].tobytes()
    assert obs["achieved_goal"][1].tobytes() == expected[0]["achieved_goal"].tobytes()
    assert reward[1] == expected[1] and info["cycles"][1] == expected[4]["cycles"] < 80
