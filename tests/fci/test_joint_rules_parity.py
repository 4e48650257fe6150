"""The joint rules' C replacement (fci/limits/_joint.c) against their numpy reference.

``check_joint_position`` and ``check_joint_velocity`` run the kernel where the backend
switch loaded it (``joint.KERNEL``) and numpy where it is None. Both paths must return
the same errors and the same derivatives, bit for bit, on random batches near every
boundary: positions at and one ulp past the stops, velocities around the envelope,
accelerations and jerks around their limits, opening commands, per-robot and scalar
intervals, non-finite values, float32 wire fields and the FER's constant envelope.
"""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.fci.limits import joint
from franka_sim_gym.fci.tables import DELTA_T, FER, FR3

pytestmark = [
    pytest.mark.skipif(joint.KERNEL is None, reason="fci.limits._joint not built"),
    pytest.mark.filterwarnings("ignore::RuntimeWarning"),  # NaN and inf on purpose
]

TOL = 0.1


def _same(a: np.ndarray, b: np.ndarray) -> None:
    """Equal bit for bit: values, NaN where NaN, the sign of every zero."""
    a, b = np.asarray(a), np.asarray(b)
    assert a.dtype == b.dtype and a.shape == b.shape
    np.testing.assert_array_equal(a, b)
    assert np.array_equal(np.signbit(a), np.signbit(b))


def _batch(rng: np.random.Generator, n: int, table):
    """n robots near every boundary of ``table`` (see the module docstring)."""
    span = table.q_upper - table.q_lower
    q_prev = table.q_lower + span * rng.choice([0.0, 1e-4, 0.02, 0.5, 0.98, 1.0], (n, 7))
    q_prev += rng.normal(scale=1e-3, size=(n, 7)) * (rng.random((n, 7)) < 0.5)
    upper, lower = table.velocity_envelope(q_prev)
    dq_prev = rng.uniform(1.05 * lower, 1.05 * upper) * (rng.random((n, 1)) < 0.8)
    ddq_prev = rng.uniform(-11.0, 11.0, (n, 7)) * (rng.random((n, 1)) < 0.8)
    steps = rng.integers(1, 4, n)
    h = steps[:, None] * DELTA_T
    jerk = rng.uniform(-5500.0, 5500.0, (n, 7)) * (rng.random((n, 7)) < 0.3)
    ddq = ddq_prev + jerk * h
    dq = dq_prev + ddq * h
    jump = rng.choice([0.0, 0.0, 0.0, 0.05, 0.2, 1.0], (n, 1)) * rng.normal(size=(n, 7))
    q_c = q_prev + dq * h + jump * (rng.random((n, 7)) < 0.2)
    # at the stops exactly, and one ulp past them
    stop = rng.random((n, 7))
    edges = (table.q_lower, table.q_upper)
    q_c = np.where(stop < 0.03, edges[0], q_c)
    q_c = np.where((stop > 0.03) & (stop < 0.06), np.nextafter(edges[0], -np.inf), q_c)
    q_c = np.where((stop > 0.06) & (stop < 0.09), edges[1], q_c)
    q_c = np.where((stop > 0.09) & (stop < 0.12), np.nextafter(edges[1], np.inf), q_c)
    dq_c = dq + 10.0 * jump * (rng.random((n, 7)) < 0.2)
    dq_c = np.where(rng.random((n, 7)) < 0.05, upper, dq_c)  # on the envelope
    dq_c = np.where(rng.random((n, 7)) < 0.05, lower, dq_c)
    dq_c = np.where(rng.random((n, 7)) < 0.02, -0.0, dq_c)
    for x in (q_c, dq_c, q_prev, dq_prev):
        odd = rng.random((n, 7))
        x[odd < 0.01] = np.nan
        x[(odd > 0.01) & (odd < 0.02)] = np.inf
        x[(odd > 0.02) & (odd < 0.03)] = -np.inf
    first = rng.random(n) < 0.25
    start = q_c + rng.choice([0.0, 0.05, 0.3], (n, 1)) * rng.normal(size=(n, 7))
    return q_c, dq_c, q_prev, dq_prev, ddq_prev, first, start, steps


def _both(monkeypatch, module, rule, *args):
    """``rule(*args)`` with the kernel, then with numpy (``module.KERNEL`` None)."""
    with_kernel = rule(*args)
    with monkeypatch.context() as m:
        m.setattr(module, "KERNEL", None)
        with_numpy = rule(*args)
    return with_kernel, with_numpy


@pytest.mark.parametrize("table", [FR3, FER], ids=["fr3", "fer"])
@pytest.mark.parametrize("seed", range(40))
def test_joint_position_and_velocity_match_numpy_bit_for_bit(monkeypatch, seed, table):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 40))
    q_c, dq_c, q_prev, dq_prev, ddq_prev, first, start, steps = _batch(rng, n, table)
    if seed % 4 == 0:
        steps = 1  # one interval for every robot, as the generators pass it
    if seed % 3 == 0:
        first = np.zeros(n, dtype=bool)  # mid-motion: the all-or-none path
    if seed % 5 == 0:
        q_c = q_c.astype(np.float32)  # a wire field
    history = (q_prev, dq_prev, ddq_prev, first)
    got, want = _both(
        monkeypatch, joint, joint.check_joint_position, q_c, *history, start, steps, table, TOL
    )
    for a, b in zip(got, want, strict=True):
        _same(a, b)
    got, want = _both(
        monkeypatch, joint, joint.check_joint_velocity, dq_c, *history, start, steps, table, TOL
    )
    for a, b in zip(got, want, strict=True):
        _same(a, b)


def test_a_scalar_opening_flag_matches_numpy(monkeypatch):
    """The generators judge late datagrams with ``first=False`` (a scalar)."""
    rng = np.random.default_rng(7)
    q_c, dq_c, q_prev, dq_prev, ddq_prev, _, start, _ = _batch(rng, 12, FR3)
    for rule, command in ((joint.check_joint_position, q_c), (joint.check_joint_velocity, dq_c)):
        args = (command, q_prev, dq_prev, ddq_prev, False, start, 1, FR3, TOL)
        got, want = _both(monkeypatch, joint, rule, *args)
        for a, b in zip(got, want, strict=True):
            _same(a, b)


def test_the_kernel_refuses_wrong_shapes():
    constants, positional = joint.joint_constants(FR3)
    rows, out = np.empty(2, np.uint8), np.empty((2, 7))
    x = np.zeros((2, 7))
    with pytest.raises(ValueError, match="axis 1 has length 6"):
        joint.KERNEL.position_rows(
            x, np.zeros((2, 6)), x, x, None, 1e-3, constants, positional, TOL, 1e-3, rows, out, out
        )
    with pytest.raises(ValueError, match="uint8"):
        joint.KERNEL.velocity_rows(
            x, x, x, x, None, 1e-3, constants, positional, TOL, 1e-3, out, out
        )


def _reaching(value, target, derive):
    """The float nearest ``value`` whose ``derive`` is exactly ``target`` (searched over
    neighbouring floats)."""
    candidates = [value]
    up = down = value
    for _ in range(64):
        up, down = np.nextafter(up, np.inf), np.nextafter(down, -np.inf)
        candidates += [up, down]
    for x in candidates:
        if derive(x) == target:
            return x
    raise AssertionError("no float reaches the target")


def test_limits_reached_exactly_are_inside_on_both_paths(monkeypatch):
    """An acceleration of exactly ddq_max (jerk zero) is allowed: ``>``, not ``>=``."""
    h = DELTA_T
    home = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
    a_max = FR3.ddq_max[0]
    # joint velocity: dq_prev 0, ddq_prev a_max, dq_c with (dq_c - 0) / h == a_max
    dq_c = np.zeros((1, 7))
    dq_c[0, 0] = _reaching(a_max * h, a_max, lambda x: (x - 0.0) / h)
    ddq_prev = np.zeros((1, 7))
    ddq_prev[0, 0] = a_max
    args = (dq_c, home[None], np.zeros((1, 7)), ddq_prev, False, dq_c, 1, FR3, TOL)
    got, want = _both(monkeypatch, joint, joint.check_joint_velocity, *args)
    assert got.error[0] == want.error[0] == -1 and got.ddq[0, 0] == a_max
    # joint position: q_prev home at rest, dq_prev = dq (no acceleration change) ...
    q_c = home[None].copy()
    q_c[0, 0] = _reaching(home[0] + a_max * h * h, a_max, lambda x: ((x - home[0]) / h) / h)
    dq = (q_c - home) / h
    args = (q_c, home[None], np.zeros((1, 7)), dq / h, False, q_c, 1, FR3, TOL)
    got, want = _both(monkeypatch, joint, joint.check_joint_position, *args)
    assert got.error[0] == want.error[0] == -1 and got.ddq[0, 0] == a_max
