"""The Cartesian generators' rules in C (fci/_cartesian_rules.c) and their IK
(sim/_ik.c) against their numpy references: each kernel on random and worst-case
inputs (bit for bit where the reference is elementwise, to rounding and with the same
verdicts where it reduces), and whole controllers streaming Cartesian poses and twists
(lost cycles, a violation) with the kernels and through the reference paths."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from franka_sim_gym import native
from franka_sim_gym.fci import frames
from franka_sim_gym.fci.cartesian_reference import columns
from franka_sim_gym.fci.limits import cartesian as rules
from franka_sim_gym.fci.tables import DELTA_T
from franka_sim_gym.fci.wire import ROBOT_COMMAND_DTYPE, MoveMotionGeneratorMode
from franka_sim_gym.sim import kinematics
from franka_sim_gym.sim.arm import ArmPhysics
from franka_sim_gym.sim.kinematics import ArmKinematics, rotation_exp
from franka_sim_gym.sim.world import HOME_Q
from tests.fci_helpers import IMP, make_controller

K = native.load("fci._cartesian_rules")
IK = native.load("sim._ik")
if K is None or IK is None:  # not built (or FRANKA_SIM_GYM_NATIVE=0): the references alone
    pytest.skip("the Cartesian kernels are not built or turned off", allow_module_level=True)

H = DELTA_T
CP = MoveMotionGeneratorMode.kCartesianPosition
CV = MoveMotionGeneratorMode.kCartesianVelocity


def _poses(rng, n: int, angle: float) -> tuple[np.ndarray, np.ndarray]:
    """(n, 4, 4) previous poses and commanded ones turned by up to ``angle`` [rad] and
    moved by up to a millimetre."""
    T_prev = np.tile(np.eye(4), (n, 1, 1))
    T_prev[:, :3, :3] = rotation_exp(rng.normal(size=(n, 3)))
    T_prev[:, :3, 3] = rng.normal(size=(n, 3)) * 0.3
    T_c = T_prev.copy()
    axes = rng.normal(size=(n, 3))
    axes *= (rng.uniform(0, angle, n) / np.linalg.norm(axes, axis=1))[:, None]
    T_c[:, :3, :3] = T_prev[:, :3, :3] @ rotation_exp(axes)
    T_c[:, :3, 3] += rng.normal(size=(n, 3)) * 1e-3
    return T_c, T_prev


def _limits(table_scale: float = 1.0) -> np.ndarray:
    from franka_sim_gym.fci.tables import robot_table

    return rules._quiet_limits(robot_table("fr3"), table_scale)


def _joint(rng, n: int) -> tuple[np.ndarray, np.ndarray]:
    """A solution q (n, 7) and a joint history (n, 3, 7) [q, dq, ddq] one step behind."""
    joint = np.empty((n, 3, 7))
    joint[:, 0] = HOME_Q + rng.normal(size=(n, 7)) * 0.1
    joint[:, 1] = rng.normal(size=(n, 7)) * 0.1
    joint[:, 2] = rng.normal(size=(n, 7)) * 0.5
    q = joint[:, 0] + joint[:, 1] * H + rng.normal(size=(n, 7)) * 1e-9
    return q, joint


def _reference_pose(T_c, T_prev, history, q, joint, limits):
    """pose_derivatives, joint_side and _quiet as the numpy path runs them."""
    n = len(T_c)
    stack, diff = np.empty((n, 3, 6)), np.empty((n, 3, 7))
    rules.pose_derivatives(T_c, T_prev, history, 1, out=stack)
    rules.joint_side(q, joint[:, 0], joint[:, 1], joint[:, 2], 1, out=diff)
    quiet = _reference_quiet(stack, diff, limits)
    return stack, diff, quiet


def _reference_quiet(stack, diff, limits) -> bool:
    n = len(stack)
    values = np.empty((n, 20))
    x = stack.reshape(n, 6, 3)
    values[:, :6] = np.einsum("nkj,nkj->nk", x, x)
    values[:, 6:] = np.abs(diff[:, 1:].reshape(n, 14))
    return bool((values <= limits).all())


# -- pose_step -------------------------------------------------------------------------------


@pytest.mark.parametrize("n", [1, 2, 16])
@pytest.mark.parametrize("angle", [0.0, 1e-13, 1e-9, 1e-3, 0.05, 1.4])
def test_pose_step_is_the_reference(n: int, angle: float):
    """Translations and the joint side bit for bit; the rotation (a trace and a norm, two
    reductions, then atan2) to rounding; the screen's verdict the reference's."""
    rng = np.random.default_rng(int(angle * 1e4) + n)
    limits = _limits()
    for _ in range(20):
        T_c, T_prev = _poses(rng, n, angle)
        if angle == 0.0:
            T_c[:, :3, :3] = T_prev[:, :3, :3]  # a pure translation: no turn at all
        history = rng.normal(size=(n, 2, 6)) * 0.01
        q, joint = _joint(rng, n)
        stack, diff = np.full((n, 3, 6), np.nan), np.full((n, 3, 7), np.nan)
        quiet = K.pose_step(T_c, T_prev, history, stack, q, joint, diff, H, limits)
        ref_stack, ref_diff, ref_quiet = _reference_pose(T_c, T_prev, history, q, joint, limits)
        assert quiet in (0, 1)
        np.testing.assert_array_equal(stack[:, :, :3], ref_stack[:, :, :3])
        np.testing.assert_array_equal(diff, ref_diff)
        # a few ulps of omega, divided by dt once more by each difference (and its own)
        omega = np.abs(ref_stack[:, 0, 3:]).max()
        for order in range(3):
            ulps = 8 * np.finfo(float).eps * (omega / H**order + np.abs(ref_stack[:, order]).max())
            np.testing.assert_allclose(
                stack[:, order, 3:], ref_stack[:, order, 3:], rtol=0, atol=ulps
            )
        if angle == 0.0:  # no reduction rounds anything: the rotation's bits too
            np.testing.assert_array_equal(stack, ref_stack)
        assert bool(quiet) == ref_quiet


def test_pose_step_screen_trips_on_each_limit_and_on_nan():
    """Each of the 20 screened values just over its limit (and NaN) is not quiet; just
    under (beyond the reductions' margin) is, as the reference's _quiet. (Within the
    margin the kernel says "not quiet" and the reference's rows decide.)"""
    rng = np.random.default_rng(7)
    limits = _limits()
    n = 1
    T_c, T_prev = _poses(rng, n, 1e-4)
    q, joint = _joint(rng, n)
    history = np.zeros((n, 2, 6))
    stack, diff = np.empty((n, 3, 6)), np.empty((n, 3, 7))
    assert K.pose_step(T_c, T_prev, history, stack, q, joint, diff, H, limits) in (0, 1)
    for k in range(20):
        for factor, expected in ((1.0 + 1e-14, False), (1.0 + 1e-9, False), (1.0 - 1e-9, True)):
            lim = np.full(20, 1e300)
            if k < 6:  # a squared norm: scale the limit to the value
                row, half = divmod(k, 2)
                x = stack[0, row, 3 * half : 3 * half + 3]
                lim[k] = np.dot(x, x) / factor
            else:
                lim[k] = abs(diff[0, 1 + (k - 6) // 7, (k - 6) % 7]) / factor
            got = K.pose_step(T_c, T_prev, history, stack, q, joint, diff, H, lim)
            assert bool(got) == expected == _reference_quiet(stack, diff, lim), (k, factor)
    nan_history = history.copy()
    nan_history[0, 1, 4] = np.nan
    assert K.pose_step(T_c, T_prev, nan_history, stack, q, joint, diff, H, limits) == 0


@pytest.mark.parametrize("angle", [np.pi / 2 + 1e-3, 2.0, np.pi - 1e-7, np.pi])
def test_pose_step_leaves_rotations_past_a_right_angle_to_the_reference(angle: float):
    """At or past pi / 2 in a cycle (near pi: the symmetric-part branch), or NaN, the
    kernel writes nothing and says so (-1); the caller runs the reference."""
    rng = np.random.default_rng(3)
    n = 4
    T_c, T_prev = _poses(rng, n, 1e-3)
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    T_c[2, :3, :3] = T_prev[2, :3, :3] @ rotation_exp(axis * angle)
    q, joint = _joint(rng, n)
    history = np.zeros((n, 2, 6))
    stack, diff = np.full((n, 3, 6), 7.0), np.full((n, 3, 7), 7.0)
    assert K.pose_step(T_c, T_prev, history, stack, q, joint, diff, H, _limits()) == -1
    assert (stack == 7.0).all() and (diff == 7.0).all()
    T_c[2] = T_prev[2]
    T_c[1, 0, 0] = np.nan
    assert K.pose_step(T_c, T_prev, history, stack, q, joint, diff, H, _limits()) == -1


# -- twist_step ------------------------------------------------------------------------------


@pytest.mark.parametrize("n", [1, 16])
def test_twist_step_is_the_reference_bit_for_bit(n: int):
    rng = np.random.default_rng(n)
    limits = _limits(0.5)
    for _ in range(30):
        twist = rng.normal(size=(n, 6)) * 0.5
        twist_prev = twist - rng.normal(size=(n, 6)) * 1e-3
        dtwist_prev = rng.normal(size=(n, 6)) * rng.choice([0.1, 3.0])
        q, joint = _joint(rng, n)
        stack, diff = np.empty((n, 3, 6)), np.empty((n, 3, 7))
        quiet = K.twist_step(twist, twist_prev, dtwist_prev, stack, q, joint, diff, H, limits)
        ref = np.empty((n, 3, 6))
        ref[:, 0] = twist
        ref[:, 1] = (twist - twist_prev) / DELTA_T
        ref[:, 2] = (ref[:, 1] - dtwist_prev) / DELTA_T
        ref_diff = np.empty((n, 3, 7))
        rules.joint_side(q, joint[:, 0], joint[:, 1], joint[:, 2], 1, out=ref_diff)
        np.testing.assert_array_equal(stack, ref)
        np.testing.assert_array_equal(diff, ref_diff)
        assert quiet == _reference_quiet(ref, ref_diff, limits)


# -- the wire pose's quick test ----------------------------------------------------------------


def _wire_poses(rng, n: int) -> np.ndarray:
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = rotation_exp(rng.normal(size=(n, 3)))
    T[:, :3, 3] = rng.normal(size=(n, 3))
    return frames.to_wire(T).copy()


@pytest.mark.parametrize("n", [1, 16])
def test_homogeneous_quick_gives_the_reference_verdicts(n: int):
    """Valid poses, rotation blocks scaled to the quick band's edges and the exact
    band's, a wrong bottom row, NaN and inf: is_homogeneous_wire says the same with the
    kernel's quick test and with numpy's."""
    rng = np.random.default_rng(11)
    tol = 1e-5
    scales = [1.0, 1 + 0.5 * tol - 1e-9, 1 + 0.5 * tol + 1e-9, 1 - tol, 1 + tol + 1e-9, 0.5]
    for trial in range(60):
        values = _wire_poses(rng, n)
        i = trial % n
        kind = trial % 9
        if kind < len(scales):
            values[i, [0, 1, 2, 4, 5, 6, 8, 9, 10]] *= scales[kind]
        elif kind == 6:
            values[i, 3] = 1e-300
        elif kind == 7:
            values[i, 13] = np.nan
        else:
            values[i, 15] = np.inf
        lo, hi = frames._QUICK_BAND
        quick = K.homogeneous_quick(values, lo, hi)
        assert quick == frames._quick_test_numpy(values, lo, hi), (kind, scales)
        exact = frames.is_homogeneous(frames.from_wire(values), tol)
        if quick:
            assert exact.all()
    # a structured field (strided records), as the controller passes commands["O_T_EE_c"]
    commands = np.zeros(n, dtype=ROBOT_COMMAND_DTYPE)
    commands["O_T_EE_c"] = _wire_poses(rng, n)
    assert K.homogeneous_quick(commands["O_T_EE_c"], *frames._QUICK_BAND)
    assert frames.is_homogeneous_wire(commands["O_T_EE_c"]) is None


# -- the IK ----------------------------------------------------------------------------------


def _kinematics(n: int, hand: bool = False):
    physics = ArmPhysics(n_arms=n, hand=hand)
    fast = ArmKinematics(physics.model, physics.layout, kernel=True)
    reference = ArmKinematics(physics.model, physics.layout, kernel=False)
    assert fast.native_solve is not None and reference.native_solve is None
    return fast, reference


def _assert_same_solution(a, b, atol: float) -> None:
    np.testing.assert_array_equal(a.converged, b.converged)
    np.testing.assert_allclose(a.q, b.q, rtol=0, atol=atol)
    np.testing.assert_allclose(a.position_error, b.position_error, rtol=0, atol=atol)
    np.testing.assert_allclose(a.rotation_error, b.rotation_error, rtol=0, atol=atol)


@pytest.mark.parametrize("n", [1, 16])
@pytest.mark.parametrize("with_tool", [False, True])
def test_ik_kernel_solves_as_the_reference(n: int, with_tool: bool):
    """Tracked targets (converged), far ones (capped steps), unreachable ones (unconverged
    after every iteration), held elbows and a subset of arms: the same verdicts, the
    same solutions to rounding."""
    fast, reference = _kinematics(n)
    rng = np.random.default_rng(n + 10 * with_tool)
    tool = None
    if with_tool:
        tool = np.tile(np.eye(4), (n, 1, 1))
        tool[:, :3, 3] = [0.0, 0.01, 0.1034]
        tool[:, :3, :3] = rotation_exp(np.tile([0.0, 0.0, -np.pi / 4], (n, 1)))
    q0 = np.tile(HOME_Q, (n, 1)) + rng.normal(size=(n, 7)) * 0.05
    seen = set()
    for trial in range(48):
        kind = trial % 6
        step = {0: 1e-3, 1: 1e-2, 2: 0.3, 3: 1e-3, 4: 1e-3, 5: 1e-3}[kind]
        target = reference.forward(q0 + rng.normal(size=(n, 7)) * step, tool)
        elbow = rows = None
        if kind == 2:
            target[n // 2, :3, 3] += [1.5, 0.0, 0.0]  # out of reach
        if kind in (3, 5):
            elbow = np.where(rng.random(n) < 0.5, q0[:, 2] + 0.01, np.nan)
        if kind in (4, 5):  # a subset of arms (5: some held elbows outside it)
            rows = rng.random(n) < 0.6
            rows[0] = False
        a = fast.solve(target, q0, tool, elbow, rows)
        b = reference.solve(target, q0, tool, elbow, rows)
        _assert_same_solution(a, b, 1e-11 if b.converged.all() else 1e-9)
        seen.add((kind, bool(b.converged.all())))
        if kind != 2 and b.converged.all():
            q0 = b.q
    assert (2, False) in seen and (0, True) in seen  # unconverged and converged both ran


def test_ik_kernel_keeps_forward_and_the_cache_right():
    """The kernel's solve leaves MjData's rows at its last iterate, not the evaluation
    buffers: forward and jacobian afterwards, and a solve from a new start, still agree
    with the reference."""
    fast, reference = _kinematics(3)
    q = np.tile(HOME_Q, (3, 1))
    target = reference.forward(q + 0.02)
    a = fast.solve(target, q)
    np.testing.assert_allclose(fast.forward(a.q), reference.forward(a.q), atol=1e-15)
    np.testing.assert_array_equal(fast.forward(q), reference.forward(q))
    np.testing.assert_array_equal(fast.jacobian(q), reference.jacobian(q))
    b, c = fast.solve(target, q), reference.solve(target, q)  # rows at q: cache hit
    _assert_same_solution(b, c, 1e-12)
    tool = np.tile(np.eye(4), (3, 1, 1))
    tool[:, 2, 3] = 0.2
    b, c = (
        fast.solve(reference.forward(q, tool), q, tool),
        reference.solve(reference.forward(q, tool), q, tool),
    )  # same q, another frame: the rows are re-evaluated
    _assert_same_solution(b, c, 1e-12)
    assert b.converged.all() and b.position_error.max() < 1e-12


def test_kernels_refuse_bad_shapes():
    n = 2
    fast, _ = _kinematics(n)
    q = np.tile(HOME_Q, (n, 1))
    solver = fast.native_solve
    args = [q, np.empty((n, 7)), fast.forward(q + 0.01), None, None, None, False, solver]
    assert IK.ik_solve(*args) is None and solver[8].all()  # (converged)
    bad = {
        0: ("q_init", q.astype(np.float32)),
        1: ("q", np.zeros((n, 6))),
        2: ("target", np.zeros((n, 3, 4))),
        3: ("F_T_EE", np.zeros((n, 4))),
        4: ("elbow", np.zeros(n + 1)),
        5: ("active", np.ones(n + 1, dtype=bool)),
    }
    for k, (name, value) in bad.items():
        broken = list(args)
        broken[k] = value
        with pytest.raises(ValueError, match=f"^{name}: "):
            IK.ik_solve(*broken)
    broken = list(args)
    broken[5] = np.ones(n)  # a float mask
    with pytest.raises(ValueError, match="active: expected a bool array"):
        IK.ik_solve(*broken)
    solver_bad = {
        0: ("cached_q", np.zeros((n, 6))),
        3: ("site_mat", np.zeros((n, 9))),
        7: ("errors", np.zeros(n)),
        8: ("converged", np.zeros(n)),
        12: ("max_iterations", -1),
        13: ("kinematics: expected a tuple", (1, 2)),
    }
    for k, (message, value) in solver_bad.items():
        broken = list(args)
        broken[7] = solver[:k] + (value,) + solver[k + 1 :]
        with pytest.raises(ValueError, match=message):
            IK.ik_solve(*broken)
    broken = list(args)
    broken[7] = solver[:13] + ((0, 1, 2),) + solver[14:]
    with pytest.raises(ValueError, match="kinematics: a null address"):
        IK.ik_solve(*broken)
    broken[7] = solver[:5]
    with pytest.raises(ValueError, match="native_solve's tuple"):
        IK.ik_solve(*broken)
    with pytest.raises(TypeError, match=r"ik_solve\(\) takes 8 arguments \(7 given\)"):
        IK.ik_solve(*args[:-1])
    q = np.zeros((n, 7))
    T = np.tile(np.eye(4), (n, 1, 1))
    good = [T, T.copy(), np.zeros((n, 2, 6)), np.zeros((n, 3, 6)), q, np.zeros((n, 3, 7))]
    good += [np.zeros((n, 3, 7)), H, _limits()]
    assert K.pose_step(*good) == 1
    for k, bad in ((2, np.zeros((n, 3, 6))), (3, np.zeros((n + 1, 3, 6))), (8, np.zeros(14))):
        broken = list(good)
        broken[k] = bad
        with pytest.raises(ValueError):
            K.pose_step(*broken)
    readonly = np.zeros((n, 3, 6))
    readonly.setflags(write=False)
    with pytest.raises(ValueError, match="stack"):
        K.pose_step(*good[:3], readonly, *good[4:])
    with pytest.raises(ValueError):
        K.twist_step(np.zeros((n, 5)), *[np.zeros((n, 6))] * 2, *good[3:])
    with pytest.raises(ValueError):
        K.homogeneous_quick(np.zeros((n, 15)), 0.9, 1.1)


def test_plain_cycle_refuses_bad_arguments():
    ctrl = make_controller(2)
    gen = ctrl.engine.cartesian
    kin, h = gen.kinematics, gen.reference
    args = [
        False, gen.T_cmd, gen.twist_cmd, h.buffer, gen._T_twist[0], gen._twist_stack,
        gen._joint, H, _limits(), None, kin.native_solve, kin.rows_valid,
    ]  # fmt: skip
    cases = {
        2: ("twist", np.zeros((2, 5))),
        3: ("history", np.zeros((2, 91))),
        4: ("T_tw", np.zeros((2, 4, 3))),
        6: ("joint", np.zeros((2, 3, 7))),
        8: ("limits", np.zeros(14)),
        10: ("ik: expected ArmKinematics.native_solve's tuple", (1, 2)),
    }
    for k, (name, value) in cases.items():
        broken = list(args)
        broken[k] = value
        with pytest.raises(ValueError, match=f"^{name}"):
            K.plain_cycle(*broken)
    with pytest.raises(TypeError, match=r"plain_cycle\(\) takes 12 arguments"):
        K.plain_cycle(*args[:-1])
    assert K.history_columns() == columns()


def test_without_mj_kinematics_from_c_the_numpy_loop_solves(monkeypatch):
    """Where MuJoCo's mj_kinematics cannot be had from C, the IK kernel and the plain
    cycle are off, and the numpy loop solves as the reference does."""
    monkeypatch.setattr(kinematics, "mj_kinematics_addresses", lambda model, data: None)
    physics = ArmPhysics(n_arms=1)
    kin = ArmKinematics(physics.model, physics.layout, kernel=True)
    assert kin.native_solve is None
    assert make_controller(1).engine.cartesian._plain is None
    q = np.tile(HOME_Q, (1, 1))
    target = kin.forward(q + 0.01)
    a = kin.solve(target, q)
    b = ArmKinematics(physics.model, physics.layout, kernel=False).solve(target, q)
    assert a.converged.all()
    np.testing.assert_array_equal(a.q, b.q)


# -- whole controllers ---------------------------------------------------------------------------


def _reference_paths(ctrl, monkeypatch) -> None:
    """Send ``ctrl`` down the numpy reference paths (as FRANKA_SIM_GYM_NATIVE=0 would)."""
    cartesian = ctrl.engine.cartesian
    cartesian._kernel = cartesian._plain = None
    cartesian.kinematics._native_solve = None
    monkeypatch.setattr(frames, "_quick_test", frames._quick_test_numpy)


class _CountingPlainCycle:
    """The plain-cycle kernel, counting what each call returned (True: it recorded)."""

    def __init__(self, kernel) -> None:
        self.kernel, self.results = kernel, []

    def plain_cycle(self, *args):
        recorded = self.kernel.plain_cycle(*args)
        self.results.append(recorded)
        return recorded


def _stream(
    generator, n: int, reference: bool, monkeypatch, enforce: bool, plain=True, keep=None
):
    """Stream a Cartesian motion to n robots with rotation, lost cycles, a late datagram
    and a violation on robot 0 at cycle 300; returns the published states per cycle, the
    events and the logged violations. ``plain``: False runs the general cycle only;
    ``keep``: a list that receives the Cartesian generators (their plain-cycle kernel
    counting what each call returned)."""
    monkeypatch.undo()
    ctrl = make_controller(n, enforce_motion_limits=enforce)
    if reference:
        _reference_paths(ctrl, monkeypatch)
    cartesian = ctrl.engine.cartesian
    if not plain:
        cartesian._plain = None
    if keep is not None:
        if cartesian._plain is not None:
            cartesian._plain = _CountingPlainCycle(cartesian._plain)
        keep.append(cartesian)
    for i in range(n):
        ctrl.move(i, int(IMP), int(generator))
    for _ in range(2):
        ctrl.step()
    rng = np.random.default_rng(5)
    T0 = frames.from_wire(ctrl.states["O_T_EE_d"].astype(np.float64)).copy()
    commands = np.zeros(n, dtype=ROBOT_COMMAND_DTYPE)
    states, events = [], []
    lost = rng.random((500, n)) < 0.05
    lost[:3] = False
    held = None
    for k in range(500):
        t = k * DELTA_T
        s = 0.5 * (1 - np.cos(2 * np.pi * t / 0.5))
        if generator == CP:
            T = T0.copy()
            T[:, 0, 3] += 0.01 * s
            T[:, 2, 3] -= 0.005 * s
            turn = np.tile([0.02, -0.03, 0.05], (n, 1)) * s
            T[:, :3, :3] = T0[:, :3, :3] @ rotation_exp(turn)
            if k >= 300:
                T[0, 1, 3] += 0.002  # a 2 m/s step in y: 19 (and more) on robot 0
            commands["O_T_EE_c"] = frames.to_wire(T)
        else:
            twist = np.zeros((n, 6))
            twist[:, 0] = 0.02 * np.sin(2 * np.pi * t / 0.5)
            twist[:, 5] = 0.05 * np.sin(2 * np.pi * t / 0.5)
            if k >= 300:
                twist[0, 1] += 0.05  # a twist step: 20 on robot 0
            commands["O_dP_EE_c"] = twist
        commands["message_id"] = ctrl.states["message_id"]
        mask = ~lost[k]
        if k == 150 and held is not None:  # a late datagram of the lost cycle before
            ctrl.receive(*held)
        ctrl.receive(commands.copy(), mask.copy())
        if lost[k].any():
            held = (commands.copy(), lost[k].copy())
        events += [(k, e.robot, e.kind, e.status) for e in ctrl.step()]
        states.append(ctrl.states.copy())
    seen = ctrl.violations.seen.copy()
    return states, events, seen


@pytest.mark.parametrize("generator", [CP, CV])
@pytest.mark.parametrize("n", [1, 3])
@pytest.mark.parametrize("enforce", [False, True])
def test_a_controller_with_the_kernels_publishes_what_the_reference_does(
    generator, n, enforce, monkeypatch, caplog
):
    with caplog.at_level(logging.WARNING, logger="franka_sim_gym.fci"):
        fast = _stream(generator, n, False, monkeypatch, enforce)
        fast_log = [r.getMessage() for r in caplog.records]
        caplog.clear()
        slow = _stream(generator, n, True, monkeypatch, enforce)
        slow_log = [r.getMessage() for r in caplog.records]
    monkeypatch.undo()
    (states_a, events_a, seen_a), (states_b, events_b, seen_b) = fast, slow
    assert events_a == events_b
    np.testing.assert_array_equal(seen_a, seen_b)
    assert seen_a[0].any()  # the violation was seen
    assert _names(fast_log) == _names(slow_log) and fast_log
    for a, b in zip(states_a, states_b, strict=True):
        for name in a.dtype.names:
            x, y = a[name], b[name]
            if x.dtype.kind == "f":
                np.testing.assert_allclose(x, y, rtol=1e-5, atol=1e-6, err_msg=name)
            else:
                np.testing.assert_array_equal(x, y, err_msg=name)


@pytest.mark.parametrize("generator", [CP, CV])
@pytest.mark.parametrize("n", [1, 3])
@pytest.mark.parametrize("enforce", [False, True])
def test_the_plain_cycle_is_the_general_cycle_bit_for_bit(generator, n, enforce, monkeypatch):
    """plain_cycle (one kernel call for the whole cycle) against _cycle's kernels, on a
    stream with lost cycles, a late datagram and a violation: every published state, event
    and logged violation and the final history, bit for bit. The plain cycle recorded
    most cycles and declined others to the general path (the violation's)."""
    kept = []
    states, events, seen = _stream(generator, n, False, monkeypatch, enforce, keep=kept)
    general = _stream(generator, n, False, monkeypatch, enforce, plain=False, keep=kept)
    monkeypatch.undo()
    fast, slow = kept
    assert slow._plain is None
    assert events == general[1]
    np.testing.assert_array_equal(seen, general[2])
    assert seen[0].any()  # the violation was seen
    for a, b in zip(states, general[0], strict=True):
        assert a.tobytes() == b.tobytes()
    assert fast.reference.buffer.tobytes() == slow.reference.buffer.tobytes()
    calls = fast._plain.results
    assert calls.count(True) > 200  # of 500 cycles, some lost (and the abort: none after)
    assert calls.count(False) >= 1  # declined: the violation's cycle


def _names(messages: list[str]) -> list[str]:
    """The log lines without their numbers (the error names and rows stay)."""
    return [" ".join(w for w in m.split() if not any(ch.isdigit() for ch in w)) for m in messages]


def _history(n: int, rng):
    """A Cartesian history with random values (a live controller's layout)."""
    h = make_controller(n).engine.cartesian.reference
    h.buffer[...] = rng.normal(0, 1, h.buffer.shape)
    return h


@pytest.mark.parametrize("n", [1, 16])
def test_record_kernels_copy_and_report_as_cartesian_record_does(n: int):
    """record_pose / record_twist against _record's plain path (every robot recorded a
    command that arrived): the copies, and the reported twist and its rate, bit for bit."""
    rng = np.random.default_rng(n)
    T_c, _ = _poses(rng, n, 0.05)
    stack = rng.normal(0, 1, (n, 3, 6))
    twist = rng.normal(0, 1, (n, 6))
    for kind in ("pose", "twist"):
        fast, ref = _history(n, rng), None
        ref_buffer = fast.buffer.copy()
        if kind == "pose":
            K.record_pose(
                T_c,
                stack,
                fast.T,
                fast.history,
                fast.acceleration_frozen,
                fast.reported,
                fast.dreported,
            )
        else:
            K.record_twist(
                T_c,
                twist,
                stack,
                fast.T,
                fast.twist,
                fast.dtwist,
                fast.dtwist_frozen,
                fast.reported,
                fast.dreported,
            )
        ref = make_controller(n).engine.cartesian.reference
        ref.buffer[...] = ref_buffer
        # fci/cartesian.py _record and _record_reported, plain path.
        ref.T[...] = T_c
        if kind == "pose":
            ref.history[...] = stack[:, :2]
            ref.acceleration_frozen[...] = ref.history[:, 1]
            spatial = np.empty((n, 6))
            spatial[:, :3] = ref.v
            np.einsum("nij,nj->ni", ref.T[:, :3, :3], ref.omega, out=spatial[:, 3:])
        else:
            ref.twist[...] = twist
            ref.dtwist[...] = stack[:, 1]
            ref.dtwist_frozen[...] = ref.dtwist
            spatial = ref.twist.copy()
        np.subtract(spatial, ref.reported, out=ref.dreported)
        ref.dreported /= DELTA_T
        ref.reported[...] = spatial
        assert np.array_equal(fast.buffer.view(np.uint64), ref.buffer.view(np.uint64)), kind


@pytest.mark.parametrize("n", [1, 16])
@pytest.mark.parametrize("omega", [0.0, 1e-6, 0.3, 1000.0])
def test_twist_target_kernel_moves_the_target_as_the_reference(n: int, omega: float):
    """fci/cartesian.py _twist_target's numpy: the translation bit for bit; the rotation
    exp(omega dt) @ R to rounding (3x3 products: numpy's go through BLAS), and exactly R
    where a robot's twist does not turn. omega (rad/s): none, the Rodrigues series' range
    (below 1e-8 rad a cycle), a hand's turn, a whole radian a cycle."""
    rng = np.random.default_rng(3 + n)
    T, _ = _poses(rng, n, 0.1)
    twist = rng.normal(0, 0.3, (n, 6))
    twist[:, 3:] = rng.normal(0, omega, (n, 3))
    still = np.arange(n) % 3 == 1  # some robots do not turn
    twist[still, 3:] = 0.0
    if n > 1:
        twist[-1, 3:] = (0.0, 1e-300, 0.0)  # barely turning is turning
    out = np.full((n, 4, 4), np.nan)
    assert K.twist_target(T, twist, out) is None
    ref = T.copy()
    ref[:, :3, 3] += twist[:, :3] * DELTA_T
    ref[:, :3, :3] = rotation_exp(twist[:, 3:] * DELTA_T) @ T[:, :3, :3]
    assert np.array_equal(out[:, :, 3].view(np.uint64), ref[:, :, 3].view(np.uint64))
    assert np.array_equal(out[:, 3].view(np.uint64), ref[:, 3].view(np.uint64))
    np.testing.assert_allclose(out[:, :3, :3], ref[:, :3, :3], rtol=0, atol=1e-15)
    kept = still | ~np.any(twist[:, 3:], axis=1)
    assert np.array_equal(out[kept, :3, :3].view(np.uint64), T[kept, :3, :3].view(np.uint64))
