"""libfranka's isHomogeneousTransformation (error 31's gate on the 1 kHz path): its
verdict at the edge of the 1e-5 band, on bad entries, on rows and on columns, of wire
poses read row-major. (The arrival's use of the same text on the wire's records:
tests/fci/test_arrival.py.)"""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.fci.frames import from_wire, is_homogeneous, to_wire
from franka_sim_gym.sim.rotations import rotation_exp


def _poses(rng: np.random.Generator, n: int) -> np.ndarray:
    T = np.zeros((n, 4, 4))
    T[:, :3, :3] = rotation_exp(rng.normal(size=(n, 3)))
    T[:, :3, 3] = rng.uniform(-1, 1, size=(n, 3))
    T[:, 3, 3] = 1.0
    return T


def _verdict(values: np.ndarray) -> np.ndarray:
    return is_homogeneous(from_wire(values))


def test_valid_poses_pass() -> None:
    wire = to_wire(_poses(np.random.default_rng(0), 64))
    assert _verdict(wire).all()


@pytest.mark.parametrize("scale", [0.0, 2e-6, 4.9e-6, 5.1e-6, 9.9e-6, 1.01e-5, 3e-5, 1e-3])
def test_scaled_rotation_blocks_get_the_exact_verdict(scale: float) -> None:
    """A rotation block stretched along one row by ``scale`` sits inside or past the
    band's edge: every pose passes below 1e-5, none above."""
    rng = np.random.default_rng(1)
    T = _poses(rng, 32)
    rows = rng.integers(0, 3, size=32)
    T[np.arange(32), rows, :3] *= 1.0 + scale
    np.testing.assert_array_equal(_verdict(to_wire(T)), np.full(32, scale < 1e-5))


@pytest.mark.parametrize("slot", [3, 7, 11, 15, 0, 5, 12, 14])
@pytest.mark.parametrize("value", [np.nan, np.inf, 1e-9])
def test_a_bad_entry_fails_only_its_own_pose(slot: int, value: float) -> None:
    wire = to_wire(_poses(np.random.default_rng(2), 4))
    wire[2, slot] = value
    verdict = _verdict(wire)
    # A tiny finite value in the translation (12, 14) is a valid pose; anywhere else
    # (a bottom-row slot, a rotation entry) or non-finite, it is not.
    bad = not np.isfinite(value) or slot not in (12, 14)
    assert verdict.tolist() == [True, True, not bad, True]


@pytest.mark.parametrize(
    "block",
    [
        [[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]],  # unit rows, columns not
        [[1.0, 1.0, 1.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]],  # unit columns, rows not
    ],
)
def test_rows_and_columns_are_both_checked(block) -> None:
    T = _poses(np.random.default_rng(3), 3)
    T[1, :3, :3] = block
    assert _verdict(to_wire(T)).tolist() == [True, False, True]
