"""The env on the table: contact in info, collision reflexes end the episode."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import franka_sim_gym  # noqa: F401  (registers the ids)

#: Forward and down onto the table in front of the arm (3 dof: translation only).
DOWN = np.array([0.12, 0.0, -0.2], dtype=np.float32)


def descend(env, steps: int = 200):
    """Push the EE down until the episode ends; the last info and whether it terminated."""
    info, terminated = {}, False
    for _ in range(steps):
        _, _, terminated, truncated, info = env.step(DOWN)
        if terminated or truncated:
            break
    return info, terminated


def make(**kwargs):
    return gym.make(
        "FrankaFCICartesianVelocity-v0", cartesian_dof=3, policy_hz=10, max_episode_steps=200,
        **kwargs,
    )  # fmt: skip


def test_pushing_into_the_table_ends_in_a_collision_reflex_named_in_info():
    env = make(collision_thresholds=(100.0, 100.0, 10.0, 20.0))
    env.reset(seed=0)
    info, terminated = descend(env)
    assert terminated
    assert "cartesian_reflex" in info["reflex_reason"] or "joint_reflex" in info["reflex_reason"]
    assert info["robot_mode"] == "kReflex"
    assert info["O_F_ext_hat_K"].shape == (6,) and info["O_F_ext_hat_K"][2] < -10.0
    assert info["cartesian_contact"][2]  # the z axis is past its lower threshold
    # The next episode starts clean: the thresholds are set again, nothing sensed.
    _, info = env.reset(seed=1)
    assert info["reflex_reason"] == () and not info["cartesian_contact"].any()
    assert np.abs(info["O_F_ext_hat_K"]).max() < 0.5


def test_free_space_episodes_sense_nothing_under_the_default_thresholds():
    env = gym.make("FrankaFCI-v0")
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(100):
        _, _, terminated, truncated, info = env.step(rng.uniform(-1, 1, 7).astype(np.float32))
        assert "joint_reflex" not in info["reflex_reason"]
        assert "cartesian_reflex" not in info["reflex_reason"]
        # ... and the estimate stays under the default lower thresholds (20 N): no contact
        assert not info["cartesian_contact"].any() and not info["joint_contact"].any()
        if terminated or truncated:
            env.reset()


def test_a_scene_gives_every_arm_its_own_objects():
    envs = gym.make_vec("FrankaFCI-v0", num_envs=3, vectorization_mode="vector_entry_point",
                        scene="block")  # fmt: skip
    physics = envs.unwrapped.core.controller.physics
    adr = int(physics.layout.scene_qpos_adr["block"][0])
    envs.reset(seed=0)
    physics.datas[1].qpos[adr] += 0.1  # arm 1's block, in arm 1's own world (MjData)
    blocks = [d.qpos[adr : adr + 3].copy() for d in physics.datas]
    assert blocks[1][0] != blocks[0][0] and np.array_equal(blocks[0], blocks[2])


@pytest.mark.parametrize(
    ("thresholds", "message"),
    [
        ((10.0, 20.0, 5.0), "must be \\(lower_torque, upper_torque, lower_force, upper_force\\)"),
        ((10.0, 20.0, [5.0] * 5, 20.0), "7, 7, 6 and 6 values"),
        ((10.0, -20.0, 5.0, 20.0), "upper_torque_thresholds_acceleration: negative"),
        ((10.0, 20.0, np.nan, 20.0), "lower_force_thresholds_acceleration: non-finite"),
    ],
)
def test_bad_collision_thresholds_are_a_value_error_naming_them(thresholds, message):
    with pytest.raises(ValueError, match=message):
        make(collision_thresholds=thresholds)


def test_under_cartesian_impedance_a_soft_spring_presses_the_table_gently():
    """Down to the table, then on slowly under a 200 N/m Cartesian spring: the force
    builds with the commanded depth at 200 N/m, and the episode runs on without the
    reflex the joint servo's stiffness would trip (a 20 N upper threshold)."""
    env = make(
        controller_mode="cartesian_impedance",
        cartesian_impedance=[200.0, 200.0, 200.0, 30.0, 30.0, 30.0],
        collision_thresholds=(100.0, 100.0, 2.0, 20.0),
    )
    obs, _ = env.reset(seed=0)
    assert int(env.unwrapped.core.controller.modes.controller_mode[0]) == 1  # kCartesian...
    slow = np.array([0.0, 0.0, -0.02], dtype=np.float32)
    info = {}
    for _ in range(150):
        near = obs["achieved_goal"][2] < 0.04  # the flange, 4 cm above the table
        obs, _, terminated, _, info = env.step(slow if near else DOWN)
        assert not terminated, info["reflex_reason"]
    assert obs["achieved_goal"][2] < 0.01
    assert info["cartesian_contact"][2]  # it is pressing (above the 2 N lower threshold)
    assert -20.0 < info["O_F_ext_hat_K"][2] < -2.0


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"controller_mode": "impedance"}, "unknown controller_mode 'impedance'"),
        ({"joint_impedance": 20000.0}, "joint_impedance: K_theta .* outside 0..14250"),
        ({"joint_impedance": [1.0] * 6}, "joint_impedance .* 7 values or one"),
        ({"cartesian_impedance": [5.0, 100, 100, 10, 10, 10]}, "cartesian_impedance: K_x"),
    ],
)
def test_bad_servo_settings_are_a_value_error_naming_them(kwargs, message):
    with pytest.raises(ValueError, match=message):
        make(**kwargs)


def test_the_torque_interface_takes_no_controller_mode():
    with pytest.raises(ValueError, match="torque interface is its own controller"):
        gym.make("FrankaFCITorque-v0", controller_mode="cartesian_impedance")


def test_a_reset_puts_the_scene_objects_back_where_the_scene_placed_them():
    env = gym.make("FrankaFCI-v0", scene="block")
    env.reset(seed=0)
    physics = env.unwrapped.core.controller.physics
    adr = physics.layout.scene_qpos_adr["block"][0]
    start = physics.data.qpos[adr : adr + 7].copy()
    physics.data.qpos[adr : adr + 2] += (0.1, 0.2)  # knocked away during an episode
    physics.data.qvel[physics.layout.scene_dof_adr["block"][0]] = 1.0
    env.reset(seed=0)
    np.testing.assert_array_equal(physics.data.qpos[adr : adr + 7], start)
    dof = physics.layout.scene_dof_adr["block"][0]
    assert not physics.data.qvel[dof : dof + 6].any()
