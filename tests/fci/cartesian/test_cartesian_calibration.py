"""The calibration replay (docs/fci-behaviour.md "Calibration on an FER") in-process: the
FER's joint side trips 29 and 30 at the replay's accelerations, an FR3 passes 2.5 m/s^2 and
refuses 3.5."""

from __future__ import annotations

import math

import numpy as np
import pytest

from franka_sim_gym.fci import frames
from franka_sim_gym.fci.errors import Error
from tests.cartesian_helpers import CP, errors, pose0, ramp_x
from tests.fci_helpers import LoopClient, make_controller

# -- the calibration replay (docs/fci-behaviour.md "Calibration on an FER") ------------------------

CALIBRATION_Q = [-0.046, -0.873, -0.104, -2.437, -0.051, 1.617, 0.748]


def _calibration(robot: str) -> LoopClient:
    """The FER calibration set-up (docs/fci-behaviour.md "Calibration on an FER"): start q, the
    Franka Hand's F_T_EE
    (Rz(45 deg), 0.1034 m), 0.5 s at rest before the ramp."""
    ctrl = make_controller(robot=robot, enforce_motion_limits=True)
    ctrl.reset([0], np.array([CALIBRATION_Q]))
    hand = np.eye(4)
    c45 = math.cos(math.pi / 4)
    hand[:3, :3] = [[c45, -c45, 0], [c45, c45, 0], [0, 0, 1]]
    hand[2, 3] = 0.1034
    ctrl.set_ne_to_ee(0, frames.to_wire(hand))
    c = LoopClient(ctrl)
    c.idle(5)
    c.start(CP)
    T0 = pose0(c)
    for _ in range(500):
        c.send(O_T_EE_c=T0)
    return c


# libfranka 0.9 rate_limiting.h FER budgets are the robot's limits minus kLimitEps.
@pytest.mark.parametrize(
    "v, a, j, trip, names",
    [
        (1.7 - 1e-3, 13.0 - 1e-3, 6500.0 - 1e-3, "early", {29, 30}),
        (0.5, 2.5, 500.0, 5, {29}),
        (0.3, 2.5, 500.0, 5, {29}),
        (0.3, 1.5, 200.0, None, set()),
        (0.4, 1.0, 100.0, None, set()),
        (0.3, 0.5, 20.0, None, set()),
    ],
)
def test_fer_calibration_replay(v, a, j, trip, names):
    """docs/fci-behaviour.md "Calibration on an FER": the 13 m/s^2 ramp refused within the first
    cycles
    with 29 and 30; the 2.5 m/s^2 ramp refused with 29 alone on the cycle where the
    per-cycle velocity increment reaches 2.5 mm/s (steps 0.5, 1.5, 3, 5, 7.5 um); the
    1.5 m/s^2 and slower ramps pass."""
    c = _calibration("fer")
    k = ramp_x(c, pose0(c), v, a, j, 500)
    if trip is None:
        assert k is None and errors(c) == ()
    elif trip == "early":
        assert k is not None and k <= 3
    else:
        assert k == trip
    assert {int(Error[name]) for name in errors(c)} == names


@pytest.mark.parametrize("a, refused", [(2.5, False), (3.5, True)])
def test_fr3_calibration_2_5_passes_and_3_5_is_refused(a, refused):
    c = _calibration("fr3")
    k = ramp_x(c, pose0(c), 0.5, a, 500.0, 500)
    assert (k is not None) == refused
    assert errors(c) == (
        ("cartesian_motion_generator_joint_velocity_discontinuity",) if refused else ()
    )
