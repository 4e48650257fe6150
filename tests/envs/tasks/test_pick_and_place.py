"""PickAndPlace: goals in the air, a physical grasp, and the held block's load configured
(``configure_load``, default True) or left to read as an external force (False)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import franka_sim_gym  # noqa: F401  (registers the ids)
from franka_sim_gym.envs.tasks.pick_and_place import LIFT, PickAndPlace
from franka_sim_gym.envs.tasks.push import HALF

EE, WIDTH, BLOCK = slice(14, 17), 23, slice(24, 27)
MASS = 0.1  # scenes/block.xml
G = 9.81


def test_the_spaces_the_hand_and_the_goals():
    env = gym.make("FrankaFCIPickAndPlace-v0")
    assert env.action_space.shape == (4,)  # Cartesian velocity (3) and the width
    assert env.observation_space["observation"].shape == (23 + 1 + 13,)
    obs, _ = env.reset(seed=0)
    assert obs["observation"][WIDTH] == pytest.approx(0.08, abs=1e-3)  # open
    rng = np.random.default_rng(0)
    heights = np.array([PickAndPlace().sample_goal(rng)[2] for _ in range(400)])
    on_table = np.isclose(heights, HALF)
    assert 0.4 < on_table.mean() < 0.6  # half the goals on the table, half in the air
    assert heights.min() >= HALF and heights.max() <= HALF + LIFT


def grasp_and_lift(configure_load: bool, block_there: bool = True, steps_held: int = 8):
    """Put the block under the TCP, go down around it, close, lift 10 cm: a small
    controller on the public action interface. Returns the env and the last info."""
    env = gym.make("FrankaFCIPickAndPlace-v0", configure_load=configure_load)
    obs, _ = env.reset(seed=1)
    physics = env.unwrapped.controller.physics
    adr = physics.layout.scene_qpos_adr["block"][0]
    ee = obs["observation"][EE]
    physics.data.qpos[adr : adr + 2] = ee[:2] if block_there else (ee[0], ee[1] + 0.5)

    def go(target, width, steps):
        nonlocal obs
        info = None
        for _ in range(steps):
            error = np.asarray(target) - obs["observation"][EE]
            v = np.clip(8.0 * error / 0.3, -0.5, 0.5)
            obs, _, terminated, _, info = env.step(np.append(v, width).astype(np.float32))
            assert not terminated, info["reflex_reason"]
        return info

    go((*ee[:2], HALF), 1.0, 40)  # down around the block, open
    go((*ee[:2], HALF), -1.0, 15)  # close: the fingers stop on the block and squeeze
    info = go((*ee[:2], HALF + 0.1), -1.0, 30)  # lift
    info = go((*ee[:2], HALF + 0.1), -1.0, steps_held)  # hold still
    return env, obs, info


def test_the_grasp_holds_the_block_and_its_load_is_configured():
    env, obs, _ = grasp_and_lift(configure_load=True)
    assert obs["observation"][WIDTH] == pytest.approx(2 * HALF, abs=1.5e-3)  # on the block
    np.testing.assert_allclose(obs["observation"][BLOCK], obs["observation"][EE], atol=5e-3)
    assert obs["achieved_goal"][2] > HALF + 0.09  # lifted with the hand
    state = env.unwrapped.controller.states[0]
    assert state["m_load"] == pytest.approx(MASS, rel=1e-6)
    # the centre of mass: at the TCP, 0.1034 m down the flange's z axis (docs/env.md)
    np.testing.assert_allclose(state["F_x_Cload"], [0.0, 0.0, 0.1034], atol=5e-3)
    # the robot expects the weight: the estimate reads no external force
    assert abs(state["O_F_ext_hat_K"][2]) < 0.25


def test_without_configure_load_the_weight_reads_as_an_external_force():
    env, _, _ = grasp_and_lift(configure_load=False)
    state = env.unwrapped.controller.states[0]
    assert state["m_load"] == 0.0
    # the robot's sign (docs/robot-state.md): the force it exerts, up, holding the weight
    assert state["O_F_ext_hat_K"][2] == pytest.approx(MASS * G, abs=0.25)


def test_the_held_weight_reaches_the_measured_torques():
    # The same motion with and without the block: the difference in tau_J is the block's
    # weight carried by the joints (configured or not, MuJoCo carries it).
    held, _, _ = grasp_and_lift(configure_load=True)
    empty, _, _ = grasp_and_lift(configure_load=True, block_there=False)
    assert empty.unwrapped.controller.states[0]["m_load"] == 0.0  # nothing held
    tau = [env.unwrapped.controller.states[0]["tau_J"].astype(float) for env in (held, empty)]
    physics = held.unwrapped.controller.physics
    tcp = physics.data.site_xpos[physics.layout.tcp_site[0]] - physics.base_pos[0]
    J = physics.jacobian(tcp[None])[0]
    expected = J[:3].T @ np.array([0.0, 0.0, MASS * G])
    np.testing.assert_allclose(tau[0] - tau[1], expected, atol=0.15)
    assert np.abs(expected).max() > 0.3


def test_letting_go_configures_no_load_again():
    env, obs, _ = grasp_and_lift(configure_load=True)
    for _ in range(10):  # open, stand still: the block falls
        obs, _, terminated, _, _ = env.step(np.array([0, 0, 0, 1.0], np.float32))
        assert not terminated
    assert obs["achieved_goal"][2] == pytest.approx(HALF, abs=2e-3)
    assert env.unwrapped.controller.states[0]["m_load"] == 0.0
