"""The joint side of the Cartesian generators, its range and envelope: the IK solution
outside the joint range is 27 (cartesian_motion_generator_joint_position_limits_violation),
its velocity outside the envelope at the previous solution 28
(cartesian_motion_generator_joint_velocity_limits_violation); docs/motion-limits.md, the
Cartesian tables."""

from __future__ import annotations

import math

import numpy as np
import pytest

from franka_sim_gym.fci import frames
from franka_sim_gym.fci.errors import Error, error_names
from franka_sim_gym.fci.tables import FR3
from franka_sim_gym.fci.wire import MoveMotionGeneratorMode, RobotMode
from franka_sim_gym.fci.wire.protocol import MoveStatus
from franka_sim_gym.sim.world import HOME_Q
from tests.fci_helpers import LoopClient, make_controller

CP = MoveMotionGeneratorMode.kCartesianPosition
CV = MoveMotionGeneratorMode.kCartesianVelocity
DT = 1e-3
Q7_MAX = FR3.q_upper[6]


def start_at(q7: float, generator, enforce: bool = True) -> LoopClient:
    """A Cartesian motion started with joint 7 at ``q7`` (the rest at home)."""
    ctrl = make_controller(enforce_motion_limits=enforce)
    q = HOME_Q.copy()
    q[6] = q7
    ctrl.reset([0], q)
    client = LoopClient(ctrl)
    assert client.start(generator) == MoveStatus.kMotionStarted
    return client


def turned(T0: np.ndarray, angle: float) -> np.ndarray:
    """T0 turned by ``angle`` about its own z axis (joint 7's axis; the IK from the
    previous solution spreads the turn over joints 1, 3, 5 and 7, joint 7 taking ~85 %)."""
    ca, sa = math.cos(angle), math.sin(angle)
    T = T0.copy()
    T[:3, :3] = T0[:3, :3] @ np.array([[ca, -sa, 0], [sa, ca, 0], [0, 0, 1]])
    return T


def spin(client: LoopClient, generator, omega_max: float, cycles: int) -> int | None:
    """Turn joint 7 through the EE's z axis at up to ``omega_max`` rad/s (5 rad/s^2, a
    1000 rad/s^3 ramp: inside every Cartesian and IK discontinuity limit); the cycle of the
    abort, or None."""
    T0 = frames.from_wire(np.array(client.state["O_T_EE_d"], dtype=np.float64))
    axis = T0[:3, 2]
    angle = omega = alpha = 0.0
    jerk, alpha_max = 1000.0, 5.0
    if generator == CP:
        client.send(O_T_EE_c=frames.to_wire(T0))
    else:
        client.send(O_dP_EE_c=np.zeros(6))
    for k in range(cycles):
        if omega + alpha * alpha / (2.0 * jerk) >= omega_max:
            alpha = max(alpha - jerk * DT, 0.0)
        else:
            alpha = min(alpha + jerk * DT, alpha_max)
        omega += alpha * DT
        angle += omega * DT
        if generator == CP:
            client.send(O_T_EE_c=frames.to_wire(turned(T0, angle)))
        else:
            client.send(O_dP_EE_c=np.concatenate([np.zeros(3), omega * axis]))
        if client.state["robot_mode"] != RobotMode.kMove:
            return k
    return None


def test_a_first_pose_whose_solution_is_past_joint_7s_stop_is_27():
    c = start_at(Q7_MAX - 0.02, CP)
    T0 = frames.from_wire(np.array(c.state["O_T_EE_d"], dtype=np.float64))
    c.send(O_T_EE_c=frames.to_wire(turned(T0, 0.05)))  # inside the start tolerance (16)
    assert c.move_statuses() == [MoveStatus.kReflexAborted]
    assert c.state["robot_mode"] == RobotMode.kReflex
    assert error_names(c.state["errors"]) == (
        "cartesian_motion_generator_joint_position_limits_violation",
    )
    assert c.state["q"][6] <= Q7_MAX  # the solution was never applied


def test_the_same_first_pose_inside_the_range_passes():
    c = start_at(Q7_MAX - 0.1, CP)
    T0 = frames.from_wire(np.array(c.state["O_T_EE_d"], dtype=np.float64))
    c.send(O_T_EE_c=frames.to_wire(turned(T0, 0.05)))
    assert c.move_statuses() == [] and c.state["robot_mode"] == RobotMode.kMove


@pytest.mark.parametrize(("inside", "statuses"), [(2e-6, [MoveStatus.kReflexAborted]), (8e-6, [])])
def test_an_opening_twist_whose_solution_is_past_joint_7s_stop_is_27(inside, statuses):
    """The opening twist's solution is judged for the range (its velocity is not: no
    previous solution yet); 5 mrad/s about the EE's z axis turns joint 7 by ~4.2 urad."""
    c = start_at(Q7_MAX - inside, CV)
    axis = frames.from_wire(np.array(c.state["O_T_EE_d"], dtype=np.float64))[:3, 2]
    c.send(O_dP_EE_c=np.concatenate([np.zeros(3), 0.005 * axis]))
    assert c.move_statuses() == statuses
    expected = ("cartesian_motion_generator_joint_position_limits_violation",) if statuses else ()
    assert error_names(c.state["errors"]) == expected


def test_a_twist_past_joint_7s_stop_is_27_and_outranks_28():
    c = start_at(Q7_MAX - 8e-6, CV)
    assert abs(c.ctrl.cartesian.q_ik[0, 6] - (Q7_MAX - 8e-6)) < 1e-6
    axis = frames.from_wire(np.array(c.state["O_T_EE_d"], dtype=np.float64))[:3, 2]
    # 5 then 10 mrad/s from rest: 5 rad/s^2 and 5000 rad/s^3 (no 20); joint 7's solution
    # ~4 urad inside the stop, then ~5 urad past it, its velocity outside the envelope there
    # too.
    c.send(O_dP_EE_c=np.concatenate([np.zeros(3), 0.005 * axis]))
    assert c.move_statuses() == []
    c.send(O_dP_EE_c=np.concatenate([np.zeros(3), 0.01 * axis]))
    assert c.move_statuses() == [MoveStatus.kReflexAborted]
    assert error_names(c.state["errors"]) == (
        "cartesian_motion_generator_joint_position_limits_violation",
    )


@pytest.mark.parametrize("generator", [CP, CV])
def test_a_smooth_turn_into_joint_7s_stop_is_28_before_the_range(generator, caplog):
    c = start_at(2.5, generator)
    aborted = spin(c, generator, omega_max=1.0, cycles=2000)
    assert aborted is not None
    assert c.move_statuses() == [MoveStatus.kReflexAborted]
    assert error_names(c.state["errors"]) == (
        "cartesian_motion_generator_joint_velocity_limits_violation",
    )
    # Joint 7 turns at ~0.85 rad/s (the IK gives it ~85 % of the EE's 1 rad/s): the envelope
    # sqrt(2 x 17 x d) - 0.35 falls below that 42 mrad before the stop.
    q7 = float(c.state["q_d"][6]) if generator == CP else float(c.ctrl.cartesian.q_ik[0, 6])
    assert Q7_MAX - 0.08 < q7 < Q7_MAX - 0.03
    # The solution's velocity is judged against the envelope at the previous solution (the
    # last one followed): the log names both, the velocity over that bound.
    [line] = [r.getMessage() for r in caplog.records if "IK joint velocity" in r.getMessage()]
    value, limit = (float(x.split()[0]) for x in line.split("joint 7 = ")[1].split("limit "))
    q_prev = c.ctrl.cartesian.q_ik[0].astype(float)
    assert limit == pytest.approx(FR3.velocity_envelope(q_prev)[0][6], abs=1e-6)
    assert value > limit


@pytest.mark.parametrize("generator", [CP, CV])
def test_the_same_turn_stopping_short_of_the_band_passes(generator):
    c = start_at(2.0, generator)
    assert spin(c, generator, omega_max=1.0, cycles=500) is None  # ~0.45 rad turned
    assert error_names(c.state["errors"]) == ()


def test_unenforced_the_turn_goes_on_and_logs_28_and_27():
    c = start_at(2.5, CP, enforce=False)
    assert spin(c, CP, omega_max=1.0, cycles=1200) is None
    seen = c.ctrl.violations.take()[0]
    assert seen[Error.cartesian_motion_generator_joint_velocity_limits_violation]
    assert seen[Error.cartesian_motion_generator_joint_position_limits_violation]
