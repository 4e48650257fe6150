"""The env as Gymnasium and SB3 users use it: the episode length in the spec and in
gym.make, copies, rendering without a display, RecordVideo, out-of-range actions."""

from __future__ import annotations

import copy
import os
import pickle
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.utils.passive_env_checker import env_render_passive_checker

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.envs import EPISODE_STEPS, IDS
from franka_sim_gym.envs.fci_env import FrankaFCIEnv
from franka_sim_gym.envs.tasks import TASKS
from franka_sim_gym.sim.render import BACKGROUND
from tests.envs.test_env import same


@pytest.mark.parametrize("env_id", list(IDS))
def test_every_id_carries_its_episode_length_in_its_spec(env_id):
    length = TASKS[IDS[env_id]["task"]].max_episode_steps  # Reach's: EPISODE_STEPS
    assert gym.spec(env_id).max_episode_steps == length
    env = gym.make(env_id)
    assert env.spec.max_episode_steps == length
    assert env.unwrapped.max_episode_steps == length
    assert FrankaFCIEnv(**IDS[env_id]).max_episode_steps == length
    assert TASKS["reach"].max_episode_steps == EPISODE_STEPS


def run_until_done(env, action, limit=200):
    steps = 0
    while steps < limit:
        _, reward, terminated, truncated, info = env.step(action)
        steps += 1
        if terminated or truncated:
            return steps, reward, terminated, truncated, info
    raise AssertionError("the episode never ended")


def test_gym_make_max_episode_steps_is_the_length_in_force():
    env = gym.make("FrankaFCI-v0", max_episode_steps=80)
    assert env.spec.max_episode_steps == 80 and env.unwrapped.max_episode_steps == 80
    env.reset(seed=0)
    steps, _, terminated, truncated, _ = run_until_done(env, np.zeros(7, dtype=np.float32))
    assert (steps, terminated, truncated) == (80, False, True)
    # make_vec, both ways
    for mode in ("vector_entry_point", "sync"):
        vec = gym.make_vec("FrankaFCI-v0", num_envs=2, vectorization_mode=mode, max_episode_steps=7)
        vec.reset(seed=0)
        for t in range(7):
            _, _, terminated, truncated, _ = vec.step(np.zeros((2, 7)))
            assert truncated.all() == (t == 6) and not terminated.any()


def test_the_reflex_charge_counts_the_steps_of_the_length_in_force():
    # A naive held jump trips a reflex on the second step (tests/envs/test_env.py): the
    # charge is the worst reward for that step and every one the episode would still have
    # had, by the length gym.make was given.
    for length in (20, 80):
        env = gym.make("FrankaFCI-v0", max_episode_steps=length, action_filter="none")
        env.reset(seed=1)
        steps, reward, terminated, _, info = run_until_done(env, np.full(7, 0.9, np.float32))
        assert terminated and steps == 2
        assert info["reflex_penalty"] == -1.0 * (length - steps + 1)


def step_all(env, actions):
    return [env.step(a) for a in actions]


def assert_same_steps(a, b):
    for x, y in zip(a, b, strict=True):
        for key in x[0]:
            assert x[0][key].tobytes() == y[0][key].tobytes(), key
        assert same(x[1:], y[1:])


@pytest.mark.parametrize(
    "env_id, kwargs",
    [
        ("FrankaFCICartesianVelocity-v0", {"channel": "delay:0-3"}),
        ("FrankaFCI-v0", {"channel": "loss:0.05", "gripper": True}),
        ("FrankaFCITorque-v0", {"reset_mode": "fci"}),
    ],
)
def test_a_copy_continues_exactly_as_the_original(env_id, kwargs):
    env = gym.make(env_id, max_episode_steps=30, **kwargs)
    shape = env.action_space.shape
    actions = np.random.default_rng(4).uniform(-0.4, 0.4, size=(40, *shape)).astype(np.float32)
    env.reset(seed=7)
    step_all(env, actions[:30])  # one episode (truncated), then the next one mid-way
    env.reset()
    step_all(env, actions[:6])
    deep = copy.deepcopy(env)
    pickled = pickle.loads(pickle.dumps(env))
    assert deep.unwrapped is not env.unwrapped
    assert deep.unwrapped.controller.physics.data is not env.unwrapped.controller.physics.data
    rest = actions[6:20]
    original = step_all(env, rest)
    assert_same_steps(original, step_all(deep, rest))
    assert_same_steps(original, step_all(pickled, rest))
    # ... and their next episodes, drawn from the random state they share
    following = env.reset()[0]
    for clone in (deep, pickled):
        assert clone.reset()[0]["observation"].tobytes() == following["observation"].tobytes()
    # the copies are independent of the original
    deep.step(actions[0])
    assert env.unwrapped.core.steps[0] == 0 and deep.unwrapped.core.steps[0] == 1


def test_a_fresh_env_copies_and_pickles():
    env = FrankaFCIEnv()
    clone = pickle.loads(pickle.dumps(env))
    a, b = env.reset(seed=3)[0], clone.reset(seed=3)[0]
    assert a["observation"].tobytes() == b["observation"].tobytes()


HEADLESS = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}


def test_human_rendering_without_a_display_is_a_clear_python_error():
    # In a child process: GLFW ends the process (exit 1, no Python exception) when it
    # cannot open a display.
    script = (
        "import gymnasium as gym, franka_sim_gym\n"
        "try:\n"
        "    env = gym.make('FrankaFCI-v0', render_mode='human')\n"
        "    env.reset(seed=0)\n"
        "    env.render()\n"
        "except RuntimeError as e:\n"
        "    print('RuntimeError:', e)\n"
        "print('still alive')\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", script], env=HEADLESS, capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 0, out.stderr
    assert "RuntimeError: render_mode='human' needs a display" in out.stdout
    assert "render_mode='rgb_array'" in out.stdout and "still alive" in out.stdout


@pytest.mark.parametrize("env_id", list(IDS))
def test_gymnasium_check_env_with_the_render_check(env_id):
    env = gym.make(env_id, render_mode="rgb_array", width=96, height=72)
    if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
        check_env(env.unwrapped)  # makes an env per render mode, "human" too
    else:
        # check_env's render check makes a "human" env too, which headless raises the
        # RuntimeError above: the rgb_array frames are checked here (offscreen EGL).
        check_env(env.unwrapped, skip_render_check=True)
        env.reset(seed=0)
        env_render_passive_checker(env.unwrapped)
        frame = env.render()
        assert frame.shape == (72, 96, 3) and frame.dtype == np.uint8
    env.close()


@pytest.mark.parametrize("env_id", list(IDS))
def test_sb3_check_env(env_id):
    sb3_env_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    sb3_env_checker.check_env(gym.make(env_id).unwrapped, warn=True)


def test_frames_have_no_black_band_at_the_top():
    env = gym.make("FrankaFCI-v0", render_mode="rgb_array")
    env.reset(seed=0)
    frame = env.render()
    # The camera sees past the floor there: the background, not MuJoCo's black.
    assert frame[:20].reshape(-1, 3).min(axis=0).tolist() == list(BACKGROUND)
    env.close()


def test_record_video_wraps_the_env_out_of_the_box(tmp_path):
    pytest.importorskip("moviepy", reason="RecordVideo's dependency (the train extra)")
    env = gym.make(
        "FrankaFCICartesianVelocity-v0",
        render_mode="rgb_array",
        width=96,
        height=72,
        max_episode_steps=6,
    )
    env = gym.wrappers.RecordVideo(env, str(tmp_path / "videos"), episode_trigger=lambda _: True)
    env.reset(seed=0)
    done = False
    while not done:
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        done = terminated or truncated
    env.close()
    (video,) = (tmp_path / "videos").glob("*.mp4")
    assert video.stat().st_size > 1000
    assert env.metadata["render_fps"] == 25  # one frame per policy step: real time
    slow = gym.make("FrankaFCI-v0", render_mode="rgb_array", policy_hz=10)
    assert slow.metadata["render_fps"] == 10


def test_the_record_video_example_writes_a_gif_of_every_step(tmp_path):
    Image = pytest.importorskip("PIL.Image", reason="Pillow writes the GIF (the train extra)")

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "examples"))
    from record_video import record

    out = record(
        lambda obs: np.zeros(3, dtype=np.float32),
        "FrankaFCICartesianVelocity-v0",
        {"cartesian_dof": 3, "max_episode_steps": 5},
        tmp_path / "policy.gif",
        episodes=2,
        size=(96, 72),
    )
    with Image.open(out) as gif:  # Pillow merges equal frames, adding their durations
        durations = []
        for k in range(gif.n_frames):
            gif.seek(k)
            durations.append(gif.info["duration"])
        assert gif.size == (96, 72)
    assert sum(durations) == 2 * (5 + 1) * 40  # two episodes of 5 steps and a reset, 25 Hz


@pytest.mark.parametrize("env_id", ["FrankaFCI-v0", "FrankaFCICartesianVelocity-v0"])
def test_out_of_range_actions_are_clipped_as_documented(env_id):
    runs = []
    for scale in (1.0, 3.0):  # 3x: every component beyond the Box, clipped back to it
        env = gym.make(env_id, enforce_motion_limits=False)
        env.reset(seed=2)
        action = np.full(env.action_space.shape, scale, np.float32)
        runs.append([env.step(action) for _ in range(3)])
    assert_same_steps(*runs)
    # ... and said where users look: the action table and the env's docstring
    docs = (Path(__file__).resolve().parents[2] / "docs" / "env.md").read_text()
    actions = " ".join(docs.split("## Actions", 1)[1].split("\n## ", 1)[0].split())
    assert "Values outside [-1, 1] are clipped" in actions
    assert "clipped" in FrankaFCIEnv.__doc__
