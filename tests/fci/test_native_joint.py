"""The robot's joint-side rules in C (fci/_joint_rules.c) against their numpy references,
bit for bit.

Each kernel fuses elementwise numpy arithmetic in the same order of operations, built
without fused multiply-adds, so its results must be the reference's very bits: the
velocity envelope, the mid-motion q_c check and the safety controller's screening row.
Inputs sweep the joint ranges past the stops and speeds past the limits, so both
verdicts are exercised.
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest

import franka_sim_gym.fci.engine as engine_module
import franka_sim_gym.fci.tables as tables_module
from franka_sim_gym import native
from franka_sim_gym.fci.tables import FER, FR3, JOINT_VELOCITY_LIMIT_TOLERANCE
from tests.fci_helpers import make_controller
from tests.native_helpers import joint_samples, same_bits

kernel = native.load("fci._joint_rules")
needs_kernel = pytest.mark.skipif(kernel is None, reason="fci/_joint_rules.c not built")


def test_kernels_are_built_where_a_compiler_is():
    """The install compiles the kernels (setup.py); a silent fallback to numpy would leave
    the speed the benchmarks record unmeasured."""
    if shutil.which("cc") is None and shutil.which("gcc") is None:
        pytest.skip("no C compiler on this machine")
    if not native.ENABLED:
        pytest.skip("FRANKA_SIM_GYM_NATIVE=0")
    assert all(native.loaded().values()), f"not built: {native.describe()}; pip install -e ."


def test_the_kernels_difference_over_the_controllers_cycle():
    """Each module carries the cycle it was built for; load() refuses another."""
    assert native.CYCLE == tables_module.DELTA_T
    for name in native.MODULES:
        module = native.load(name)
        if module is not None:
            assert module.DELTA_T == tables_module.DELTA_T


@needs_kernel
@pytest.mark.parametrize("n", [1, 16])
def test_envelope_kernel_is_the_numpy_envelope_bit_for_bit(n, monkeypatch):
    rng = np.random.default_rng(n)
    shifts = [JOINT_VELOCITY_LIMIT_TOLERANCE, -0.04, rng.random(14), rng.random((n, 14))]
    for _ in range(50):
        q = joint_samples(rng, n)
        for shift in shifts:
            fast = FR3.velocity_envelope_halves(q.copy(), shift)
            doubled = np.concatenate([q, q], axis=1)
            fast_doubled = FR3.velocity_envelope_halves(doubled, shift)
            with monkeypatch.context() as m:
                m.setattr(tables_module, "JOINT_KERNEL", None)
                reference = FR3.velocity_envelope_halves(q.copy(), shift)
            assert same_bits(fast, reference)
            assert same_bits(fast_doubled, reference)
            assert fast_doubled is doubled  # in place, as the reference


@needs_kernel
def test_envelope_kernel_is_exact_at_the_stops_and_the_offsets_edge(monkeypatch):
    """The clamps' edges: at a stop the distance is 0 (sqrt(0) under the offset), just
    inside and outside it, and where sqrt(2 a d) equals the offset."""
    two_a, bound, offset, _ = FR3._envelope_constants
    d_edge = offset[:7] ** 2 / two_a[:7]
    rows = [
        FR3.q_upper,
        FR3.q_lower,
        np.nextafter(FR3.q_upper, 0.0 * FR3.q_upper - 10),
        np.nextafter(FR3.q_upper, FR3.q_upper + 10),
        FR3.q_upper - d_edge,
        FR3.q_lower + d_edge,
    ]
    q = np.array(rows)
    fast = FR3.velocity_envelope_halves(q)
    monkeypatch.setattr(tables_module, "JOINT_KERNEL", None)
    assert same_bits(fast, FR3.velocity_envelope_halves(q))


@needs_kernel
def test_kernels_name_a_bad_argument_instead_of_reading_past_it():
    table = FR3.envelope_table
    with pytest.raises(ValueError, match="q: expected"):
        kernel.envelope(np.zeros((2, 5)), table, 0.0, np.zeros((2, 14)))
    with pytest.raises(ValueError, match="out: axis 0 has length 1, expected 2"):
        kernel.envelope(np.zeros((2, 7)), table, 0.0, np.zeros((1, 14)))
    with pytest.raises(ValueError, match="constants"):
        kernel.envelope(np.zeros((2, 7)), table[:3], 0.0, np.zeros((2, 14)))
    with pytest.raises(ValueError, match="q: expected a 2-D float64"):
        kernel.envelope(np.zeros((2, 7), dtype=np.float32), table, 0.0, np.zeros((2, 14)))
    with pytest.raises(ValueError, match="writable"):
        ro = np.zeros((2, 14))
        ro.setflags(write=False)
        kernel.envelope(np.zeros((2, 7)), table, 0.0, ro)
    with pytest.raises(ValueError, match="shift"):
        kernel.envelope(np.zeros((2, 7)), table, np.zeros(3), np.zeros((2, 14)))
    with pytest.raises(TypeError, match=r"envelope\(\) takes 4 arguments \(2 given\)"):
        kernel.envelope(np.zeros((2, 7)), table)


def _reference_motion(ctrl, rng, scale: float) -> np.ndarray:
    """Random reference (q, dq, ddq) and a q_c around it: ``scale`` sets how far the
    derivatives reach (0.01 inside the ranges passes, 3 trips rows)."""
    ref = ctrl.reference
    n = ctrl.n
    ref.q[...] = joint_samples(rng, n, past=-0.1 if scale < 0.1 else 0.05)
    ref.dq[...] = rng.normal(0.0, 1.5 * scale, (n, 7))
    ref.ddq[...] = rng.normal(0.0, 5.0 * scale, (n, 7))
    v = ref.dq + rng.normal(0.0, 0.005 * scale, (n, 7))
    return ref.q + v * 1e-3


@needs_kernel
@pytest.mark.parametrize("n", [1, 16])
def test_q_c_check_kernel_gives_the_reference_verdict_and_derivatives(n):
    ctrl = make_controller(n)
    eng = ctrl.engine
    rng = np.random.default_rng(7 + n)
    verdicts = set()
    for trial in range(400):
        q_c = _reference_motion(ctrl, rng, scale=[0.01, 0.3, 1.0, 3.0][trial % 4])
        eng._envelope_kernel = engine_module.JOINT_KERNEL
        fast = eng._positions_inside_limits(q_c)
        fast_rows = eng._stacked.copy()
        eng._stacked[...] = np.nan
        eng._envelope_kernel = None
        reference = eng._positions_inside_limits(q_c)
        assert fast is reference
        assert same_bits(fast_rows, eng._stacked)
        verdicts.add(fast)
    assert verdicts == {True, False}


@needs_kernel
@pytest.mark.parametrize("n", [1, 16])
def test_dq_c_check_kernel_gives_the_reference_verdict_and_derivatives(n):
    """velocities_inside against _velocities_inside_limits' numpy: the verdict, and the
    implied acceleration, jerk and next q_d, bit for bit."""
    ctrl = make_controller(n)
    eng = ctrl.engine
    rng = np.random.default_rng(11 + n)
    verdicts = set()
    outputs = (eng._velocity_ddq, eng._velocity_dddq, eng._velocity_q)
    for trial in range(400):
        q_c = _reference_motion(ctrl, rng, scale=[0.01, 0.3, 1.0, 3.0][trial % 4])
        dq_c = (q_c - ctrl.reference.q) / 1e-3
        eng._envelope_kernel = engine_module.JOINT_KERNEL
        fast = eng._velocities_inside_limits(dq_c)
        fast_out = [x.copy() for x in outputs]
        for x in outputs:
            x[...] = np.nan
        eng._envelope_kernel = None
        reference = eng._velocities_inside_limits(dq_c)
        assert fast is reference
        for a, b in zip(fast_out, outputs, strict=True):
            assert same_bits(a, b)
        verdicts.add(fast)
    assert verdicts == {True, False}
    ddq_max = ctrl.table.ddq_max
    args = [dq_c, *(np.zeros((n, 7)) for _ in range(6)), ddq_max, ddq_max]
    args += [ctrl.table.envelope_table, 0.0]
    for k, name in ((4, "ddq_out"), (7, "ddq_max")):
        broken = list(args)
        broken[k] = np.zeros(6)
        with pytest.raises(ValueError, match=name):
            kernel.velocities_inside(*broken)


@needs_kernel
@pytest.mark.parametrize("n", [1, 16])
def test_measured_screen_kernel_gives_the_reference_row_and_verdict(n):
    ctrl = make_controller(n)
    eng, physics, w = ctrl.engine, ctrl.physics, ctrl.writer
    rng = np.random.default_rng(3 + n)
    verdicts = set()
    for trial in range(300):
        calm = trial % 3 == 0  # inside the shortcut's bounds; the others trip some row
        q = joint_samples(rng, n, past=-0.3 if calm else 0.05)
        physics.data.qpos[physics.layout.qpos_adr] = q
        physics.data.qvel[physics.layout.dof_adr] = rng.normal(0, 0.1 if calm else 2.0, (n, 7))
        w.O_T_EE[:, 12:15] = rng.normal(0.4, 0.2, (n, 3))
        eng.ee_prev[...] = w.O_T_EE[:, 12:15] + rng.normal(0, 2e-4 if calm else 2e-3, (n, 3))
        fast = kernel.measured_inside(
            physics.dq, physics.q, w.O_T_EE, eng.ee_prev, eng._measured, eng._measured_bounds
        )
        fast_row = eng._measured.copy()
        x = eng._measured
        np.subtract(w.O_T_EE[:, 12:15], eng.ee_prev, out=x[:, 14:17])
        x[:, 14:17] *= 1.0 / 1e-3
        x[:, :7] = physics.dq
        x[:, 7:14] = physics.q
        np.negative(x[:, :17], out=x[:, 17:])
        reference = np.count_nonzero(x <= eng._measured_bounds) == x.size
        assert fast is bool(reference)
        assert same_bits(fast_row, x)
        verdicts.add(fast)
    assert verdicts == {True, False}


@needs_kernel
def test_the_fer_keeps_its_numpy_paths():
    """The FER's envelope is constant: no kernel table, the numpy paths decide."""
    assert FER.envelope_table is None
    ctrl = make_controller(1, robot="fer")
    assert ctrl.engine._envelope_kernel is None
