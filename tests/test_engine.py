"""The engine's fused fast path decides exactly as the rule functions do."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from franka_sim_gym.fci import limits
from franka_sim_gym.fci.tables import FER, FR3, INTERIOR_SPEED, JOINT_VELOCITY_LIMIT_TOLERANCE

from .fci_helpers import IMP, JP, LoopClient, make_controller

CTRL = make_controller()
LoopClient(CTRL).start(JP, IMP)
ENGINE = CTRL.engine
TABLE = CTRL.table


@settings(max_examples=300, deadline=None)
@given(
    joint=st.integers(0, 6),
    q_offset=st.floats(-3.2, 3.2),
    velocity=st.floats(-3.0, 3.0),
    acceleration=st.floats(-12.0, 12.0),
    jerk=st.floats(-6000.0, 6000.0),
)
def test_fast_path_agrees_with_check_joint_position(joint, q_offset, velocity, acceleration, jerk):
    dt = 1e-3
    ref = CTRL.reference
    ref.q[0] = np.clip(TABLE.q_lower + (TABLE.q_upper - TABLE.q_lower) / 2 + 0.0, -3, 4)
    ref.q[0, joint] = np.clip(q_offset, TABLE.q_lower[joint] - 0.05, TABLE.q_upper[joint] + 0.05)
    ref.dq[0] = 0.0
    ref.ddq[0] = 0.0
    ref.dq[0, joint] = velocity - acceleration * dt
    ref.ddq[0, joint] = acceleration - jerk * dt
    q_c = ref.q.copy()
    q_c[0, joint] += velocity * dt
    fast = ENGINE._positions_inside_limits(q_c)
    rule = limits.check_joint_position(
        q_c, ref.q, ref.dq, ref.ddq, False, ref.q, 1, TABLE, 0.1
    ).error
    assert fast == (rule[0] == limits.NO_ERROR)


@settings(max_examples=100, deadline=None)
@given(answers=st.lists(st.booleans(), min_size=1, max_size=260))
def test_one_robot_accounting_matches_the_batched_arithmetic(answers):
    from franka_sim_gym.fci.accounting import CycleAccounting

    one, two = CycleAccounting(1), CycleAccounting(2)  # n = 2 takes the array path
    for acc in (one, two):
        acc.start_motion(0, 0)
        acc.started[0] = True
    for answered in answers:
        one.answered[0] = two.answered[0] = answered
        one.close_cycle(1)
        two.close_cycle(1)
        assert one.success_rate()[0] == two.success_rate()[0]
        assert one.lost_run[0] == two.lost_run[0]
        assert one.longest_lost_run[0] == two.longest_lost_run[0]
        assert one.lost_total[0] == two.lost_total[0]


def _interior_edges(table):
    distance = (INTERIOR_SPEED + table.dq_offset) ** 2 / (2.0 * table.ddq_decel)
    return table.q_upper - distance, table.q_lower + distance


@pytest.mark.parametrize("robot", [FR3, FER], ids=["fr3", "fer"])
@pytest.mark.parametrize(
    "shift", [JOINT_VELOCITY_LIMIT_TOLERANCE, JOINT_VELOCITY_LIMIT_TOLERANCE - 0.1]
)
def test_interior_shortcut_never_passes_a_speed_the_envelope_refuses(robot, shift):
    # The hardest case for the shortcut: the largest speed it lets through, at every q
    # it accepts, on a fine grid across the joint's range and at the interior's edges
    # and their float neighbours.
    bounds = robot.interior_bounds(INTERIOR_SPEED, shift)
    grids = [
        np.linspace(lo - 0.05, hi + 0.05, 4001)
        for lo, hi in zip(robot.q_lower, robot.q_upper, strict=True)
    ]
    if robot.dq_offset is not None:
        upper_edge, lower_edge = _interior_edges(robot)
        for j in range(7):
            around = np.concatenate(
                [upper_edge[j] + np.arange(-3, 4) * 1e-16, lower_edge[j] + np.arange(-3, 4) * 1e-16]
            )
            grids[j] = np.concatenate(
                [grids[j], np.nextafter(around, np.inf), np.nextafter(around, -np.inf), around]
            )
    checked = 0
    for j in range(7):
        q = np.tile((robot.q_lower + robot.q_upper) / 2, (len(grids[j]), 1))
        q[:, j] = grids[j]
        for sign, limit in ((1.0, bounds[j]), (-1.0, bounds[14 + j])):
            velocity = np.zeros_like(q)
            velocity[:, j] = sign * limit
            x = np.concatenate([velocity, q, -velocity, -q], axis=1)
            accepted = (x <= bounds).all(axis=1)
            exact = np.concatenate([velocity, -velocity], axis=1) <= robot.velocity_envelope_halves(
                q, shift
            )
            assert exact[accepted].all()
            checked += int(accepted.sum())
    assert checked > 10_000  # the shortcut accepts most of each range


def test_interior_shortcut_covers_the_home_pose_at_a_joint_speed_of_1_4_rad_per_s():
    # The shortcut is worth its place only if it decides the common case: a motion
    # around the home pose (spec) at the speeds the examples reach.
    home = np.array([0.0, -np.pi / 4, 0.0, -3 * np.pi / 4, 0.0, np.pi / 2, np.pi / 4])
    velocity = np.full(7, 1.4)
    for shift in (JOINT_VELOCITY_LIMIT_TOLERANCE, JOINT_VELOCITY_LIMIT_TOLERANCE - 0.1):
        bounds = FR3.interior_bounds(INTERIOR_SPEED, shift)
        assert (np.concatenate([velocity, home, -velocity, -home]) <= bounds).all()


def test_ee_speed_shortcut_never_passes_a_speed_over_the_limit():
    # The safety controller's per-axis bound on the measured EE velocity (for 4): the
    # largest vector it lets through, (c, +-c, +-c), is within kMaxTranslationalVelocity.
    bounds = ENGINE._measured_bounds
    axis = bounds[14:17]
    assert (bounds[31:34] == axis).all()
    for signs in np.array(np.meshgrid([1, -1], [1, -1], [1, -1])).T.reshape(-1, 3):
        v = signs * axis
        assert np.einsum("i,i->", v, v) <= TABLE.v_trans_max**2
    # ... and it is not vacuous: it passes 1.7 m/s along every axis at once.
    assert (axis >= 1.7).all()
