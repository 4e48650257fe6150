"""The contact estimate's C replacements (fci/_contact.c) against their numpy reference.

``filter_residual`` is elementwise: bit for bit. The wrench's products and 6 x 6 solve
are numpy's BLAS and LAPACK on one side and a plain elimination on the other: they agree
to rounding (times J J^T's condition), so the published (rounded) wrench is the same
unless a value lies that close to a rounding boundary; the rounded results are compared
exactly where no value does, and the unrounded ones to 1e-9 of the wrench's size.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from franka_sim_gym.fci import contact
from franka_sim_gym.fci.collision import (
    ACCELERATION_PHASE,
    THRESHOLD_NAMES,
    CollisionBehavior,
    accelerating,
)
from franka_sim_gym.fci.statuses import SetterStatus
from franka_sim_gym.fci.tables import FR3
from franka_sim_gym.fci.wire import ROBOT_STATE_DTYPE, MoveMotionGeneratorMode
from franka_sim_gym.sim.arm import ArmPhysics
from tests.fci_helpers import LoopClient, make_controller
from tests.sim.test_scene import OVER_THE_TABLE

pytestmark = pytest.mark.skipif(contact.KERNEL is None, reason="fci._contact not built")

C, NP = contact.KERNEL, contact.NUMPY_RULES
DECIMALS = contact.RESOLUTION_DECIMALS
OK = SetterStatus.kSuccess


def _same(a: np.ndarray, b: np.ndarray) -> None:
    np.testing.assert_array_equal(a, b)
    assert np.array_equal(np.signbit(a), np.signbit(b))


def _arm_jacobians(n: int, seed: int) -> np.ndarray:
    """(n, 6, 7) Jacobians of the FR3 at random configurations, at points near the flange."""
    rng = np.random.default_rng(seed)
    physics = ArmPhysics(n_arms=n)
    q = rng.uniform(FR3.q_lower, FR3.q_upper, (n, 7))
    if n > 2:
        q[0] = [0.0, 0.0, 0.0, -0.1458, 0.0, 0.54092, 0.0]  # near the stretched singularity
    physics.reset_arms(np.arange(n), q)
    point = physics.flange_pose()[0] + rng.normal(scale=0.05, size=(n, 3))
    return physics.jacobian(point)


@pytest.mark.parametrize("seed", range(10))
def test_filter_residual_matches_numpy_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 33))
    state = rng.normal(scale=rng.choice([1e-6, 0.01, 5.0]), size=(n, 7))
    state[rng.random((n, 7)) < 0.05] = 0.0
    tau_ext = {"c": state.copy(), "np": state.copy()}
    for _ in range(5):
        tau_J, m_ddq, bias = (rng.normal(scale=10.0, size=(n, 7)) for _ in range(3))
        m_ddq[rng.random((n, 7)) < 0.1] = -bias[rng.random((n, 7)) < 0.1][:1].sum()
        out_c, out_np = np.empty((n, 7)), np.empty((n, 7))
        C.filter_residual(tau_ext["c"], tau_J, m_ddq, bias, contact.ALPHA, DECIMALS, out_c)
        NP.filter_residual(tau_ext["np"], tau_J, m_ddq, bias, contact.ALPHA, DECIMALS, out_np)
        _same(tau_ext["c"], tau_ext["np"])
        _same(out_c, out_np)


@pytest.mark.parametrize("seed", range(6))
def test_wrench_and_its_frame_match_numpy(seed):
    rng = np.random.default_rng(seed)
    n = 16
    J = _arm_jacobians(n, seed)
    tau = rng.normal(scale=rng.choice([1e-5, 0.05, 10.0]), size=(n, 7))
    tau[0] = 0.0  # rest: zero, never a negative zero
    damping = contact.WRENCH_DAMPING
    # the solve itself (15 decimals: no rounding at these magnitudes), to rounding
    # amplified by J J^T's condition (up to ~1e6 at these poses, one near a singularity)
    raw_c = C.wrench_from_torque(J, tau, damping, 15, np.empty((n, 6)))
    raw_np = NP.wrench_from_torque(J, tau, damping, 15, np.empty((n, 6)))
    scale = np.abs(raw_np).max(axis=1, keepdims=True) + 1e-12
    np.testing.assert_array_less(np.abs(raw_c - raw_np) / scale, 1e-9)
    # published: the same values, away from a rounding boundary
    scaled = raw_np * 10.0**DECIMALS
    clear = np.abs(scaled - np.floor(scaled) - 0.5) > 1e-3
    got = C.wrench_from_torque(J, tau, damping, DECIMALS, np.empty((n, 6)))
    want = NP.wrench_from_torque(J, tau, damping, DECIMALS, np.empty((n, 6)))
    _same(got[clear], want[clear])
    assert not np.signbit(got[got == 0]).any() and not np.signbit(want[want == 0]).any()
    # in K's axes
    R = np.linalg.qr(rng.normal(size=(n, 3, 3)))[0]
    got_k = C.in_frame(want, R, DECIMALS, np.empty((n, 6)))
    want_k = NP.in_frame(want, R, DECIMALS, np.empty((n, 6)))
    scaled = np.abs((want.reshape(-1, 2, 3) @ R).reshape(-1, 6)) * 10.0**DECIMALS
    clear = np.abs(scaled - np.floor(scaled) - 0.5) > 1e-3
    _same(got_k[clear], want_k[clear])
    assert not np.signbit(got_k[got_k == 0]).any()


@pytest.mark.parametrize("seed", range(6))
def test_k_frame_matches_numpy(seed):
    """K's origin and axes: to rounding (numpy's product is BLAS's), and exactly while
    EE_T_K is the identity (every robot's default: K is the EE frame)."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 17))
    poses = []
    for _ in range(2):  # O_T_EE and EE_T_K: rotations and offsets, wire order
        T = np.zeros((n, 4, 4))
        T[:, :3, :3] = np.linalg.qr(rng.normal(size=(n, 3, 3)))[0]
        T[:, :3, 3] = rng.normal(scale=0.5, size=(n, 3))
        T[:, 3, 3] = 1.0
        poses.append(T.transpose(0, 2, 1).reshape(n, 16).copy())
    poses[1][0] = np.eye(4).reshape(16)
    got = np.empty((n, 3)), np.empty((n, 3, 3))
    want = np.empty((n, 3)), np.empty((n, 3, 3))
    C.k_frame(*poses, *got)
    NP.k_frame(*poses, *want)
    for a, b in zip(got, want, strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-15)
        np.testing.assert_array_equal(a[0], b[0])  # identity K
    np.testing.assert_array_equal(got[0][0], poses[0][0, 12:15])
    np.testing.assert_array_equal(got[1][0], poses[0][0].reshape(4, 4).T[:3, :3])


def _sense_inputs(seed: int, n: int = 16) -> dict:
    """Random inputs of one sensing step: estimates on both sides of random thresholds,
    some robots accelerating, one with a NaN torque reading."""
    rng = np.random.default_rng(seed)
    scale = rng.choice([0.5, 5.0, 30.0])
    behavior = CollisionBehavior(n)
    behavior.thresholds[...] = rng.uniform(0.0, 2 * scale, behavior.thresholds.shape)
    behavior.thresholds[rng.random(n) < 0.4] *= 100.0  # robots far from theirs
    behavior.thresholds[0] = 0.0  # every comparison trips at any non-zero value
    ddq_d = rng.normal(scale=0.6, size=(n, 7))
    ddq_d[1] = [0.5] * 7  # at the bound: nominal
    tau_ext, tau_J, m_ddq, bias = (rng.normal(scale=scale, size=(n, 7)) for _ in range(4))
    tau_J[2, 3] = np.nan
    # robot 3 at rest, estimate 0.0, thresholds 0.0: at a threshold is not above it
    tau_ext[3], tau_J[3] = 0.0, m_ddq[3] + bias[3]
    behavior.thresholds[3] = 0.0
    in_motion = rng.random(n) < 0.7
    in_motion[1] = True
    return {
        "tau_ext": tau_ext,
        "tau_J": tau_J,
        "m_ddq": m_ddq,
        "bias": bias,
        "jacobian": _arm_jacobians(n, seed),
        "rotation": np.linalg.qr(rng.normal(size=(n, 3, 3)))[0],
        "ddq_d": ddq_d,
        "in_motion": in_motion,
        "behavior": behavior,
    }


@pytest.mark.parametrize("seed", range(8))
def test_the_whole_sensing_step_matches_the_numpy_rules(seed):
    """fci/_contact.c sense against contact_sensing's numpy steps: the estimate (state
    and published) bit for bit, the wrenches to rounding (as above), and the flags and
    the count over an upper threshold exactly those CollisionBehavior.levels gives on
    the published values, in the phase collision.accelerating gives."""
    x = _sense_inputs(seed)
    n = len(x["tau_J"])
    b = x["behavior"]
    consts = (contact.ALPHA, contact.WRENCH_DAMPING, DECIMALS, ACCELERATION_PHASE)
    out = {k: np.full((n, size), -1.0) for k, size in
           (("tau", 7), ("wrench", 6), ("k", 6), ("joint", 7), ("cartesian", 6))}  # fmt: skip
    tau_ext = x["tau_ext"].copy()
    over = C.sense(
        tau_ext, x["tau_J"], x["m_ddq"], x["bias"], x["jacobian"], x["rotation"], x["ddq_d"],
        x["in_motion"], b.thresholds, *consts, *out.values(),
    )  # fmt: skip
    want_ext, want_tau = x["tau_ext"].copy(), np.empty((n, 7))
    NP.filter_residual(want_ext, x["tau_J"], x["m_ddq"], x["bias"], contact.ALPHA, DECIMALS,
                       want_tau)  # fmt: skip
    _same(tau_ext, want_ext)
    _same(out["tau"], want_tau)
    want_wrench = NP.wrench_from_torque(
        x["jacobian"], np.nan_to_num(want_tau), contact.WRENCH_DAMPING, DECIMALS, np.empty((n, 6))
    )
    finite = np.isfinite(want_tau).all(axis=1)
    np.testing.assert_allclose(out["wrench"][finite], want_wrench[finite], rtol=0, atol=1.01e-4)
    assert np.isnan(out["wrench"][~finite]).all() and (~finite).sum() == 1
    want_k = NP.in_frame(out["wrench"], x["rotation"], DECIMALS, np.empty((n, 6)))
    _same(out["k"], want_k)
    phase = accelerating(x["ddq_d"], x["in_motion"])
    assert 0 < phase.sum() < n
    levels = b.levels(out["tau"], out["wrench"], phase)
    np.testing.assert_array_equal(out["joint"], levels.joint_contact)
    np.testing.assert_array_equal(out["cartesian"], levels.cartesian_contact)
    crossed = levels.joint_over.any(axis=1) | levels.cartesian_over.any(axis=1)
    assert over == crossed.sum() and 0 < over < n
    assert out["joint"].any() and not out["joint"].all()
    assert out["joint"][2, 3] == 0.0  # a NaN estimate crosses nothing, as in numpy
    assert not out["joint"][3].any() and not out["cartesian"][3].any()
    assert not phase[1]  # |ddq_d| at the bound is not above it


def test_the_estimate_runs_the_same_on_both_paths(monkeypatch):
    """The public functions take the C rules where loaded and numpy where RULES says so."""
    J = _arm_jacobians(4, 9)
    tau = np.random.default_rng(9).normal(size=(4, 7))
    with_kernel = contact.wrench_from_torque(J, tau)
    monkeypatch.setattr(contact, "RULES", contact.NUMPY_RULES)
    np.testing.assert_allclose(contact.wrench_from_torque(J, tau), with_kernel, atol=1e-4)


def _descent_into_the_table() -> list[bytes]:
    """A Cartesian velocity motion down onto the table and back (5 cm/s, contact flags
    under 5 N lower thresholds, not enforced): every published state's bytes."""
    ctrl = make_controller(1)
    ctrl.reset([0], OVER_THE_TABLE[None])
    phases = ([5.0] * 7, [100.0] * 7) * 2 + ([5.0] * 6, [20.0] * 6) * 2
    values = dict(zip(THRESHOLD_NAMES, phases, strict=True))
    ctrl.set_collision_behavior(0, values)
    client = LoopClient(ctrl)
    client.start(MoveMotionGeneratorMode.kCartesianVelocity)
    seen = []
    for k in range(4400):
        v = 0.05 * 0.5 * (1 - math.cos(math.pi * min((k + 1) * 1e-3 / 0.5, 1.0)))
        client.send(O_dP_EE_c=[0.0, 0.0, v if k > 4100 else -v, 0.0, 0.0, 0.0])
        seen.append(ctrl.states.tobytes())
    return seen


def test_a_press_on_the_table_publishes_the_same_states_with_and_without_the_kernels(
    monkeypatch,
):
    """The controller's published states, bit for bit, with the contact rules' C text and
    with their numpy rules, through contact, the contact flags and the cartesian_collision
    flag."""
    with_kernels = _descent_into_the_table()
    monkeypatch.setattr(contact, "RULES", contact.NUMPY_RULES)
    with_numpy = _descent_into_the_table()
    last = np.frombuffer(with_numpy[-1], dtype=ROBOT_STATE_DTYPE)[0]
    pressed = [
        np.frombuffer(s, dtype=ROBOT_STATE_DTYPE)[0]["cartesian_contact"][2] for s in with_numpy
    ]
    assert any(pressed) and last["cartesian_collision"][2] == 1.0  # contact was reached
    assert with_kernels == with_numpy


def _sense_estimates(monkeypatch, thresholds: tuple) -> set:
    """Robot 1 of 2 configured with ``thresholds`` (then reset to the defaults halfway),
    estimates of growing size: checks that sense()'s flags (its numpy path) are the
    comparisons' flags; returns which (robot 1 in contact, robot 0 quiet) pairs were seen."""
    monkeypatch.setattr(contact, "RULES", contact.NUMPY_RULES)
    ctrl = make_controller(2)
    sensing, field = ctrl.contact, ctrl.contact.field
    values = dict(zip(THRESHOLD_NAMES, thresholds, strict=True))
    assert ctrl.set_collision_behavior(1, values) == OK
    rng = np.random.default_rng(5)
    nowhere = np.zeros(2, dtype=bool)
    seen = set()
    for k, scale in enumerate((0.3, 0.6, 1.0, 1.5, 2.5, 4.0, 8.0, 15.0, 30.0) * 2):
        if k == 9:
            sensing.reset([1])  # back to the defaults; the lowest bounds stay
        estimate = np.round(rng.normal(scale=scale, size=(2, 7)), 4)

        def filter(tau_J, m_ddq, bias, out, estimate=estimate):
            out[...] = estimate
            return out

        monkeypatch.setattr(sensing.estimator, "filter", filter)
        sensing.sense(nowhere, None)
        want = sensing.behavior.levels(
            field["tau_ext_hat_filtered"], field["O_F_ext_hat_K"], nowhere
        )
        np.testing.assert_array_equal(field["joint_contact"], want.joint_contact)
        np.testing.assert_array_equal(field["cartesian_contact"], want.cartesian_contact)
        quiet = not want.joint_contact[0].any() and not want.cartesian_contact[0].any()
        seen.add((bool(want.joint_contact[1].any() or want.cartesian_contact[1].any()), quiet))
    return seen


def test_skipping_the_comparisons_gives_the_levels_the_comparisons_give(monkeypatch):
    """ContactSensing.sense's numpy path skips the threshold comparisons while the estimate lies at
    or below every threshold any robot has had: the flags must be those the comparisons
    give, with a robot's torque (then force) thresholds configured below the defaults
    and later reset to them, estimates on both sides of every threshold."""
    torque = ([2.0] * 7, [40.0] * 7) * 2 + ([20.0] * 6, [50.0] * 6) * 2
    force = ([20.0] * 7, [40.0] * 7) * 2 + ([3.0] * 6, [50.0] * 6) * 2
    for thresholds in (torque, force):
        # robot 1 in contact below the defaults while robot 0 was not
        assert (True, True) in _sense_estimates(monkeypatch, thresholds)
