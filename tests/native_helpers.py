"""Shared by the C kernels' tests (tests/*/test_native_*.py): exact comparison, joint
samples, a random-action episode, and the switch to the numpy reference paths."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

import franka_sim_gym.envs.commands as commands_module
from franka_sim_gym.fci.tables import FR3


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    a, b = np.ascontiguousarray(a, dtype=np.float64), np.ascontiguousarray(b, dtype=np.float64)
    return a.shape == b.shape and bool(np.array_equal(a.view(np.uint64), b.view(np.uint64)))


def joint_samples(rng: np.random.Generator, n: int, table=FR3, past: float = 0.05) -> np.ndarray:
    """(n, 7) joint positions over the ranges and ``past`` of the span beyond either stop
    (negative: that far inside)."""
    span = table.q_upper - table.q_lower
    return table.q_lower - past * span + rng.random((n, 7)) * (1.0 + 2.0 * past) * span


def rollout(interface: str, action_filter: str, steps: int = 25):
    env = gym.make("FrankaFCI-v0", action_interface=interface, action_filter=action_filter)
    obs, _ = env.reset(seed=5)
    rng = np.random.default_rng(5)
    out = [obs["observation"].copy()]
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(
            rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
        )
        out.append(obs["observation"].copy())
        out.append(np.array([reward, info["cycles"], len(info["errors"])], dtype=np.float64))
        if terminated or truncated:
            obs, _ = env.reset()
    env.close()
    return out


def joint_and_client_kernels_off(monkeypatch) -> None:
    """Envs made after this run the client's filters on their numpy references (the
    controller's joint rules have one text, C: there is nothing of theirs to switch)."""
    monkeypatch.setattr(commands_module, "CLIENT_KERNEL", None)
