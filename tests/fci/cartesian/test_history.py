"""The Cartesian history's arithmetic (fci/cartesian/_history.c), against what
docs/fci-behaviour.md documents: the pose's differences (translation in the base frame,
rotation in the body frame, one cycle each), the joint side's warm-up, what a judged step
records (at rest on the opening command, the lost-cycle law's velocity and frozen
acceleration, the reported twist in the base frame, the IK history rebased after a failed
solve) and the layout it refuses."""

from __future__ import annotations

import math

import numpy as np
import pytest

from franka_sim_gym.fci.cartesian.reference import CartesianReference
from franka_sim_gym.fci.cartesian.step import WARM_ACCELERATION, WARM_JERK, history_plan, usable
from franka_sim_gym.fci.state import StateWriter
from franka_sim_gym.fci.tables import DELTA_T
from franka_sim_gym.sim.ik import USABLE_POSITION_ERROR, USABLE_ROTATION_ERROR, IkResult
from franka_sim_gym.sim.rotations import NEAR_PI, SERIES_BELOW, SLERP_LINEAR, TURNING_ABOVE

N = 3


def _rx(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])


def _rz(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


@pytest.fixture
def plan():
    h = CartesianReference(N)
    h.T[...] = np.eye(4)
    pose_stack, joint_stack = np.zeros((N, 3, 6)), np.zeros((N, 4, 7))
    plan = history_plan(h, pose_stack, joint_stack, np.tile(np.eye(4), (N, 1, 1)), StateWriter(N))
    return h, plan, pose_stack, joint_stack


def _flags(*rows: int) -> np.ndarray:
    out = np.zeros(N, dtype=bool)
    out[list(rows)] = True
    return out


NONE = np.zeros(N, dtype=bool)
ALL = np.ones(N, dtype=bool)


# -- the pose's differences --------------------------------------------------------------------


def test_pose_differences_translate_in_the_base_frame_and_turn_in_the_body_frame(plan):
    h, p, D, _ = plan
    R0 = _rx(math.pi / 2)  # the body's z is the base's -y
    h.T[:, :3, :3] = R0
    h.T[:, :3, 3] = [0.3, 0.0, 0.5]
    h.v[1] = [0.5, 0.0, 0.0]  # the previous cycle's velocity and acceleration (robot 1)
    h.a[1] = [100.0, 0.0, 0.0]
    T = h.T.copy()
    T[:, 0, 3] += 1e-3  # 1 mm along the base's x in one cycle: 1 m/s
    T[:, :3, :3] = R0 @ _rz(1e-3)  # 1 mrad about the body's z: omega_body = (0, 0, 1)
    p.pose_derivatives(h.buffer, T)
    np.testing.assert_allclose(D[:, 0, :3], [[1.0, 0, 0]] * N, atol=1e-9)
    np.testing.assert_allclose(D[:, 0, 3:], [[0, 0, 1.0]] * N, atol=1e-9)
    # the acceleration and jerk: one more difference each over the cycle
    assert D[1, 1, 0] == pytest.approx((1.0 - 0.5) / DELTA_T, rel=1e-9)
    assert D[1, 2, 0] == pytest.approx(((1.0 - 0.5) / DELTA_T - 100.0) / DELTA_T, rel=1e-9)
    assert D[0, 1, 0] == pytest.approx(1.0 / DELTA_T, rel=1e-9)


def test_pose_differences_read_the_history_they_are_given(plan):
    """A late datagram is differenced against a published history, not the live one."""
    h, p, D, _ = plan
    published = h.buffer.copy()
    published[:, h.column(h.T) + 3] = -1e-3  # T[0, 3] one millimetre behind
    p.pose_derivatives(published, np.tile(np.eye(4), (N, 1, 1)))
    np.testing.assert_allclose(D[:, 0, 0], 1.0, rtol=1e-9)
    p.pose_derivatives(h.buffer, np.tile(np.eye(4), (N, 1, 1)))
    assert not D.any()


# -- the joint side ----------------------------------------------------------------------------


def test_the_joint_side_is_judged_only_as_far_as_its_history_is_warm(plan):
    h, p, _, S = plan
    h.q_ik[:] = 0.1
    h.dq_ik[:] = 2.0
    h.ik_warm[:] = [WARM_JERK, WARM_ACCELERATION, WARM_JERK]
    S[:, 0] = 0.1 + 3.0 * DELTA_T  # 3 rad/s
    checked = np.zeros(N, dtype=bool)
    converged = _flags(0, 1)
    failed = p.joint_side(h.buffer, NONE, ALL, converged, checked)
    assert failed == 1  # robot 2's solve did not converge (Python logs it)
    np.testing.assert_allclose(S[:, 1], 3.0, rtol=1e-9)
    np.testing.assert_allclose(S[:, 2], (3.0 - 2.0) / DELTA_T, rtol=1e-9)
    # robot 0 is warm for the jerk; robot 1 only for the acceleration; robot 2 failed
    assert S[0, 3] == pytest.approx(1000.0 / DELTA_T, rel=1e-9)
    assert not S[1, 3].any() and not S[2, 3].any()
    assert checked.tolist() == [True, True, False]
    # the opening command: nothing is judged yet
    p.joint_side(h.buffer, _flags(0), ALL, converged, checked)
    assert checked.tolist() == [False, True, False] and not S[0, 3].any()
    assert p.joint_side(h.buffer, NONE, _flags(0, 1), converged, checked) == 0
    # just rebased (a failed solve before): the velocity alone, nothing judged
    h.ik_warm[:] = 0.0
    p.joint_side(h.buffer, NONE, ALL, ALL, checked)
    assert not checked.any() and not S[:, 3].any()


# -- the record --------------------------------------------------------------------------------


def _record(p, T, first=NONE, extrapolate=NONE, real=ALL, apply=ALL, converged=ALL, errors=0.0,
            pose=ALL, twist=None, twist_stack=None, pose_ex=(None, None), echo=None):  # fmt: skip
    twist = np.zeros((N, 6)) if twist is None else twist
    error = np.full(N, errors)
    echo = np.arange(7, 7 + N, dtype=np.uint64) if echo is None else echo
    p.record(T, twist, twist_stack, *pose_ex, pose, apply, real, extrapolate, first, converged,
             error, error.copy(), echo)  # fmt: skip


def test_a_pose_step_records_its_differences_and_reports_the_base_frame_twist(plan):
    h, p, D, S = plan
    R = _rx(math.pi / 2)
    T = np.tile(np.eye(4), (N, 1, 1))
    T[:, :3, :3] = R
    D[:, 0] = [0.1, 0.2, 0.3, 0.0, 0.0, 1.0]  # v | omega_body
    D[:, 1] = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]
    S[:, :3] = [[0.5], [2.0], [40.0]]  # q, dq, ddq of the solution
    h.reported[:] = 0.05
    h.ik_warm[:] = 3.0
    _record(p, T)
    np.testing.assert_array_equal(h.T, T)
    np.testing.assert_array_equal(h.history, D[:, :2])
    np.testing.assert_array_equal(h.acceleration_frozen, D[:, 1])  # commands that arrived
    # O_dP_EE_c: the translation as commanded, the rotation R_c omega_body (base frame)
    np.testing.assert_allclose(h.reported[:, 3:], [R @ [0, 0, 1.0]] * N, atol=1e-15)
    np.testing.assert_array_equal(h.reported[:, :3], D[:, 0, :3])
    np.testing.assert_allclose(h.dreported[:, 0], (0.1 - 0.05) / DELTA_T, rtol=1e-12)
    np.testing.assert_array_equal(h.joint, S[:, :3])
    assert h.ik_warm.tolist() == [4.0] * N
    assert h.real_echo.tolist() == [7, 8, 9] and not h.run.any()


def test_the_opening_command_starts_the_history_at_rest(plan):
    h, p, D, S = plan
    D[...] = 5.0
    S[:, :3] = [[0.5], [2.0], [40.0]]
    h.reported[:] = 0.3
    _record(p, np.tile(np.eye(4), (N, 1, 1)), first=_flags(1))
    assert not h.history[1].any() and not h.dreported[1].any()
    assert (h.history[0] == 5.0).all()
    assert h.q_ik[1].tolist() == [0.5] * 7
    assert not h.dq_ik[1].any() and not h.ddq_ik[1].any()
    assert h.ik_warm.tolist() == [1.0, WARM_JERK, 1.0]


def test_a_lost_cycle_records_the_laws_velocity_and_the_frozen_acceleration(plan):
    h, p, D, _ = plan
    h.acceleration_frozen[:] = 7.0
    h.real_echo[:] = 3
    h.run[:] = 2
    D[...] = 5.0
    v_ex, w_ex = np.full((N, 3), 0.25), np.full((N, 3), -0.5)
    _record(p, np.tile(np.eye(4), (N, 1, 1)), extrapolate=_flags(2), real=_flags(0, 1),
            pose_ex=(v_ex, w_ex))  # fmt: skip
    assert h.v[2].tolist() == [0.25] * 3 and h.omega[2].tolist() == [-0.5] * 3
    assert h.a[2].tolist() == [7.0] * 3 and h.alpha[2].tolist() == [7.0] * 3
    assert h.acceleration_frozen[2].tolist() == [7.0] * 6  # the guess's: the frozen one
    assert h.acceleration_frozen[0].tolist() == [5.0] * 6
    assert h.real_echo.tolist() == [7, 8, 3] and h.run.tolist() == [0, 0, 2]
    with pytest.raises(ValueError, match="extrapolated robot without v_ex"):
        _record(p, np.tile(np.eye(4), (N, 1, 1)), extrapolate=_flags(2), real=_flags(0, 1))
    with pytest.raises(ValueError, match="v_ex and w_ex go together"):
        _record(p, np.tile(np.eye(4), (N, 1, 1)), pose_ex=(v_ex, None))


def test_a_twist_motion_records_its_twist_and_reports_it(plan):
    h, p, _, _ = plan
    twist = np.tile([0.1, 0, 0, 0, 0, 0.2], (N, 1))
    stack = np.zeros((N, 3, 6))
    stack[:, 1] = 9.0
    h.dtwist_frozen[:] = -1.0
    _record(p, np.tile(np.eye(4), (N, 1, 1)), pose=NONE, twist=twist, twist_stack=stack,
            extrapolate=_flags(1), real=_flags(0, 2),
            pose_ex=(np.zeros((N, 3)), np.zeros((N, 3))))  # fmt: skip
    np.testing.assert_array_equal(h.twist, twist)
    assert h.dtwist[:, 0].tolist() == [9.0, -1.0, 9.0]  # the guess's acceleration is frozen
    assert h.dtwist_frozen[:, 0].tolist() == [9.0, -1.0, 9.0]  # re-frozen by the real ones
    np.testing.assert_array_equal(h.reported, twist)
    assert not h.history.any()  # no pose motion: the pose's history is not touched


def test_a_failed_solve_rebases_the_joint_history_and_an_unusable_one_is_not_followed(plan):
    h, p, _, S = plan
    h.q_ik[:] = 0.1
    h.ik_warm[:] = 5.0
    S[:, :3] = [[0.5], [2.0], [40.0]]
    near = np.zeros(N, dtype=bool)  # not converged, within the usable bounds
    _record(p, np.tile(np.eye(4), (N, 1, 1)), converged=near, errors=USABLE_POSITION_ERROR / 2)
    assert h.q_ik[0].tolist() == [0.5] * 7  # followed
    assert not h.dq_ik.any() and not h.ddq_ik.any() and not h.ik_warm.any()
    h.q_ik[:] = 0.1
    _record(p, np.tile(np.eye(4), (N, 1, 1)), converged=near, errors=2 * USABLE_ROTATION_ERROR)
    assert h.q_ik[0].tolist() == [0.1] * 7  # held: the servo keeps the last usable one


def test_only_the_applied_robots_are_recorded(plan):
    h, p, D, _ = plan
    D[...] = 5.0
    before = h.buffer.copy()
    _record(p, np.zeros((N, 4, 4)), apply=_flags(0), real=_flags(0))
    np.testing.assert_array_equal(h.buffer[1:], before[1:])
    assert h.real_echo.tolist() == [7, 0, 0]


def test_usable_solutions():
    converged = np.array([True, False, False, False])
    position = np.array([1.0, USABLE_POSITION_ERROR, USABLE_POSITION_ERROR, np.nan])
    rotation = np.array([1.0, USABLE_ROTATION_ERROR, 1.1 * USABLE_ROTATION_ERROR, 0.0])
    ik = IkResult(np.zeros((4, 7)), converged, position, rotation)
    assert usable(ik).tolist() == [True, True, False, False]


# -- what the state publishes -------------------------------------------------------------------

#: a plan's constants as step.py hands them over
CONSTANTS = (DELTA_T, WARM_ACCELERATION, WARM_JERK, USABLE_POSITION_ERROR, USABLE_ROTATION_ERROR,
             NEAR_PI, TURNING_ABOVE, SERIES_BELOW, SLERP_LINEAR)  # fmt: skip


def _published() -> tuple:
    """The plan's "published" arrays, fresh ones."""
    start = np.tile(np.eye(4), (N, 1, 1))
    return (start, *(np.zeros((N, 16)) for _ in range(2)), *(np.zeros((N, 6)) for _ in range(3)),
            *(np.zeros((N, 2)) for _ in range(2)))  # fmt: skip


def test_the_state_publishes_each_motions_own_pose_and_every_motions_twist():
    """docs/fci-behaviour.md "RobotState fields": a pose motion's O_T_EE_d / O_T_EE_c are its
    commanded pose, a twist motion's the pose it started from, column-major as the wire; both
    report the recorded twist and its rate; elbow_d / elbow_c the streamed elbow."""
    h = CartesianReference(N)
    w = StateWriter(N)
    start = np.tile(np.eye(4), (N, 1, 1))
    start[:, :3, 3] = [0.1, 0.2, 0.3]
    p = history_plan(h, np.zeros((N, 3, 6)), np.zeros((N, 4, 7)), start, w)
    h.T[...] = np.arange(16.0).reshape(4, 4)
    h.reported[...] = 0.5
    h.dreported[...] = -2.0
    h.elbow[...] = [0.7, -1.0]
    h.set_has_elbow(_flags(0, 1))
    w.elbow_d[...] = w.elbow_c[...] = 9.0
    before = w.O_T_EE_d.copy()
    p.publish(_flags(0), _flags(1))
    np.testing.assert_array_equal(w.O_T_EE_d[0], np.arange(16.0).reshape(4, 4).T.reshape(16))
    np.testing.assert_array_equal(w.O_T_EE_c[0], w.O_T_EE_d[0])
    np.testing.assert_array_equal(w.O_T_EE_d[1], start[1].T.reshape(16))
    np.testing.assert_array_equal(w.O_T_EE_c[1], start[1].T.reshape(16))
    np.testing.assert_array_equal(w.O_T_EE_d[2], before[2])  # no Cartesian motion
    for field, value in (("O_dP_EE_d", 0.5), ("O_dP_EE_c", 0.5), ("O_ddP_EE_c", -2.0)):
        assert w.field[field][:2].tolist() == [[value] * 6] * 2
        assert not w.field[field][2].any()
    assert w.elbow_d[:2].tolist() == [[0.7, -1.0]] * 2 and w.elbow_c[1].tolist() == [0.7, -1.0]
    h.set_has_elbow(ALL)  # robot 2 streams none while in no Cartesian motion: its own stays
    w.elbow_d[...] = 9.0
    p.publish(_flags(0), _flags(1))
    assert w.elbow_d[:2].tolist() == [[0.7, -1.0]] * 2 and (w.elbow_d[2] == 9.0).all()
    h.set_has_elbow(NONE)
    w.elbow_d[...] = 9.0
    p.publish(_flags(0), NONE)
    assert (w.elbow_d == 9.0).all()  # no elbow streamed: the measured one stays


def test_the_reported_rotation_of_a_held_orientation_is_a_positive_zero(plan):
    """omega_body exactly +0 (an opening command, a held orientation) and a rotation row of
    negative entries: R_c omega is +0.0 as numpy's einsum gives it (the wire carries the
    sign of a zero)."""
    h, p, D, _ = plan
    T = np.tile(np.eye(4), (N, 1, 1))
    T[:, :3, :3] = [[-1e-16, -1.0, -1e-17], [1.0, -1e-16, 0.0], [0.0, 0.0, 1.0]]
    D[...] = 0.0
    _record(p, T)
    assert not np.signbit(h.reported).any()


# -- the layout it refuses ---------------------------------------------------------------------


def test_the_plan_refuses_another_layout_by_name(plan):
    h, p, _, S = plan
    with pytest.raises(ValueError, match="history: axis 1 has length 91, expected 92"):
        p.pose_derivatives(h.buffer[:, :-1], np.tile(np.eye(4), (N, 1, 1)))
    with pytest.raises(ValueError, match="T: axis 1 has length 3, expected 4"):
        p.pose_derivatives(h.buffer, np.zeros((N, 3, 4)))
    with pytest.raises(ValueError, match="checked: expected a writable"):
        p.joint_side(h.buffer, NONE, ALL, ALL, NONE.copy().view(np.int8))
    with pytest.raises(ValueError, match=r"layout: T \(16 columns at 0\) does not fit a 10-"):
        type(p)(h.buffer, h.real_echo, h.run, np.zeros((N, 3, 6)), S, _published(),
                (10, *range(12)), CONSTANTS)  # fmt: skip
    with pytest.raises(ValueError, match="buffer: expected rows of contiguous"):
        wide = np.zeros((N, 2 * h.buffer.shape[1]))[:, ::2]
        type(p)(wide, h.real_echo, h.run, np.zeros((N, 3, 6)), S, _published(),
                (h.buffer.shape[1], *range(12)), CONSTANTS)  # fmt: skip
    with pytest.raises(ValueError, match="O_dP_EE_c: axis 1 has length 7, expected 6"):
        fields = list(_published())
        fields[4] = np.zeros((N, 7))
        type(p)(h.buffer, h.real_echo, h.run, np.zeros((N, 3, 6)), S, tuple(fields),
                (h.buffer.shape[1], *range(12)), CONSTANTS)  # fmt: skip
