"""The Cartesian generators' tables (fci/limits/cartesian.py, whose rows' one text is
fci/limits/_joint.c ``cartesian_rule``), judged on hand-made commands.

Rows and precedence: docs/fci-behaviour.md "What is checked, and what it latches" and
"The joint side of a Cartesian command"; the limits are the FR3's (docs/limits.md): a
Cartesian half is within its limit up to its norm's square equal to the limit's, a NaN is
never within, the pose's derivatives are judged after its opening command and the
twist's always, the joint side's velocity at the envelope of the previous solution.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from franka_sim_gym.fci.errors import Error
from franka_sim_gym.fci.limits import cartesian as rules
from franka_sim_gym.fci.tables import FR3

# NaN inputs must be judged silently: no RuntimeWarning on the cycle path.
pytestmark = pytest.mark.filterwarnings("error")

E = Error
HOME = np.array([0.0, -math.pi / 4, 0.0, -3 * math.pi / 4, 0.0, math.pi / 2, math.pi / 4])


def no_elbow(n: int, **fields) -> rules.ElbowStream:
    zeros = np.zeros(n)
    stream = {
        "command": np.tile([0.0, -1.0], (n, 1)),
        "has": np.zeros(n, dtype=bool),
        "had": np.zeros(n, dtype=bool),
        "prev_flag": np.full(n, -1.0),
        "derivatives": rules.ElbowDerivatives(zeros, zeros.copy(), zeros.copy()),
    }
    stream.update(fields)
    return rules.ElbowStream(**stream)


def joint_at_rest(n: int, checked=True, solved=True, q=None, dq=None, ik=None, q_prev=None):
    q = np.tile(HOME, (n, 1)) if q is None else np.asarray(q, dtype=float)
    q_prev = np.tile(HOME, (n, 1)) if q_prev is None else np.asarray(q_prev, dtype=float)
    dq = np.zeros((n, 7)) if dq is None else np.asarray(dq, dtype=float)
    return rules.JointSide(
        np.zeros((n, 2, 7)) if ik is None else np.asarray(ik, dtype=float),
        np.full(n, checked),
        np.stack([q, dq], axis=1),
        q_prev,
        np.full(n, solved),
    )


def twist(stacked, first=False, elbow=None, joint=None, n=None):
    stacked = np.asarray(stacked, dtype=float)
    n = len(stacked)
    return rules.check_cartesian_velocity(
        stacked,
        np.full(n, first),
        no_elbow(n) if elbow is None else elbow,
        joint_at_rest(n) if joint is None else joint,
        FR3,
        1.0,
    )


def pose(stacked, first=False, elbow=None, joint=None):
    stacked = np.asarray(stacked, dtype=float)
    n = len(stacked)
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, 3] = [0.3, 0.0, 0.5]
    O_T_EE = T.transpose(0, 2, 1).reshape(n, 16).astype(np.float32)
    elbow = no_elbow(n) if elbow is None else elbow
    return rules.check_cartesian_pose(
        rules.PoseDerivatives(stacked),
        np.full(n, first),
        T,
        O_T_EE,
        elbow,
        elbow.command.copy(),
        joint_at_rest(n) if joint is None else joint,
        FR3,
        1.0,
        0.05,
        0.1,
        0.1,
    )


def stack(v=(0, 0, 0), omega=(0, 0, 0), a=(0, 0, 0), alpha=(0, 0, 0), jerk=(0, 0, 0)):
    """One robot's (1, 3, 6) [[v | omega], [a | alpha], [jerk | zeta]]."""
    return np.array([[[*v, *omega], [*a, *alpha], [*jerk, 0, 0, 0]]], dtype=float)


def errors(check) -> list[int]:
    return check.error.tolist()


@pytest.mark.parametrize(
    "half, limit, code",
    [
        ("v", FR3.v_trans_max, E.cartesian_motion_generator_velocity_limits_violation),
        ("omega", FR3.v_rot_max, E.cartesian_motion_generator_velocity_limits_violation),
        ("a", FR3.a_trans_max, E.cartesian_motion_generator_acceleration_discontinuity),
        ("alpha", FR3.a_rot_max, E.cartesian_motion_generator_acceleration_discontinuity),
        ("jerk", FR3.j_trans_max, E.cartesian_motion_generator_acceleration_discontinuity),
    ],
)
def test_a_twist_half_at_its_limit_passes_and_one_ulp_over_trips(half, limit, code):
    assert errors(twist(stack(**{half: (limit, 0, 0)}))) == [-1]
    over = np.nextafter(limit, math.inf)
    check = twist(stack(**{half: (over, 0, 0)}))
    assert errors(check) == [int(code)]
    assert check.tripped.sum() == 1  # only its own row


def test_a_nan_in_a_half_is_never_within_it():
    assert errors(twist(stack(v=(math.nan, 0, 0)))) == [
        int(E.cartesian_motion_generator_velocity_limits_violation)
    ]
    assert errors(pose(stack(alpha=(0, math.nan, 0)))) == [
        int(E.cartesian_motion_generator_velocity_discontinuity)
    ]


def test_the_pose_judges_its_derivatives_after_the_opening_command_the_twist_always():
    fast = stack(a=(20.0, 0, 0))  # over the 9 m/s^2 on either generator
    assert errors(pose(fast, first=True)) == [-1]
    assert errors(pose(fast)) == [int(E.cartesian_motion_generator_velocity_discontinuity)]
    assert errors(twist(fast, first=True)) == [
        int(E.cartesian_motion_generator_acceleration_discontinuity)
    ]


def test_the_pose_table_latches_its_first_row_acceleration_over_velocity_and_jerk():
    everything = stack(v=(5.0, 0, 0), a=(20.0, 0, 0), jerk=(1e4, 0, 0))
    check = pose(everything)
    assert errors(check) == [int(E.cartesian_motion_generator_velocity_discontinuity)]  # 19
    names = [rules.POSE_ROWS[k] for k in np.flatnonzero(check.tripped[0])]
    assert names == ["acceleration", "velocity", "jerk"]
    check = twist(stack(v=(5.0, 0, 0), jerk=(1e4, 0, 0)))  # jerk (20) over velocity (18)
    assert errors(check) == [int(E.cartesian_motion_generator_acceleration_discontinuity)]


def test_the_joint_side_acceleration_and_jerk_where_checked_29_and_30():
    ik = np.zeros((1, 2, 7))
    ik[0, 0, 3] = np.nextafter(FR3.ik_ddq_max[3], math.inf)
    assert errors(pose(stack(), joint=joint_at_rest(1, ik=ik))) == [
        int(E.cartesian_motion_generator_joint_velocity_discontinuity)  # 29
    ]
    # The twist's 30 for both its acceleration and its jerk rows.
    assert errors(twist(stack(), joint=joint_at_rest(1, ik=ik))) == [
        int(E.cartesian_motion_generator_joint_acceleration_discontinuity)
    ]
    ik[0, 0, 3] = FR3.ik_ddq_max[3]  # at the limit
    assert errors(pose(stack(), joint=joint_at_rest(1, ik=ik))) == [-1]
    ik = np.zeros((1, 2, 7))
    ik[0, 1, 6] = -2 * FR3.ik_dddq_max[6]
    assert errors(pose(stack(), joint=joint_at_rest(1, ik=ik))) == [
        int(E.cartesian_motion_generator_joint_acceleration_discontinuity)  # 30
    ]
    # Not checked (the IK history not warm, or not converged): neither row.
    assert errors(pose(stack(), joint=joint_at_rest(1, checked=False, ik=ik))) == [-1]
    ik[0, 0, 0] = 2 * FR3.ik_ddq_max[0]
    assert errors(twist(stack(), joint=joint_at_rest(1, checked=False, ik=ik))) == [-1]


def test_the_solution_outside_its_range_is_27_where_solved_even_on_the_opening_command():
    q = HOME.copy()
    q[6] = np.nextafter(FR3.q_upper[6], math.inf)
    joint = joint_at_rest(1, checked=False, q=[q])
    assert errors(pose(stack(), first=True, joint=joint)) == [
        int(E.cartesian_motion_generator_joint_position_limits_violation)
    ]
    q[6] = math.nan  # "not inside": a NaN solution trips
    assert errors(twist(stack(), joint=joint_at_rest(1, q=[q]))) == [
        int(E.cartesian_motion_generator_joint_position_limits_violation)
    ]
    unsolved = joint_at_rest(1, checked=False, solved=False, q=[q])
    assert errors(pose(stack(), joint=unsolved)) == [-1]


def test_the_solution_velocity_is_judged_at_the_envelope_of_the_previous_solution_28():
    halves = FR3.velocity_envelope_halves(HOME)  # [upper | -lower] at q_prev
    dq = np.zeros(7)
    dq[1] = halves[1]  # at the bound
    assert errors(pose(stack(), joint=joint_at_rest(1, dq=[dq]))) == [-1]
    dq[1] = np.nextafter(halves[1], math.inf)
    assert errors(pose(stack(), joint=joint_at_rest(1, dq=[dq]))) == [
        int(E.cartesian_motion_generator_joint_velocity_limits_violation)
    ]
    dq[1] = -np.nextafter(halves[8], math.inf)  # past the lower bound
    assert errors(twist(stack(), joint=joint_at_rest(1, dq=[dq]))) == [
        int(E.cartesian_motion_generator_joint_velocity_limits_violation)
    ]
    # Near the stop the envelope at the previous solution is the bound, not the one at
    # the new solution (back at HOME, where it is wider).
    near = HOME.copy()
    near[1] = FR3.q_upper[1] - 0.01
    narrow = FR3.velocity_envelope_halves(near)[1]
    assert narrow < 0.5 * halves[1]
    dq = np.zeros(7)
    dq[1] = 1.01 * narrow
    joint = joint_at_rest(1, dq=[dq], q_prev=[near])
    assert errors(pose(stack(), joint=joint)) == [
        int(E.cartesian_motion_generator_joint_velocity_limits_violation)
    ]


def test_the_elbow_flag_flip_is_21_only_on_a_command_that_continues_an_elbow_stream():
    flipped = {"command": np.array([[0.0, 1.0]]), "has": np.array([True])}
    continuing = no_elbow(1, had=np.array([True]), **flipped)
    assert errors(pose(stack(), elbow=continuing)) == [
        int(E.cartesian_motion_generator_elbow_sign_inconsistent)
    ]
    assert errors(twist(stack(), elbow=continuing)) == [
        int(E.cartesian_motion_generator_elbow_sign_inconsistent)
    ]
    assert errors(twist(stack(), elbow=no_elbow(1, **flipped))) == [-1]  # a new stream
    assert errors(twist(stack(), first=True, elbow=continuing)) == [-1]


def test_the_elbow_outside_joint_3s_range_is_17_always_its_speed_only_when_continuing():
    outside = np.array([[np.nextafter(FR3.q_upper[2], math.inf), -1.0]])
    has = np.array([True])
    assert errors(twist(stack(), first=True, elbow=no_elbow(1, command=outside, has=has))) == [
        int(E.cartesian_motion_generator_elbow_limit_violation)
    ]
    fast = rules.ElbowDerivatives(np.array([2 * FR3.v_elbow_max]), np.zeros(1), np.zeros(1))
    new = no_elbow(1, has=has, derivatives=fast)
    assert errors(twist(stack(), elbow=new)) == [-1]
    going = no_elbow(1, has=has, had=has, derivatives=fast)
    assert errors(twist(stack(), elbow=going)) == [
        int(E.cartesian_motion_generator_elbow_limit_violation)
    ]


def test_each_robot_of_a_batch_gets_its_own_error():
    n = 5
    stacked = np.zeros((n, 3, 6))
    stacked[1, 0, 0] = 5.0  # velocity: 18
    stacked[3, 1, 4] = 20.0  # angular acceleration: 19 (pose) / 20 (twist)
    ik = np.zeros((n, 2, 7))
    ik[4, 1, 0] = 1e5  # IK jerk: 30
    joint = joint_at_rest(n, ik=ik)
    expected_pose = [-1, 18, -1, 19, 30]
    assert errors(pose(stacked, joint=joint)) == expected_pose
    assert errors(twist(stacked, joint=joint)) == [-1, 18, -1, 20, 30]
    assert errors(pose(stacked[[0, 2]], joint=joint_at_rest(2))) == [-1, -1]


def test_a_check_with_nothing_tripped_builds_no_rows():
    check = twist(np.zeros((3, 3, 6)))
    assert check.tripped is None and errors(check) == [-1, -1, -1]


def test_bad_arguments_are_a_value_error_naming_them():
    with pytest.raises(ValueError, match="stacked"):
        twist(np.zeros((1, 2, 6)))
    joint = joint_at_rest(2)
    with pytest.raises(ValueError, match="ik"):
        twist(np.zeros((1, 3, 6)), joint=joint)
