"""The contact estimate's and the collision levels' rules, their one C text
(fci/contact/_contact.c), against what docs/robot-state.md and fci/contact/collision.py say of them.

The levels are driven through the whole sensing step (``sense``) with inputs whose
published estimate and wrench are the values under test: an estimate already equal to
its residual stays put (the filter moves it by alpha times their difference), and with
J = [I6 | 0] and no damping the wrench is the torque's first six components.
"""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.fci.contact import estimate as contact
from franka_sim_gym.fci.contact.collision import (
    ACCELERATION_PHASE,
    DEFAULT_TORQUE_THRESHOLDS,
    CollisionBehavior,
)
from tests.fci.contact.test_collision import payload

C = contact.RULES
DECIMALS = contact.RESOLUTION_DECIMALS
HUGE = 1e9  # a threshold nothing reaches


def sense(behavior, tau, ddq_d=None, in_motion=None):
    """One sensing step whose published estimate is ``tau`` (n, 7) and whose wrench is
    its first six components; returns (count over, outputs by name)."""
    tau = np.asarray(tau, dtype=float)
    n = len(tau)
    jacobian = np.zeros((n, 6, 7))
    jacobian[:, :, :6] = np.eye(6)
    out = {k: np.full((n, size), -1.0) for k, size in
           (("tau", 7), ("wrench", 6), ("k", 6), ("joint", 7), ("cartesian", 6),
            ("joint_over", 7), ("cartesian_over", 6))}  # fmt: skip
    accelerating = np.full(n, 7, dtype=np.uint8)
    over = C.sense(
        tau.copy(), tau, np.zeros((n, 7)), np.zeros((n, 7)), jacobian,
        np.broadcast_to(np.eye(3), (n, 3, 3)).copy(),
        np.zeros((n, 7)) if ddq_d is None else np.asarray(ddq_d, dtype=float),
        np.zeros(n, bool) if in_motion is None else np.asarray(in_motion, dtype=bool),
        behavior.thresholds, contact.ALPHA, 0.0, DECIMALS, ACCELERATION_PHASE,
        *out.values(), accelerating,
    )  # fmt: skip
    out["accelerating"] = accelerating
    return over, out


def test_the_filter_moves_the_estimate_by_alpha_of_the_residual_and_publishes_it_rounded():
    """docs/robot-state.md (tau_ext_hat_filtered): the model residual tau_J - (M ddq +
    bias), first-order low-pass filtered (y += alpha (x - y)), published at 0.1 mNm."""
    tau_ext = np.array([[0.0, 1.0, -2.0, 0.5, 0.0, 0.0, 3.0]])
    tau_J = np.array([[1.23456789, 1.0, 4.0, 0.5, -7.0, 0.0, 3.0]])
    m_ddq = np.array([[0.5, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0]])
    bias = np.array([[0.25, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0]])
    out = np.empty((1, 7))
    state = tau_ext.copy()
    C.filter_residual(state, tau_J, m_ddq, bias, contact.ALPHA, DECIMALS, out)
    residual = tau_J - (m_ddq + bias)
    want = tau_ext + contact.ALPHA * (residual - tau_ext)
    np.testing.assert_allclose(state, want, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(out, np.round(state, DECIMALS))
    assert out[0, 0] != state[0, 0]  # this one was rounded
    assert state[0, 1] == 1.0 and state[0, 6] == 3.0  # at its residual: it stays


def test_a_wrench_publishes_no_negative_zero():
    """A component that rounds to zero from below is published as +0.0 (docs/robot-state.md:
    the wrench at 0.1 mN, no negative zero)."""
    J = np.zeros((1, 6, 7))
    J[0, :, :6] = np.eye(6)
    tau = np.array([[-1e-9, 2.0, 0.0, -3.00004, 0.0, 0.0, 0.0]])
    F = C.wrench_from_torque(J, tau, 0.0, DECIMALS, np.empty((1, 6)))
    np.testing.assert_array_equal(F, [[0.0, 2.0, 0.0, -3.0, 0.0, 0.0]])
    assert not np.signbit(F[0, 0])
    K = C.in_frame(-F, np.eye(3)[None], DECIMALS, np.empty((1, 6)))
    assert not np.signbit(K[F == 0]).any()


def test_the_frame_k_is_o_t_ee_times_ee_t_k():
    """O_T_K = O_T_EE · EE_T_K from the wire's column-major transforms: K 10 cm along the
    EE's z, turned 90 degrees about it."""
    O_T_EE = np.eye(4)
    O_T_EE[:3, :3] = [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]  # Ry(90 deg)
    O_T_EE[:3, 3] = [0.4, -0.1, 0.3]
    EE_T_K = np.eye(4)
    EE_T_K[:3, :3] = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]  # Rz(90 deg)
    EE_T_K[:3, 3] = [0.0, 0.0, 0.1]
    wire = [T.T.reshape(1, 16).copy() for T in (O_T_EE, EE_T_K)]
    point, rotation = np.empty((1, 3)), np.empty((1, 3, 3))
    C.k_frame(*wire, point, rotation)
    O_T_K = O_T_EE @ EE_T_K
    np.testing.assert_allclose(point[0], [0.5, -0.1, 0.3], atol=1e-15)
    np.testing.assert_allclose(point[0], O_T_K[:3, 3], atol=1e-15)
    np.testing.assert_allclose(rotation[0], O_T_K[:3, :3], atol=1e-15)
    # the identity EE_T_K (every robot's default): K is the EE frame, exactly
    C.k_frame(wire[0], np.eye(4).reshape(1, 16), point, rotation)
    np.testing.assert_array_equal(point[0], O_T_EE[:3, 3])
    np.testing.assert_array_equal(rotation[0], O_T_EE[:3, :3])


def test_between_lower_and_upper_a_contact_above_upper_a_collision():
    b = CollisionBehavior(1)
    b.configure(0, payload(10.0, 30.0, HUGE, HUGE))
    over, out = sense(b, [[0.0, 12.0, -31.0, 0.0, 9.9, 0.0, 0.0]])
    np.testing.assert_array_equal(out["joint"][0], [0, 1, 1, 0, 0, 0, 0])
    np.testing.assert_array_equal(out["joint_over"][0], [0, 0, 1, 0, 0, 0, 0])
    assert over == 1 and not out["cartesian"].any() and not out["cartesian_over"].any()
    b.configure(0, payload(HUGE, HUGE, 5.0, 20.0))
    over, out = sense(b, [[0.0, 0.0, -25.0, 6.0, 0.0, 4.9, 0.0]])
    np.testing.assert_array_equal(out["cartesian"][0], [0, 0, 1, 1, 0, 0])
    np.testing.assert_array_equal(out["cartesian_over"][0], [0, 0, 1, 0, 0, 0])
    assert over == 1 and not out["joint"].any() and not out["joint_over"].any()
    np.testing.assert_array_equal(out["wrench"][0], [0.0, 0.0, -25.0, 6.0, 0.0, 4.9])


def test_at_a_threshold_is_not_above_it():
    """Strictly above: an estimate equal to its lower (upper) threshold is no contact
    (collision); the next value up is."""
    b = CollisionBehavior(2)
    for i in range(2):
        b.configure(i, payload(10.0, 30.0, 10.0, 30.0))
    at = [[10.0, -30.0, 0.0, 0.0, 0.0, 0.0, 0.0], [0.0] * 6 + [30.0]]
    over, out = sense(b, at)
    assert over == 0 and not out["joint"][0, 2:].any()
    np.testing.assert_array_equal(out["joint"][0, :2], [0, 1])  # 30 is above the lower 10
    np.testing.assert_array_equal(out["cartesian"][0, :2], [0, 1])  # the wrench: the same
    assert not out["joint_over"].any() and not out["cartesian_over"].any()
    past = [[10.0001, -30.0001, 0.0, 0.0, 0.0, 0.0, 0.0], [0.0] * 7]
    over, out = sense(b, past)
    np.testing.assert_array_equal(out["joint"][0, :2], [1, 1])
    np.testing.assert_array_equal(out["joint_over"][0, :2], [0, 1])
    np.testing.assert_array_equal(out["cartesian_over"][0, :2], [0, 1])
    assert over == 1


def test_the_acceleration_phase_uses_its_own_thresholds():
    """fci/contact/collision.py: in motion with some |ddq_d| above ACCELERATION_PHASE, the
    acceleration phase's thresholds; otherwise (out of motion, at the bound, NaN) nominal."""
    b = CollisionBehavior(5)
    for i in range(5):
        b.configure(i, payload(10.0, 30.0, HUGE, HUGE, nominal_scale=0.5))
    tau = np.full((5, 7), 20.0)
    tau[:, :6] = 0.0  # no wrench
    ddq_d = np.zeros((5, 7))
    ddq_d[1, 2] = -2 * ACCELERATION_PHASE
    ddq_d[2, 2] = 2 * ACCELERATION_PHASE
    ddq_d[3, 2] = ACCELERATION_PHASE  # at the bound: not above it
    ddq_d[4, 2] = np.nan
    in_motion = [True, True, False, True, True]
    over, out = sense(b, tau, ddq_d, in_motion)
    np.testing.assert_array_equal(out["accelerating"], [0, 1, 0, 0, 0])
    # nominal: upper 15 Nm, crossed; acceleration: upper 30 Nm, not
    np.testing.assert_array_equal(out["joint_over"][:, 6], [1, 0, 1, 1, 1])
    assert over == 4


def test_a_nan_estimate_crosses_nothing():
    b = CollisionBehavior(1)
    tau = np.zeros((1, 7))
    tau[0, 3] = np.nan
    over, out = sense(b, tau)
    assert over == 0 and not out["joint"].any() and not out["joint_over"].any()
    assert np.isnan(out["tau"][0, 3])


def test_the_defaults_are_libfrankas_set_default_behavior():
    b = CollisionBehavior(1)
    tau = np.zeros((1, 7))
    tau[0, 6] = DEFAULT_TORQUE_THRESHOLDS[6] + 0.5  # 12.5 Nm on joint 7: over its 12
    over, out = sense(b, tau)
    assert over == 1 and out["joint_over"][0, 6] == 1.0 and out["joint"][0, 6] == 1.0


@pytest.mark.parametrize("bad", ["accelerating", "joint_over"])
def test_outputs_of_the_wrong_kind_are_refused_by_name(bad):
    b = CollisionBehavior(1)
    n = 1
    jacobian = np.zeros((n, 6, 7))
    out = [np.zeros((n, s)) for s in (7, 6, 6, 7, 6, 7, 6)]
    flags = np.zeros(n, np.uint8)
    if bad == "accelerating":
        flags = np.zeros(n, np.float64)
    else:
        out[5] = np.zeros((n, 6))
    with pytest.raises(ValueError, match=bad):
        C.sense(
            np.zeros((n, 7)), np.zeros((n, 7)), np.zeros((n, 7)), np.zeros((n, 7)), jacobian,
            np.eye(3)[None].copy(), np.zeros((n, 7)), np.zeros(n, bool), b.thresholds,
            contact.ALPHA, 0.0, DECIMALS, ACCELERATION_PHASE, *out, flags,
        )  # fmt: skip


def _plan_arrays():
    """The arrays and constants of a one-arm controller's sensing plan, as a list."""
    from franka_sim_gym.fci.config import ControllerConfig
    from franka_sim_gym.fci.controller import FciController
    from franka_sim_gym.sim.arm import ArmPhysics

    return list(FciController(ArmPhysics(1), ControllerConfig()).contact.plan_arrays())


def _read_only(a):
    a = a.copy()
    a.flags.writeable = False
    return a


@pytest.mark.parametrize(
    ("index", "bad", "error", "text"),
    [
        (0, lambda a: a[0], ValueError, "qM"),
        (1, lambda a: np.where(np.arange(49) == 3, 10**6, a), ValueError, r"block\[3\]"),
        (1, lambda a: a[:48], ValueError, "block"),
        (4, lambda a: np.zeros((1, 6)), ValueError, "payload"),
        (6, _read_only, ValueError, "dq_prev"),
        (7, lambda a: np.zeros((1, 7, 6)), ValueError, "mass"),
        (29, lambda a: np.zeros(1), ValueError, "accelerating"),
        (30, lambda a: a[:4], TypeError, "constants"),
        (30, lambda a: (*a[:4], 0.0), ValueError, "cycle: 0"),
    ],
)
def test_the_sensing_plan_refuses_bad_arrays_by_name(index, bad, error, text):
    arrays = _plan_arrays()
    arrays[index] = bad(arrays[index] if arrays[index] is not None else np.zeros((1, 7)))
    with pytest.raises(error, match=text):
        C.Sensing(*arrays)


def test_the_sensing_plan_refuses_a_bad_cycle_by_name():
    plan = C.Sensing(*_plan_arrays())
    with pytest.raises(ValueError, match="in_motion"):
        plan.run(np.zeros(2, bool), None)
    with pytest.raises(ValueError, match="load"):
        plan.run(np.zeros(1, bool), np.zeros((1, 6)))
    with pytest.raises(TypeError, match="run"):
        plan.run(np.zeros(1, bool))
    assert plan.run(np.zeros(1, bool), None) == 0  # and it still runs
    with pytest.raises(ValueError, match="robots: 1 is not one of the 1"):
        plan.reset(np.array([1]))
    with pytest.raises(ValueError, match="robots: expected"):
        plan.reset(np.zeros(1, np.int32))


def test_a_reset_restarts_the_estimate_at_the_state_the_arm_is_at():
    from franka_sim_gym.fci.config import ControllerConfig
    from franka_sim_gym.fci.controller import FciController
    from franka_sim_gym.sim.arm import ArmPhysics

    physics = ArmPhysics(2)
    ctrl = FciController(physics, ControllerConfig())
    sensing, est = ctrl.contact, ctrl.contact.estimator
    for _ in range(20):  # a push: joint velocities, an estimate off zero
        physics.step(physics.q + 0.05, None)
        ctrl.writer.write_measured(physics)
        sensing.sense(ctrl.modes.in_motion, None)
    assert np.abs(est.tau_ext).max() > 1e-3 and np.abs(physics.dq).max() > 0.1
    before = est.tau_ext[1].copy(), est.dq_prev[1].copy()
    physics.reset_arms([0], physics.q[:1] + 0.1)  # a teleport: robot 0 at rest elsewhere
    sensing.reset([0])
    assert est.tau_ext[0].tolist() == [0.0] * 7
    assert est.dq_prev[0].tolist() == physics.dq[0].tolist() == [0.0] * 7  # no jump
    np.testing.assert_array_equal(est.tau_ext[1], before[0])  # the other robot untouched
    np.testing.assert_array_equal(est.dq_prev[1], before[1])
