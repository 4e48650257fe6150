"""The physics Franka Hand (sim.physics_hand + sim.finger_drive) in a real MuJoCo world.

The arm holds home while the tick hook (FingerDrive.tick) runs after every 1 ms
step, and the hand is polled every 4 ticks as the gripper server's 250 Hz
timer polls it. Behaviours: docs/fci-behaviour.md "Gripper fidelity",
with its listed divergences closed (force is a limit, stop halts in place,
is_grasped appears as the fingers close).

Everything runs in simulated time, in-process (the server's tick thread and
250 Hz gripper timer are wall-clock paced; ``Rig`` steps both here), so the 4 s
settle timeout is reached in well under a second of wall time. Disturbances
are real forces in the real MjData (``Rig.push``), not mocks.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable

import mujoco
import numpy as np
import pytest

from franka_sim_gym.fci import frames
from franka_sim_gym.fci.controller import FciController
from franka_sim_gym.fci.wire.protocol import SetterStatus
from franka_sim_gym.sim.arm import ArmPhysics
from franka_sim_gym.sim.finger_drive import FingerDrive
from franka_sim_gym.sim.gripper import Outcome
from franka_sim_gym.sim.hand_load import hand_load
from franka_sim_gym.sim.kinematics import ArmKinematics
from franka_sim_gym.sim.physics_hand import (
    MOVE_TOLERANCE,
    SETTLE_POLLS,
    SETTLE_TIMEOUT,
    PhysicsHand,
)
from franka_sim_gym.sim.world import HOME_Q, build_world
from tests.fci_helpers import DESK_HAND_F_T_NE

POLL_TICKS = 4  # the gripper server's 250 Hz timer against the 1 kHz tick


class Rig:
    """One arm with the hand mounted, stepped tick by tick like the robot server.

    ``push``, if set, is an external generalized force [N] on finger_joint1
    (positive opens) as a function of simulated time, written into the real
    MjData's ``qfrc_applied`` before every step: a disturbance, not a mock.
    """

    def __init__(self, object_width: float | None = None) -> None:
        self.physics = ArmPhysics(n_arms=1, hand=True, object_width=object_width)
        self.drive = FingerDrive(self.physics)
        self.hand = PhysicsHand(self.drive, object_width=object_width)
        self.ticks = 0
        self.is_grasped_while_busy = False
        self.push: Callable[[float], float] | None = None
        self._finger_dof = int(self.physics.layout.finger_dof_adr[0][0])

    @property
    def time(self) -> float:
        """Simulated time [s]."""
        return self.physics.time

    def tick(self, n: int = 1) -> None:
        for _ in range(n):
            if self.push is not None:
                data = self.physics.data
                data.qfrc_applied[self._finger_dof] = self.push(float(data.time))
            self.physics.step(HOME_Q[None, :], None)
            self.drive.tick()
            self.ticks += 1
            if self.ticks % POLL_TICKS == 0:
                self.hand.step(POLL_TICKS * 1e-3)
                self.is_grasped_while_busy |= self.hand.busy and self.hand.is_grasped

    def run(self, seconds: float = 10.0) -> float:
        """Tick until the running action finishes; the simulated seconds it took."""
        start = self.ticks
        while self.hand.busy and self.ticks - start < seconds * 1000:
            self.tick()
        return (self.ticks - start) / 1000

    def object_force(self) -> float:
        """Total normal force [N] the fingertips press on the virtual object with."""
        model, data = self.physics.model, self.physics.data
        total, force = 0.0, np.zeros(6)
        for i in range(data.ncon):
            names = model.geom(data.contact[i].geom1).name + model.geom(data.contact[i].geom2).name
            if "object" in names:
                mujoco.mj_contactForce(model, data, i, force)
                total += force[0]
        return total


def test_move_reaches_its_target_at_the_commanded_speed():
    rig = Rig()
    rig.hand.move(0.04, 0.02)
    seconds = rig.run()
    assert rig.hand.outcome is Outcome.SUCCESS
    # The servo settles within ~20 um (velocity under 1 mm/s); the success band is 1 mm.
    assert rig.hand.width == pytest.approx(0.04, abs=1e-4)
    # 4 cm at 2 cm/s in simulated time, plus the settling polls.
    assert seconds == pytest.approx(2.0, abs=0.1)


def test_a_motion_does_not_settle_before_the_fingers_start_moving():
    rig = Rig()
    rig.hand.move(0.0, 0.01)
    rig.tick(POLL_TICKS * (SETTLE_POLLS + 2))  # the fingers were at rest when it began
    assert rig.hand.busy
    assert rig.hand.width < 0.08 - 1e-4


def test_settling_takes_three_consecutive_quiet_polls():
    rig = Rig()
    rig.hand.move(0.08, 0.05)  # already there: every poll is quiet
    rig.tick(POLL_TICKS * (SETTLE_POLLS - 1))
    assert rig.hand.busy
    rig.tick(POLL_TICKS)
    assert rig.hand.outcome is Outcome.SUCCESS


#: A disturbance the fingers cannot settle under: a 10 Hz sine of 0.3 N on
#: finger_joint1 swings the width by up to +-0.5 mm (measured; inside
#: MOVE_TOLERANCE), so the width's velocity swings by ~3 cm/s and passes
#: through the SETTLE_SPEED band in about a millisecond, even on top of the
#: 2 cm/s ramp: never for the three consecutive 4 ms polls a settle needs.
#: (0.2 N was too weak on the ramp: it let a pushed move settle by chance.)
SHAKE_HZ = 10.0
SHAKE_FORCE = 0.3
#: The disturbance runs this long [ticks] before the command, so the action
#: meets it in steady state (switched on with the command, the push jolts the
#: fingers while the ramp starts).
PRE_ROLL_TICKS = 500
#: A steady inward push [N] under the shake: the servo (kp 1000 N/m per
#: finger, models/hand.xml) yields 1.5 mm per finger, a width 3 mm short of
#: the target, farther than MOVE_TOLERANCE.
PUSH_INWARD = -1.5
TARGET, SPEED = 0.04, 0.02  # a 2 s ramp from the open hand


def shaking(offset: float = 0.0) -> Callable[[float], float]:
    """The external force on finger_joint1 at simulated time t: ``offset`` plus the shake."""
    return lambda t: offset + SHAKE_FORCE * math.sin(2.0 * math.pi * SHAKE_HZ * t)


def timeout_records(caplog: pytest.LogCaptureFixture) -> list[logging.LogRecord]:
    return [r for r in caplog.records if "gripper-settle-timeout" in r.getMessage()]


def test_undisturbed_move_settles_long_before_the_timeout(caplog):
    """The control case of the timeout test below: same move, no disturbance."""
    caplog.set_level(logging.WARNING, logger="franka_sim_gym.gripper")
    rig = Rig()
    ramp = abs(TARGET - rig.hand.width) / SPEED
    rig.hand.move(TARGET, SPEED)
    seconds = rig.run()
    assert rig.hand.outcome is Outcome.SUCCESS
    assert seconds < ramp + 0.1  # (the timeout is 4 s after the ramp)
    assert timeout_records(caplog) == []


@pytest.mark.parametrize(
    ("offset", "outcome"),
    [(0.0, Outcome.SUCCESS), (PUSH_INWARD, Outcome.UNSUCCESSFUL)],
    ids=["within-tolerance", "short-of-target"],
)
def test_fingers_that_never_settle_are_answered_at_the_timeout(caplog, offset, outcome):
    """docs/fci-behaviour.md "Command coverage": 4 s timeout, here from the ramp's nominal end; the
    action is then judged like a settled one (physics_hand.py)."""
    caplog.set_level(logging.WARNING, logger="franka_sim_gym.gripper")
    rig = Rig()
    rig.push = shaking(offset)
    rig.tick(PRE_ROLL_TICKS)
    start = rig.time
    ramp = abs(TARGET - rig.hand.width) / SPEED
    action = rig.hand.move(TARGET, SPEED)
    timeout_at = start + ramp + SETTLE_TIMEOUT

    # Up to the last tick before ramp end + 4 s: not answered, nothing logged.
    rig.tick(round((timeout_at - start) * 1000) - 1)
    assert rig.hand.busy and rig.hand.take_finished() == []
    assert timeout_records(caplog) == []

    rig.run(seconds=0.1)
    # Answered at the timeout: the first poll at or after it (the deadline counts
    # from the action's first fresh sample, at most one poll after the command).
    assert not rig.hand.busy
    assert timeout_at <= rig.time <= timeout_at + 2 * POLL_TICKS * 1e-3 + 1e-9
    assert rig.hand.take_finished() == [(action, outcome)]
    assert len(timeout_records(caplog)) == 1
    off_target = abs(rig.hand.width - TARGET)
    if outcome is Outcome.SUCCESS:
        assert off_target <= MOVE_TOLERANCE
    else:
        assert off_target > MOVE_TOLERANCE


def test_grasp_of_thin_air_stalls_at_zero_and_fails():
    rig = Rig()
    rig.hand.grasp(0.04, 0.05, 20.0)
    rig.run()
    assert rig.hand.outcome is Outcome.UNSUCCESSFUL
    assert rig.hand.is_grasped is False
    assert rig.hand.width == pytest.approx(0.0, abs=1e-4)


@pytest.mark.parametrize("force", [20.0, 140.0])
def test_grasp_of_zero_on_nothing_succeeds_even_at_high_force(force):
    # The finger end stops are stiff: the squeeze does not push the fingers out of
    # the (-5 mm, 5 mm) band.
    rig = Rig()
    rig.hand.grasp(0.0, 0.1, force)
    rig.run()
    assert rig.hand.outcome is Outcome.SUCCESS and rig.hand.is_grasped
    assert abs(rig.hand.width) < 1e-4


@pytest.mark.parametrize("force", [10.0, 60.0])
def test_grasp_force_is_the_limit_of_the_finger_force(force):
    rig = Rig(object_width=0.04)
    rig.hand.grasp(0.04, 0.05, force)
    rig.run()
    assert rig.hand.outcome is Outcome.SUCCESS and rig.hand.is_grasped
    assert rig.hand.width == pytest.approx(0.04, abs=2e-4)
    rig.tick(200)  # the object held for 0.2 s
    assert rig.object_force() == pytest.approx(force, rel=1e-3)
    assert rig.physics.data.actuator_force[rig.drive._act] == pytest.approx(-force)


def test_is_grasped_appears_before_the_grasp_is_answered():
    rig = Rig(object_width=0.03)
    rig.hand.grasp(0.03, 0.05, 20.0)
    rig.run()
    assert rig.hand.outcome is Outcome.SUCCESS
    assert rig.is_grasped_while_busy


def test_grasp_expecting_another_width_fails_on_the_object():
    rig = Rig(object_width=0.03)
    rig.hand.grasp(0.05, 0.05, 20.0)
    rig.run()
    assert rig.hand.outcome is Outcome.UNSUCCESSFUL and not rig.hand.is_grasped
    assert rig.hand.width == pytest.approx(0.03, abs=2e-4)


def test_inward_move_is_blocked_by_the_object_and_opening_is_not():
    rig = Rig(object_width=0.03)
    rig.hand.move(0.01, 0.05)
    rig.run()
    assert rig.hand.outcome is Outcome.UNSUCCESSFUL
    assert rig.hand.width == pytest.approx(0.03, abs=2e-4)
    rig.hand.move(0.07, 0.05)
    rig.run()
    assert rig.hand.outcome is Outcome.SUCCESS
    assert rig.hand.width == pytest.approx(0.07, abs=MOVE_TOLERANCE)


def test_stop_halts_the_fingers_where_they_are():
    rig = Rig()
    rig.hand.move(0.0, 0.05)
    rig.tick(300)  # 1.5 cm closed
    rig.hand.stop()
    at_stop = rig.hand.width
    assert rig.hand.take_finished()[-1][1] is Outcome.ABORTED
    rig.tick(1000)
    # Braking from 5 cm/s on a ~130 rad/s servo: well under a millimetre.
    assert rig.hand.width == pytest.approx(at_stop, abs=5e-4)
    assert rig.hand.width == pytest.approx(0.08 - 0.015, abs=2e-3)


def test_the_object_collides_with_the_fingertips_only_and_adds_no_mass():
    bare, _ = build_world(hand=True)
    model, _ = build_world(hand=True, object_width=0.04)
    assert model.ngeom == bare.ngeom + 1 and model.npair == 2
    np.testing.assert_allclose(model.body_mass, bare.body_mass)
    with pytest.raises(ValueError):
        build_world(hand=True, object_width=0.09)
    with pytest.raises(ValueError):
        build_world(object_width=0.04)  # no hand to hold it


def test_hand_load_is_the_hand_the_arm_carries():
    """m_ee / F_x_Cee reproduce the extra gravity torque the mounted hand puts on the arm."""
    model, layout = build_world(hand=True)
    bare_model, _ = build_world()
    load = hand_load(model, layout)
    assert load.m_ee == pytest.approx(0.6544 + 2 * 0.0291)  # models/hand.xml inertials
    np.testing.assert_allclose(load.I_ee, load.I_ee.T)
    assert np.all(np.linalg.eigvalsh(load.I_ee) > 0)

    def gravity_torque(m: mujoco.MjModel) -> np.ndarray:
        data = mujoco.MjData(m)
        mujoco.mj_resetDataKeyframe(m, data, m.key("home").id)
        mujoco.mj_forward(m, data)
        return data.qfrc_gravcomp[layout.dof_adr[0]].copy(), data

    with_hand, data = gravity_torque(model)
    without, _ = gravity_torque(bare_model)
    # The point load m_ee at F_x_Cee on the flange, through the flange's Jacobian.
    site = int(layout.flange_site[0])
    com = data.site_xpos[site] + data.site_xmat[site].reshape(3, 3) @ load.F_x_Cee
    jacp = np.zeros((3, model.nv))
    mujoco.mj_jac(model, data, jacp, None, com, model.site_bodyid[site])
    expected = jacp[:, layout.dof_adr[0]].T @ np.array([0.0, 0.0, load.m_ee * 9.81])
    np.testing.assert_allclose(with_hand - without, expected, atol=1e-6)
    assert (with_hand - without)[3] == pytest.approx(3.3, abs=0.1)  # docs/gripper.md


# -- the hand as Desk's end effector: F_T_NE at its TCP -------------------------------------

#: An arm pose off home, so no flange axis lines up with a base axis.
POSE_Q = np.array([0.3, -0.5, 0.2, -2.2, 0.4, 1.9, 0.1])


def hand_controller(q: np.ndarray = POSE_Q) -> FciController:
    ctrl = FciController(ArmPhysics(n_arms=1, hand=True))
    ctrl.reset([0], q[None, :])
    return ctrl


def site_pose(physics: ArmPhysics, site: int) -> np.ndarray:
    """Row-major 4x4 pose of a MuJoCo site in arm 0's base frame."""
    T = np.eye(4)
    T[:3, :3] = physics.data.site_xmat[site].reshape(3, 3)
    T[:3, 3] = physics.data.site_xpos[site] - physics.base_pos[0]
    return T


def test_the_hand_tcp_is_desks_franka_hand_frame():
    model, layout = build_world(hand=True)
    F_T_NE = hand_load(model, layout).F_T_NE
    np.testing.assert_allclose(frames.to_wire(F_T_NE), DESK_HAND_F_T_NE, atol=1e-4)
    assert frames.is_homogeneous_transformation(frames.to_wire(F_T_NE), tol=1e-12)


def test_the_state_reports_the_hand_tcp_as_nominal_end_effector():
    ctrl = hand_controller()
    s = ctrl.states[0]
    np.testing.assert_allclose(s["F_T_NE"], DESK_HAND_F_T_NE, atol=1e-4)
    np.testing.assert_array_equal(s["F_T_EE"], s["F_T_NE"])  # NE_T_EE is identity
    np.testing.assert_array_equal(s["NE_T_EE"], frames.IDENTITY16)
    assert s["m_ee"] == pytest.approx(0.7126, abs=1e-4)  # the same Desk configuration


def test_o_t_ee_is_the_flange_fk_composed_with_the_hand_tcp():
    ctrl = hand_controller()
    F_T_NE = frames.from_wire(ctrl.states[0]["F_T_NE"].astype(float))
    flange = ArmKinematics(ctrl.physics.model, ctrl.physics.layout).forward(POSE_Q[None, :])[0]
    O_T_EE = frames.from_wire(ctrl.states[0]["O_T_EE"].astype(float))
    np.testing.assert_allclose(O_T_EE, flange @ F_T_NE, atol=1e-6)  # float32 wire
    # ... which is the MuJoCo hand's own TCP site, between the fingertips.
    tcp = site_pose(ctrl.physics, int(ctrl.physics.layout.tcp_site[0]))
    np.testing.assert_allclose(O_T_EE, tcp, atol=1e-6)
    assert np.linalg.norm(O_T_EE[:3, 3] - flange[:3, 3]) == pytest.approx(0.1034, abs=1e-6)


def test_home_o_t_ee_with_the_hand_is_the_tcp_pointing_down():
    """A real FR3 with the Franka Hand configured reports this EE pose at home."""
    ctrl = hand_controller(HOME_Q)
    O_T_EE = frames.from_wire(ctrl.states[0]["O_T_EE"].astype(float))
    np.testing.assert_allclose(O_T_EE[:3, 3], [0.306891, 0.0, 0.590282 - 0.1034], atol=1e-5)
    np.testing.assert_allclose(O_T_EE[:3, :3], np.diag([1.0, -1.0, -1.0]), atol=1e-6)


def test_the_ee_jacobian_is_the_tcp_jacobian():
    """Cartesian IK and the EE speed act at F_T_EE: with the hand, at the TCP site."""
    ctrl = hand_controller()
    physics = ctrl.physics
    J = ArmKinematics(physics.model, physics.layout).jacobian(POSE_Q[None, :], ctrl.writer.F_T_EE)[
        0
    ]
    jacp, jacr = np.zeros((3, physics.model.nv)), np.zeros((3, physics.model.nv))
    mujoco.mj_jacSite(physics.model, physics.data, jacp, jacr, int(physics.layout.tcp_site[0]))
    dofs = physics.layout.dof_adr[0]
    np.testing.assert_allclose(J[:3], jacp[:, dofs], atol=1e-9)
    np.testing.assert_allclose(J[3:], jacr[:, dofs], atol=1e-9)


def test_set_ne_to_ee_is_relative_to_the_tcp_and_a_disconnect_resets_it_to_the_tcp():
    ctrl = hand_controller()
    hand = frames.from_wire(ctrl.states[0]["F_T_NE"].astype(float))
    np.testing.assert_allclose(frames.to_wire(hand), DESK_HAND_F_T_NE, atol=1e-4)
    tcp_pose = frames.from_wire(ctrl.states[0]["O_T_EE"].astype(float))
    NE_T_EE = np.eye(4)
    NE_T_EE[2, 3] = 0.05  # 5 cm beyond the TCP, along its z axis
    assert ctrl.set_ne_to_ee(0, frames.to_wire(NE_T_EE)) == SetterStatus.kSuccess
    ctrl.step()
    s = ctrl.states[0]
    np.testing.assert_allclose(s["F_T_EE"], frames.to_wire(hand @ NE_T_EE), atol=1e-7)
    np.testing.assert_allclose(s["F_T_NE"], frames.to_wire(hand), atol=1e-7)
    O_T_EE = frames.from_wire(s["O_T_EE"].astype(float))
    np.testing.assert_allclose(O_T_EE[:3, 3], tcp_pose[:3, 3] + 0.05 * tcp_pose[:3, 2], atol=1e-5)

    ctrl.end_session(0)
    ctrl.step()
    s = ctrl.states[0]
    np.testing.assert_array_equal(s["NE_T_EE"], frames.IDENTITY16)
    np.testing.assert_allclose(s["F_T_NE"], DESK_HAND_F_T_NE, atol=1e-4)  # Desk's stays
    np.testing.assert_array_equal(s["F_T_EE"], s["F_T_NE"])
    np.testing.assert_allclose(frames.from_wire(s["O_T_EE"].astype(float)), tcp_pose, atol=1e-5)


def test_a_bare_flange_keeps_identity_frames():
    ctrl = FciController(ArmPhysics(n_arms=1))
    s = ctrl.states[0]
    for name in ("F_T_NE", "F_T_EE", "NE_T_EE"):
        np.testing.assert_array_equal(s[name], frames.IDENTITY16)
