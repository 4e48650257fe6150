"""envs/_client_filters.c, the C replacements of the client's filter rules
(envs/client_kernel.py), held to the numpy rules they replace: the joint, torque and twist
limiters bit for bit, the Cartesian low-pass, the pose limiter and the reference pose to
rounding, and libfranka's own values for the pose rules.

Joint states sweep the ranges and head into the stops with the band binding; twist
states sweep the corners of the norm limiter: at rest (no jerk, no acceleration),
inside the velocity ball, at its surface and outside it (the square root's negative
argument), and jerks far past the limit, on both halves of the twist. End to end,
random-action episodes are the same bit for bit with and without the kernels (the pose
interface to rounding).
"""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.envs import client_filters as cf
from franka_sim_gym.envs.client_kernel import NUMPY_RULES as NP
from franka_sim_gym.envs.commands import CLIENT_KERNEL as C
from franka_sim_gym.envs.commands import LIMITER_MARGIN
from franka_sim_gym.fci.frames import from_wire, is_homogeneous, to_wire
from franka_sim_gym.fci.tables import FR3, JOINT_VELOCITY_LIMIT_TOLERANCE
from franka_sim_gym.fci.wire import ROBOT_STATE_DTYPE
from franka_sim_gym.sim.rotations import rotation_exp
from tests.cartesian_filter_helpers import LIBFRANKA_LOWPASS_CASES as LOWPASS_CASES
from tests.cartesian_filter_helpers import LIBFRANKA_POSE_LIMITER_CASES as POSE_LIMITER_CASES
from tests.cartesian_filter_helpers import LIMITS as LIBFRANKA_LIMITS
from tests.native_helpers import joint_and_client_kernels_off, joint_samples, rollout, same_bits

pytestmark = pytest.mark.skipif(C is None, reason="envs/_client_filters.c not built / off")

A_MAX, J_MAX = FR3.ddq_max - LIMITER_MARGIN["ddq"], FR3.dddq_max - LIMITER_MARGIN["dddq"]
#: The conservative Cartesian limits the env uses by default (commands.CARTESIAN_LIMITS).
TWIST_LIMITS = (0.5, 1.0, 200.0, 1.0, 2.0, 400.0)
#: How far the pose rules' C replacements may be from numpy and from libfranka: rounding
#: (their acos, atan2, sin, cos are libm's, as Eigen's are; numpy's SIMD ones may differ
#: by an ulp; their 3x3 products sum in another order than BLAS's).
POSE_ATOL = 1e-13


def _joint_state(rng, n: int, near_band: bool) -> np.ndarray:
    """A wire state (float32 fields, packed records) with q_d, dq_d, ddq_d: anywhere, or
    heading into a stop with the band binding."""
    s = np.zeros(n, dtype=ROBOT_STATE_DTYPE)
    q = joint_samples(rng, n)
    dq = rng.normal(0, 1.0, (n, 7))
    if near_band:
        q = FR3.q_upper - rng.random((n, 7)) * 0.05
        dq = rng.random((n, 7)) * 1.0
    s["q_d"] = q
    s["dq_d"] = dq
    s["ddq_d"] = rng.normal(0, 6.0, (n, 7))
    s["tau_J_d"] = rng.normal(0, 20.0, (n, 7))
    return s


def _band(state) -> tuple[np.ndarray, np.ndarray]:
    shift = JOINT_VELOCITY_LIMIT_TOLERANCE + LIMITER_MARGIN["dq"]  # as the env's client
    band = FR3.velocity_envelope_halves(np.asarray(state["q_d"], dtype=np.float64), shift)
    return band[:, :7], -band[:, 7:]


def _both(name: str, *args, shape) -> tuple[np.ndarray, np.ndarray]:
    """Rule ``name`` in C and in numpy on the same arguments, out given to each."""
    fast = getattr(C, name)(*args, np.full(shape, np.nan))
    reference = getattr(NP, name)(*args, np.full(shape, np.nan))
    return fast, reference


@pytest.mark.parametrize("columns", [6, 7])
@pytest.mark.parametrize("n", [1, 16])
def test_the_lowpass_filter_is_the_numpy_rule_bit_for_bit(columns: int, n: int):
    """Against the wire state's float32 references and float64 ones, at several cutoffs."""
    rng = np.random.default_rng(columns + n)
    for trial in range(100):
        state = _joint_state(rng, n, near_band=False)
        ref = state["q_d"] if columns == 7 else rng.normal(size=(n, 6))
        x = rng.normal(size=(n, columns)) * (trial % 5 != 0)
        gain = cf.lowpass_gain(float(rng.choice([1.0, 10.0, 100.0, 999.0])))
        fast, reference = _both("lowpass_core", x, ref, gain, shape=(n, columns))
        assert same_bits(fast, reference), trial


@pytest.mark.parametrize("positions", [True, False])
@pytest.mark.parametrize("n", [1, 16])
def test_the_joint_limiters_are_the_numpy_rules_bit_for_bit(positions: bool, n: int):
    rng = np.random.default_rng(11 + n + positions)
    for trial in range(300):
        state = _joint_state(rng, n, near_band=trial % 3 == 0)
        upper, lower = _band(state)
        history = (state["dq_d"], state["ddq_d"], upper, lower, A_MAX, J_MAX)
        if positions:
            q_c = state["q_d"] + rng.uniform(-0.1, 0.1, (n, 7)) * (trial % 5 != 0)
            fast, reference = _both(
                "limit_positions_core", q_c, state["q_d"], *history, shape=(n, 7)
            )
        else:
            dq_c = rng.uniform(-1, 1, (n, 7)) * (trial % 5 != 0)
            fast, reference = _both("limit_velocities_core", dq_c, *history, shape=(n, 7))
        assert same_bits(fast, reference), (trial, np.max(np.abs(fast - reference)))


@pytest.mark.parametrize("n", [1, 16])
def test_the_torque_limiter_is_the_numpy_rule_bit_for_bit(n: int):
    """Torque commands within the rate bound, far past it either way, and at rest."""
    rng = np.random.default_rng(21 + n)
    d_max = FR3.dtau_max - LIMITER_MARGIN["dtau"]
    for trial in range(300):
        state = _joint_state(rng, n, near_band=False)
        state["tau_J_d"] *= trial % 4 != 0
        tau_c = state["tau_J_d"] + rng.uniform(-2, 2, (n, 7)) * (trial % 5 != 0)
        fast, reference = _both("limit_torques_core", tau_c, state["tau_J_d"], d_max, shape=(n, 7))
        assert same_bits(fast, reference), (trial, np.max(np.abs(fast - reference)))
        steps = np.abs(fast - state["tau_J_d"]) / d_max / 1e-3
        assert np.all(steps <= 1.0 + 1e-9)  # the rate bound holds


def _twist_state(rng, n: int, regime: str) -> np.ndarray:
    s = np.zeros(n, dtype=ROBOT_STATE_DTYPE)
    if regime == "rest":
        return s
    direction = rng.normal(size=(n, 6))
    speed = {"inside": 0.5, "surface": 1.0, "outside": 1.3}[regime]
    # Around the default ("conservative") limits' balls (0.5 m/s, 1.0 rad/s), per half.
    twist = direction.reshape(n, 2, 3)
    twist /= np.linalg.norm(twist, axis=-1, keepdims=True)
    twist *= speed * np.array([0.5, 1.0])[None, :, None]
    s["O_dP_EE_c"] = twist.reshape(n, 6)
    s["O_ddP_EE_c"] = rng.normal(0, 1.0, (n, 6))
    return s


@pytest.mark.parametrize("n", [1, 16])
@pytest.mark.parametrize("regime", ["rest", "inside", "surface", "outside"])
def test_the_twist_limiter_is_the_numpy_rule_bit_for_bit(n: int, regime: str):
    rng = np.random.default_rng(n + len(regime))
    for trial in range(200):
        state = _twist_state(rng, n, regime)
        twist_c = rng.uniform(-1, 1, (n, 6)) * (0.0 if trial % 5 == 0 else 1.0)
        args = (twist_c, state["O_dP_EE_c"], state["O_ddP_EE_c"], *TWIST_LIMITS)
        fast, reference = _both("limit_twist_core", *args, shape=(n, 6))
        assert same_bits(fast, reference), (trial, np.max(np.abs(fast - reference)))


def test_an_acceleration_that_rounds_to_nothing_leaves_the_twist_as_it_was():
    """At rest with a last acceleration of ~1e-13: the jerk takes it back to |a| <= eps,
    where libfranka returns v_last itself (its kNormEps branch)."""
    rng = np.random.default_rng(2)
    for _ in range(50):
        state = np.zeros(16, dtype=ROBOT_STATE_DTYPE)
        state["O_ddP_EE_c"] = rng.normal(0, 1e-13, (16, 6))
        args = (np.zeros((16, 6)), state["O_dP_EE_c"], state["O_ddP_EE_c"], *TWIST_LIMITS)
        fast, reference = _both("limit_twist_core", *args, shape=(16, 6))
        assert same_bits(fast, reference)
        assert not fast.any()


def test_the_kernel_names_a_bad_argument():
    six = np.zeros((2, 6))
    with pytest.raises(ValueError, match="^twist_last: axis 0 has length 1, expected 2"):
        C.limit_twist_core(six, six[:1], six, *TWIST_LIMITS, np.zeros((2, 6)))
    with pytest.raises(ValueError, match="^out: expected a 2-D float64 array"):
        C.limit_twist_core(six, six, six, *TWIST_LIMITS, np.zeros((2, 6)).astype(int))
    seven = np.zeros((2, 7))
    with pytest.raises(ValueError, match="^a_max: axis 0 has length 6, expected 7"):
        C.limit_velocities_core(seven, seven, seven, seven, seven, np.ones(6), np.ones(7), seven)
    with pytest.raises(TypeError, match=r"limit_torques_core\(\) takes 4 arguments \(3 given\)"):
        C.limit_torques_core(seven, seven, 1.0)
    T, wire = np.tile(np.eye(4), (2, 1, 1)), np.zeros((2, 16))
    with pytest.raises(ValueError, match="^dtwist_last: axis 1 has length 5, expected 6"):
        C.limit_pose_core(T, T, six, six[:, :5], *TWIST_LIMITS, np.zeros((2, 4, 4)))
    with pytest.raises(ValueError, match="^out: expected a 3-D float64 array"):
        C.reference_pose(wire, np.zeros((2, 16)))


@pytest.mark.parametrize(
    "interface", ["joint_position", "joint_velocity", "cartesian_velocity", "torque"]
)
def test_an_episode_is_the_same_with_and_without_the_kernels(interface, monkeypatch):
    """End to end, random actions through libfranka's limiters (reflexes included): the
    client's kernels change no bit of what a policy sees."""
    fast = rollout(interface, "limit_rate")
    joint_and_client_kernels_off(monkeypatch)
    reference = rollout(interface, "limit_rate")
    assert len(fast) == len(reference)
    for a, b in zip(fast, reference, strict=True):
        assert same_bits(a, b)


def _pose_state(rng, n: int, regime: str) -> np.ndarray:
    """A wire state at poses of every orientation (all four branches of Shepperd's method),
    with the last twist and its rate in a regime of the norm limiter."""
    s = _twist_state(rng, n, regime)
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = rotation_exp(rng.normal(size=(n, 3)) * rng.uniform(0.0, 3.1, (n, 1)))
    T[:, :3, 3] = rng.normal(0, 0.4, (n, 3))
    s["O_T_EE_c"] = to_wire(T)
    return s


def _moved(rng, state: np.ndarray, step: float) -> np.ndarray:
    """The state with O_T_EE_c moved by up to ``step`` (m, rad): the motion under way."""
    s = state.copy()
    n = len(s)
    T = from_wire(s["O_T_EE_c"])
    T[:, :3, 3] += rng.normal(0, step, (n, 3))
    T[:, :3, :3] = rotation_exp(rng.normal(0, step, (n, 3))) @ T[:, :3, :3]
    s["O_T_EE_c"] = to_wire(T)
    return s


@pytest.mark.parametrize("n", [1, 16])
@pytest.mark.parametrize("regime", ["rest", "inside", "surface", "outside"])
def test_the_pose_rules_are_the_numpy_rules_to_rounding(n: int, regime: str):
    """The reference pose read off the state, the Cartesian low-pass toward it and the pose
    limiter, at poses of every orientation and motions under way."""
    rng = np.random.default_rng(7 * n + len(regime))
    gain = cf.lowpass_gain(100.0)
    for trial in range(150):
        state = _moved(rng, _pose_state(rng, n, regime), 1e-3 if trial % 2 else 0.05)
        fast_ref, ref = _both("reference_pose", state["O_T_EE_c"], shape=(n, 4, 4))
        np.testing.assert_allclose(fast_ref, ref, rtol=0, atol=POSE_ATOL, err_msg=trial)
        target = ref.copy()
        target[:, :3, 3] += rng.normal(0, 0.05, (n, 3))
        target[:, :3, :3] = rotation_exp(rng.normal(0, 0.2, (n, 3))) @ ref[:, :3, :3]
        fast, lowpassed = _both("cartesian_lowpass_core", target, ref, gain, shape=(n, 4, 4))
        np.testing.assert_allclose(fast, lowpassed, rtol=0, atol=POSE_ATOL, err_msg=trial)
        args = (lowpassed, ref, state["O_dP_EE_c"], state["O_ddP_EE_c"], *TWIST_LIMITS)
        fast, reference = _both("limit_pose_core", *args, shape=(n, 4, 4))
        np.testing.assert_allclose(fast, reference, rtol=0, atol=POSE_ATOL, err_msg=trial)
        assert is_homogeneous(fast).all()


@pytest.mark.parametrize("offset", [0.5, 2e-3, 5e-4, 1e-6, 1e-9])
def test_the_c_pose_limiter_differentiates_a_near_half_turn_as_numpy(offset: float):
    """A command a half turn minus ``offset`` from the last pose: the rotation's logarithm
    takes its axis from the quaternion within 1e-3 of pi, from the skew part farther."""
    rng = np.random.default_rng(3)
    n = 8
    T_last = np.tile(np.eye(4), (n, 1, 1))
    T_last[:, :3, :3] = rotation_exp(rng.normal(size=(n, 3)))
    axes = rng.normal(size=(n, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    T_c = T_last.copy()
    T_c[:, :3, :3] = rotation_exp(axes * (np.pi - offset)) @ T_last[:, :3, :3]
    zero = np.zeros((n, 6))
    fast, reference = _both(
        "limit_pose_core", T_c, T_last, zero, zero, *TWIST_LIMITS, shape=(n, 4, 4)
    )
    np.testing.assert_allclose(fast, reference, rtol=0, atol=POSE_ATOL)
    step = np.einsum("nij,nkj->nik", fast[:, :3, :3], T_last[:, :3, :3])  # R R_last^T
    assert (np.einsum("nii->n", step) < 3.0).all()  # it turned


@pytest.mark.parametrize(("T_c", "T_last", "twist", "dtwist", "expected"), POSE_LIMITER_CASES)
def test_the_c_pose_limiter_limits_as_libfranka_does(T_c, T_last, twist, dtwist, expected):
    """libfranka 0.21.2's limitRate values, computed with Eigen."""
    args = (T_c[None], T_last[None], np.array([twist], float), np.array([dtwist], float))
    out = C.limit_pose_core(*args, *LIBFRANKA_LIMITS, np.zeros((1, 4, 4)))
    np.testing.assert_allclose(out[0], expected, rtol=0, atol=POSE_ATOL)


@pytest.mark.parametrize(("T_c", "T_ref", "cutoff", "expected"), LOWPASS_CASES)
def test_the_c_cartesian_lowpass_filters_as_libfranka_does(T_c, T_ref, cutoff, expected):
    """libfranka 0.21.2's cartesianLowpassFilter values."""
    gain = cf.lowpass_gain(cutoff)
    out = C.cartesian_lowpass_core(T_c[None], T_ref[None], gain, np.zeros((1, 4, 4)))
    np.testing.assert_allclose(out[0], expected, rtol=0, atol=POSE_ATOL)


@pytest.mark.parametrize("action_filter", ["lowpass", "limit_rate"])
def test_a_pose_episode_with_the_kernel_ends_as_the_reference_does(action_filter, monkeypatch):
    """End to end, 60 steps of random pose actions: the same rewards, cycles and errors
    step by step, and the end effector where the reference puts it.

    Not the same bits: the kernel's rounding differs from numpy's, and the limiter's
    loop through the float32 state amplifies that (one float32 ulp of O_T_EE_c is 6e-8 m,
    60 um/s once differentiated over 1 ms). The arm's null space is not commanded at all,
    so its joints wander apart by up to ~1e-3 rad over the episode while the end effector
    agrees to ~3e-7 m.
    """
    fast = rollout("cartesian_pose", action_filter, steps=60)
    joint_and_client_kernels_off(monkeypatch)
    reference = rollout("cartesian_pose", action_filter, steps=60)
    assert len(fast) == len(reference)
    np.testing.assert_array_equal(fast[2::2], reference[2::2])  # reward, cycles, errors
    ee = slice(14, 17)  # observation: q, dq, then O_T_EE's position
    for a, b in zip(fast[1::2], reference[1::2], strict=True):
        np.testing.assert_allclose(a[ee], b[ee], rtol=0, atol=1e-5)
    if action_filter == "lowpass":  # a naive stream: every episode ends in a reflex
        assert all(info[2] > 0 for info in fast[2::2])
    else:
        assert not any(info[2] for info in fast[2::2])  # the limiter keeps it clean
