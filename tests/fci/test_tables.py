"""The robot tables' derived data: the interior shortcut the client filters use."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.fci.tables import FER, FR3, INTERIOR_SPEED, JOINT_VELOCITY_LIMIT_TOLERANCE


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
