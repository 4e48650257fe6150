"""The external-force estimate along free-space motions, and what a reflex during a move
to pylibfranka's example pose is (fci/contact/estimate.py; docs/robot-state.md, the contact group).

The motion is the one pylibfranka's ``examples/cartesian_velocity_example.py`` runs (a
joint move, then 8 s of Cartesian velocity under ControllerMode::CartesianImpedance: a
cosine speed profile along x = z, out for 4 s, back for 4 s), driven in-process.
"""

from __future__ import annotations

import math

import numpy as np

from franka_sim_gym.fci.contact.collision import (
    DEFAULT_FORCE_THRESHOLDS,
    DEFAULT_TORQUE_THRESHOLDS,
    THRESHOLD_NAMES,
)
from franka_sim_gym.fci.errors import Error, error_names
from franka_sim_gym.fci.events import EventKind
from franka_sim_gym.fci.wire import MoveControllerMode, MoveMotionGeneratorMode
from franka_sim_gym.fci.wire.statuses import MoveStatus, SetterStatus
from tests.fci_helpers import LoopClient, make_controller
from tests.sim.test_scene import table_contacts

CARTESIAN_IMPEDANCE = MoveControllerMode.kCartesianImpedance
#: The pose every libfranka C++ example moves to first (examples/*.cpp, ``q_goal``), the
#: simulated robot's start pose.
READY = np.array([0.0, -math.pi / 4, 0.0, -3 * math.pi / 4, 0.0, math.pi / 2, math.pi / 4])
#: pylibfranka 0.21's cartesian_velocity_example.py's ``q_goal``: joint 2 at +pi/4 where
#: the C++ examples have -pi/4. The arm leans forward and the flange ends 2.6 cm above
#: the table plane, the wrist's housings below it.
PYLIBFRANKA_EXAMPLE_GOAL = READY * [1, -1, 1, 1, 1, 1, 1]
#: A free-space pose 0.3 to 0.7 rad from READY in every joint (the flange stays > 30 cm
#: above the table).
ELSEWHERE = np.array([0.5, -0.2, 0.4, -2.1, -0.3, 2.2, 1.2])


def thresholds(lower_torque, upper_torque, lower_force, upper_force) -> dict:
    """SetCollisionBehavior's eight arrays from its 4-argument form (both phases alike)."""
    t_lo, t_up, f_lo, f_up = (
        list(v) for v in (lower_torque, upper_torque, lower_force, upper_force)
    )
    return dict(zip(THRESHOLD_NAMES, (t_lo, t_up, t_lo, t_up, f_lo, f_up, f_lo, f_up), strict=True))


class Recorder:
    """Peak |estimate| and the contact flags of every state, and the table's force."""

    def __init__(self, ctrl) -> None:
        self.ctrl = ctrl
        self.tau = np.zeros(7)
        self.force = np.zeros(6)
        self.flags = 0.0
        self.table = 0.0

    def __call__(self, state) -> None:
        self.tau = np.maximum(self.tau, np.abs(state["tau_ext_hat_filtered"]))
        self.force = np.maximum(self.force, np.abs(state["O_F_ext_hat_K"]))
        self.flags += state["joint_contact"].sum() + state["cartesian_contact"].sum()
        self.table = max(self.table, table_contacts(self.ctrl.physics)[0])


def joint_move(client: LoopClient, goal, duration: float, record) -> int | None:
    """A cosine-blended joint-position move to ``goal`` in ``duration`` s (Cartesian
    impedance controller mode, as the example's); the Move's final status."""
    assert client.start(MoveMotionGeneratorMode.kJointPosition, CARTESIAN_IMPEDANCE) == 1
    q0 = np.array(client.state["q_d"], dtype=float)
    for k in range(1, int(duration * 1000) + 20):
        s = 0.5 * (1 - math.cos(math.pi * min(k * 1e-3 / duration, 1.0)))
        events = client.send(q_c=q0 + s * (np.asarray(goal) - q0), finished=k * 1e-3 >= duration)
        record(client.state)
        for event in events:
            if event.kind is EventKind.MOVE_FINISHED:
                return event.status
    return None


def example_cartesian_motion(client: LoopClient, record) -> int | None:
    """The example's 8 s Cartesian velocity motion; the Move's final status."""
    assert client.start(MoveMotionGeneratorMode.kCartesianVelocity, CARTESIAN_IMPEDANCE) == 1
    t_max, v_max = 4.0, 0.1
    for k in range(1, 8100):
        t = k * 1e-3
        v = (1 if t < t_max else -1) * v_max / 2 * (1 - math.cos(2 * math.pi / t_max * t))
        v_xz = math.cos(math.pi / 4) * v
        events = client.send(O_dP_EE_c=[v_xz, 0.0, v_xz, 0.0, 0.0, 0.0], finished=t >= 2 * t_max)
        record(client.state)
        for event in events:
            if event.kind is EventKind.MOVE_FINISHED:
                return event.status
    return None


def test_the_estimate_stays_far_below_the_default_thresholds_along_the_examples_motion():
    """Joint moves at up to 0.7 rad/s and 1.5 rad/s^2 and the example's Cartesian motion,
    all in free space: the estimate stays under 0.1 Nm and 0.5 N (the default lower
    thresholds are 12 to 20 Nm and 20 to 25 N), no contact flag ever rises."""
    ctrl = make_controller(1, enforce_motion_limits=True)
    client = LoopClient(ctrl)
    record = Recorder(ctrl)
    assert joint_move(client, ELSEWHERE, 1.5, record) == MoveStatus.kSuccess
    assert joint_move(client, READY, 1.5, record) == MoveStatus.kSuccess
    torque, force = [20.0, 20.0, 18.0, 18.0, 16.0, 14.0, 12.0], [20.0] * 3 + [25.0] * 3
    limits = thresholds(torque, torque, force, force)  # the example's, before its motion
    assert ctrl.set_collision_behavior(0, limits) == SetterStatus.kSuccess
    assert example_cartesian_motion(client, record) == MoveStatus.kSuccess
    assert record.table == 0.0  # free space all along
    assert record.flags == 0.0
    assert (record.tau < np.asarray(DEFAULT_TORQUE_THRESHOLDS)).all()
    assert (record.force < np.asarray(DEFAULT_FORCE_THRESHOLDS)).all()
    assert record.tau.max() < 0.1, record.tau
    assert record.force.max() < 0.5, record.force


def test_the_pylibfranka_examples_goal_meets_the_table_and_only_then_the_estimate_rises():
    """The move to pylibfranka's example pose (joint 2 at +pi/4) drives the wrist into the
    table: the estimate stays near zero while MuJoCo reports no table force, and the
    cartesian_reflex comes with the table pressing the arm (a true collision)."""
    ctrl = make_controller(1, enforce_motion_limits=True)
    client = LoopClient(ctrl)
    limits = thresholds([20.0] * 7, [40.0] * 7, [10.0] * 6, [20.0] * 6)  # the example's first
    assert ctrl.set_collision_behavior(0, limits) == SetterStatus.kSuccess
    before = Recorder(ctrl)
    at_the_table: list[float] = []
    contact = np.zeros(6)  # the cartesian_contact flags seen at the table

    def record(state) -> None:
        if table_contacts(ctrl.physics)[0] == 0.0:
            before(state)
            return
        if not at_the_table:
            at_the_table.append(float(state["O_T_EE"][14]))
        np.maximum(contact, state["cartesian_contact"], out=contact)

    status = joint_move(client, PYLIBFRANKA_EXAMPLE_GOAL, 2.0, record)
    assert status == MoveStatus.kReflexAborted
    assert error_names(client.state["errors"]) == (Error.cartesian_reflex.name,)
    assert table_contacts(ctrl.physics)[0] > 20.0  # the table pushes back: a real contact
    assert at_the_table and at_the_table[0] < 0.1  # the flange 10 cm above the table at most
    assert before.force.max() < 0.5 and before.tau.max() < 0.1  # nothing sensed in free space
    assert before.flags == 0.0
    # Pressed: the contact flags (above the 10 N lower thresholds) rise, and the collision
    # flags of the axes over 20 N latch with the reflex.
    assert contact.any()
    collided = np.asarray(client.state["cartesian_collision"])
    assert collided.any() and set(np.flatnonzero(collided)) <= set(np.flatnonzero(contact))
