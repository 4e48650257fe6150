"""The internal Cartesian impedance servo (sim/cartesian_servo.py through ArmPhysics.step)."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.sim.arm import ArmPhysics
from franka_sim_gym.sim.cartesian_servo import CartesianTarget, in_axes, orientation_error
from franka_sim_gym.sim.hand_load import hand_load
from tests.sim.test_scene import OVER_THE_TABLE, table_contacts

#: SetCartesianImpedance's values in libfranka's examples (examples_common.cpp).
STIFFNESS = np.array([3000.0, 3000.0, 3000.0, 300.0, 300.0, 300.0])


def rz(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def ry(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


class Servo:
    """One arm with the hand, K at the hand's TCP times ``k_rotation``, over the table."""

    def __init__(self, k_rotation: np.ndarray | None = None) -> None:
        self.physics = ArmPhysics(1, hand=True)
        self.flange_to_k = hand_load(self.physics.model, self.physics.layout).F_T_NE.copy()
        if k_rotation is not None:
            self.flange_to_k[:3, :3] = self.flange_to_k[:3, :3] @ k_rotation
        self.physics.reset_arms([0], OVER_THE_TABLE[None])
        self.q_ref = OVER_THE_TABLE[None].copy()

    def k_pose(self) -> tuple[np.ndarray, np.ndarray]:
        p, R = self.physics.flange_pose()
        k = self.flange_to_k
        return p[0] + R[0] @ k[:3, 3], R[0] @ k[:3, :3]

    def hold(self, position, rotation, stiffness, cycles: int) -> list[np.ndarray]:
        target = CartesianTarget(
            np.array([True]), position[None], rotation[None], self.flange_to_k[None],
            np.asarray(stiffness, float)[None],
        )  # fmt: skip
        trace = []
        for _ in range(cycles):
            self.physics.step(self.q_ref, None, cartesian=target)
            trace.append(self.k_pose()[0])
        return trace


def test_k_held_on_its_own_pose_does_not_move():
    servo = Servo()
    p, R = servo.k_pose()
    trace = servo.hold(p, R, STIFFNESS, 1000)
    assert np.abs(np.array(trace) - p).max() < 1e-6
    assert np.abs(servo.physics.dq).max() < 1e-4


def test_a_step_is_critically_damped():
    servo = Servo()
    p, R = servo.k_pose()
    goal = p + [0.0, 0.0, 0.02]
    z = np.array(servo.hold(goal, R, STIFFNESS, 1500))[:, 2]
    assert abs(z[-1] - goal[2]) < 1e-4
    assert z.max() - goal[2] < 0.02 * 0.02  # under 2 % overshoot
    # ... and not overdamped to a crawl: most of the way within 0.2 s
    assert z[200] - p[2] > 0.9 * 0.02


def test_a_rotation_step_settles_on_the_commanded_orientation():
    servo = Servo()
    p, R = servo.k_pose()
    goal = R @ rz(0.1)  # 0.1 rad about K's z
    servo.hold(p, goal, STIFFNESS, 1500)
    _, R_now = servo.k_pose()
    assert np.linalg.norm(orientation_error(R_now[None], goal[None])) < 1e-3


@pytest.mark.parametrize("stiffness", [500.0, 1500.0])
def test_pressed_into_the_table_the_force_is_stiffness_times_the_depth(stiffness):
    servo = Servo()
    p, R = servo.k_pose()
    goal = p.copy()
    goal[2] = -0.02  # 2 cm under the table's surface
    trace = servo.hold(goal, R, [stiffness] * 3 + [300.0] * 3, 3000)
    force, _, _ = table_contacts(servo.physics)
    depth = trace[-1][2] - goal[2]  # how far the spring is stretched at rest
    assert depth > 0.02
    assert force == pytest.approx(stiffness * depth, rel=0.05)


def test_the_stiffness_acts_along_the_k_frames_axes():
    """K's x axis turned onto the base's vertical: its x stiffness is what presses."""
    soft, stiff = 300.0, 3000.0
    servo = Servo(k_rotation=ry(np.pi / 2))
    p, R = servo.k_pose()
    assert abs(abs(R[2, 0]) - 1.0) < 1e-9  # K's x axis is vertical
    goal = p.copy()
    goal[2] = -0.02
    trace = servo.hold(goal, R, [soft, stiff, stiff, 300.0, 300.0, 300.0], 3000)
    force, _, _ = table_contacts(servo.physics)
    assert force == pytest.approx(soft * (trace[-1][2] - goal[2]), rel=0.05)


def test_a_diagonal_gain_in_a_turned_frame():
    R = rz(np.pi / 2)[None]
    np.testing.assert_allclose(in_axes(R, np.array([[1.0, 10.0, 100.0]]), np.array([[1.0, 0, 0]])),
                               [[10.0, 0.0, 0.0]], atol=1e-12)  # fmt: skip


def test_the_nullspace_moves_the_elbow_toward_the_reference_and_not_k():
    servo = Servo()
    p, R = servo.k_pose()
    q0 = servo.physics.q[0].copy()
    servo.q_ref = (q0 + [0.0, 0.0, 0.3, 0.0, 0.0, 0.0, 0.0])[None]  # the elbow, joint 3
    trace = servo.hold(p, R, STIFFNESS, 2000)
    assert np.abs(np.array(trace) - p).max() < 5e-4  # K stays where it is held
    assert servo.physics.q[0, 2] - q0[2] > 0.05  # ... while the arm turns its elbow
