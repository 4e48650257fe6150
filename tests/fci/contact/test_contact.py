"""The external-torque estimate and the wrench at K (fci/contact/estimate.py), held to MuJoCo.

MuJoCo's contact forces are the ground truth: the estimator never reads them, it runs
on q, dq, tau_J and the arm's model terms (sim/dynamics.py), as the robot runs on its
sensors and its model.
"""

from __future__ import annotations

import mujoco
import numpy as np

from franka_sim_gym.fci.config import ControllerConfig
from franka_sim_gym.fci.contact.estimate import in_frame, wrench_from_torque
from franka_sim_gym.fci.controller import FciController
from franka_sim_gym.sim.arm import ArmPhysics
from franka_sim_gym.sim.dynamics import ArmDynamics
from franka_sim_gym.sim.scene import TABLE
from tests.sim.test_scene import OVER_THE_TABLE


class Sensed:
    """The robot's contact sensing on ``physics`` stepped by hand: after each step the
    controller's own measured fields and sensing (fci/contact/sensing.py), as its cycle
    runs them, and the estimate it publishes."""

    def __init__(self, physics: ArmPhysics) -> None:
        self.physics = physics
        self.ctrl = FciController(physics, ControllerConfig())
        self.reset()

    def reset(self) -> None:
        """The estimate restarts from the arms' current state (a teleport)."""
        self.ctrl.contact.reset(np.arange(self.physics.n))

    def step(self, q_ref: np.ndarray, dq_ref: np.ndarray | None) -> np.ndarray:
        """One physics step, then the cycle's sensing: tau_ext_hat_filtered (n, 7)."""
        self.physics.step(q_ref, dq_ref)
        ctrl = self.ctrl
        ctrl.writer.write_measured(self.physics)
        ctrl.contact.sense(ctrl.modes.in_motion, None)
        return ctrl.writer.field["tau_ext_hat_filtered"]


def flange_jacobian(physics: ArmPhysics, dyn: ArmDynamics) -> tuple[np.ndarray, np.ndarray]:
    """(n, 6, 7) Jacobian at the flange and (n, 3) its position, base frame."""
    point = physics.flange_pose()[0]  # every arm's flange, in its own world (MjData)
    return dyn.jacobian(point), point


def test_the_jacobian_at_a_point_is_mujocos():
    physics = ArmPhysics(2)
    physics.reset_arms([0, 1], np.array([[0.3, -0.5, 0.2, -2.0, 0.1, 1.8, 0.4], OVER_THE_TABLE]))
    J, _ = flange_jacobian(physics, ArmDynamics(physics))
    for i in range(2):
        jacp, jacr = np.zeros((3, physics.model.nv)), np.zeros((3, physics.model.nv))
        data = physics.datas[i]  # arm i's own world
        mujoco.mj_jacSite(physics.model, data, jacp, jacr, physics.layout.flange_site[i])
        dofs = physics.layout.dof_adr[i]
        np.testing.assert_allclose(J[i], np.vstack([jacp[:, dofs], jacr[:, dofs]]), atol=1e-12)


def test_a_wrench_at_the_point_is_recovered_from_its_joint_torques():
    physics = ArmPhysics(1)
    J, _ = flange_jacobian(physics, ArmDynamics(physics))
    F = np.array([[3.0, -20.0, -50.0, 1.0, 0.5, -2.0]])
    tau = np.einsum("nij,ni->nj", J, F)  # J^T F
    np.testing.assert_allclose(wrench_from_torque(J, tau), F, atol=1e-5)


def test_a_wrench_in_the_k_frame_is_rotated_not_moved():
    R = np.array([[[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]])  # Rz(90 deg)
    O_F = np.array([[1.0, 0.0, -5.0, 0.0, 2.0, 0.0]])
    np.testing.assert_allclose(in_frame(O_F, R), [[0.0, -1.0, -5.0, 2.0, 0.0, 0.0]], atol=1e-15)


def test_at_rest_in_free_space_the_estimate_is_zero():
    physics = ArmPhysics(1, hand=True)
    sensed = Sensed(physics)
    q = physics.q.copy()
    worst = 0.0
    for _ in range(1000):
        worst = max(worst, np.abs(sensed.step(q, None)).max())
    assert worst < 0.05


def contact_wrench_on_the_environment(physics: ArmPhysics, point: np.ndarray) -> np.ndarray:
    """(6,) MuJoCo's table contact forces on arm 0, as the wrench the arm exerts at
    ``point`` (base frame): the ground truth."""
    m, d = physics.model, physics.data
    table = m.geom(TABLE).id
    force, torque, local = np.zeros(3), np.zeros(3), np.zeros(6)
    for c in range(d.ncon):
        con = d.contact[c]
        if table not in (con.geom1, con.geom2) or con.efc_address < 0:
            continue
        mujoco.mj_contactForce(m, d, c, local)
        on_geom2 = con.frame.reshape(3, 3).T @ local[:3]  # geom1 pushes geom2
        on_arm = -on_geom2 if con.geom2 == table else on_geom2
        force -= on_arm
        torque -= np.cross(con.pos - physics.base_pos[0] - point, on_arm)
    return np.concatenate([force, torque])


def test_in_static_contact_the_estimate_is_the_contact_wrench_within_5_percent():
    physics = ArmPhysics(1, hand=True)
    sensed = Sensed(physics)
    physics.reset_arms([0], OVER_THE_TABLE[None])
    sensed.reset()
    target = OVER_THE_TABLE.copy()
    for k in range(3000):
        if k < 2100:
            target[1] += 0.0001  # down onto the table at 0.1 rad/s, then press
        tau = sensed.step(target[None], None)
    J, point = flange_jacobian(physics, ArmDynamics(physics))
    estimate = wrench_from_torque(J, tau)[0]
    truth = contact_wrench_on_the_environment(physics, point[0])
    assert truth[2] < -50.0  # pressing down: the arm pushes the table in -z
    np.testing.assert_allclose(estimate[:3], truth[:3], atol=0.05 * np.linalg.norm(truth[:3]))
    np.testing.assert_allclose(estimate[3:], truth[3:], atol=0.05 * np.linalg.norm(truth[3:]))


def test_in_free_space_motion_the_estimate_stays_near_zero():
    """A smooth joint motion up to 3.1 rad/s and ~10 rad/s^2: the model explains the
    torques (inertia, Coriolis, gravity, joint friction), so nothing external shows --
    to 0.01 Nm because the estimate pairs each step's torque with the model of the
    state that step started from (paired with the next state's, gravity alone moved it
    by up to 0.07 Nm here)."""
    physics = ArmPhysics(1, hand=True)
    sensed = Sensed(physics)
    home = physics.q[0].copy()
    amplitude = np.array([0.6, 0.4, 0.5, 0.5, 0.8, 0.5, 1.0])
    worst = fastest = 0.0
    for k in range(2000):
        phase = np.pi * k * 1e-3  # one 2 s period of 1 - cos
        q = home + amplitude * (1.0 - np.cos(phase))
        dq = amplitude * np.pi * np.sin(phase)
        tau = sensed.step(q[None], dq[None])
        worst = max(worst, np.abs(tau).max())
        fastest = max(fastest, np.abs(physics.dq).max())
    assert fastest > 3.0  # it did move fast
    assert worst < 0.01
