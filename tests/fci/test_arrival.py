"""fci/arrival.py: a refused command's log line names the wire field that was refused.

docs/fci-behaviour.md: a non-finite command is refused whatever the enforcement; the
server's log is what a user reads to find which field their client broke.
"""

from __future__ import annotations

import logging

import numpy as np
import pytest

from franka_sim_gym.fci.errors import Error
from franka_sim_gym.fci.wire import MoveMotionGeneratorMode
from tests.fci_helpers import EXT, IMP, JP, JV, NONE, LoopClient, make_controller

CP = MoveMotionGeneratorMode.kCartesianPosition
CV = MoveMotionGeneratorMode.kCartesianVelocity


def _pose(c: LoopClient) -> np.ndarray:
    return c.state["O_T_EE"].astype(float)


def _nan_at(values, index: int) -> np.ndarray:
    values = np.array(values, dtype=float)
    values[index] = np.nan
    return values


#: case -> (generator, controller, the command, the errors it latches: engine.py
#: judge_non_finite, docs/motion-limits.md)
CASES = {
    "q_c": (
        JP,
        IMP,
        lambda c: {"q_c": _nan_at(c.state["q_d"], 3)},
        Error.joint_motion_generator_position_limits_violation,
    ),
    "dq_c": (
        JV,
        IMP,
        lambda c: {"dq_c": _nan_at(np.zeros(7), 1)},
        # 13 latches 3 with it (fci/violations.py, docs/fci-behaviour.md
        # "joint_velocity_violation (3)")
        (Error.joint_velocity_violation, Error.joint_motion_generator_velocity_limits_violation),
    ),
    "tau_J_d": (
        NONE,
        EXT,
        lambda c: {"tau_J_d": _nan_at(np.zeros(7), 6)},
        Error.tau_j_range_violation,
    ),
    "tau_J_d beside a finite q_c": (
        JP,
        EXT,
        lambda c: {"q_c": c.state["q_d"], "tau_J_d": _nan_at(np.zeros(7), 0)},
        Error.tau_j_range_violation,
    ),
    "q_c beside a finite tau_J_d": (
        JP,
        EXT,
        lambda c: {"q_c": _nan_at(c.state["q_d"], 0), "tau_J_d": np.zeros(7)},
        Error.joint_motion_generator_position_limits_violation,
    ),
    "O_dP_EE_c": (
        CV,
        IMP,
        lambda c: {"O_dP_EE_c": _nan_at(np.zeros(6), 2)},
        Error.cartesian_motion_generator_velocity_limits_violation,
    ),
    "O_T_EE_c": (
        CP,
        IMP,
        lambda c: {"O_T_EE_c": _nan_at(_pose(c), 12)},
        Error.cartesian_position_motion_generator_invalid_frame,
    ),
    "elbow_c": (
        CV,
        IMP,
        lambda c: {"O_dP_EE_c": np.zeros(6), "valid_elbow": True, "elbow_c": [np.nan, -1.0]},
        Error.cartesian_motion_generator_elbow_limit_violation,
    ),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_non_finite_field_is_refused_named_in_the_log_and_latched_as_its_error(case, caplog):
    generator, controller, command, error = CASES[case]
    field = case.split()[0]
    ctrl = make_controller()
    c = LoopClient(ctrl)
    c.start(generator, controller)
    q_before = c.state["q"].copy()
    with caplog.at_level(logging.WARNING, logger="franka_sim_gym.fci"):
        c.send(**command(c))
    assert f"robot 0: non-finite value in the commanded {field}; command refused" in caplog.text
    latched = np.flatnonzero(ctrl.violations.take()[0])
    assert latched.tolist() == sorted(int(e) for e in np.atleast_1d(error))
    # refused: nothing non-finite reached the physics
    assert np.all(np.isfinite(c.state["q"])) and np.all(np.isfinite(c.state["tau_J"]))
    assert np.max(np.abs(c.state["q"] - q_before)) < 1e-3


def test_a_pose_that_is_no_transformation_is_named_so(caplog):
    c = LoopClient(make_controller())
    c.start(CP, IMP)
    pose = _pose(c)
    pose[3] = 0.5  # the bottom row (column-major) is no longer (0, 0, 0, 1)
    with caplog.at_level(logging.WARNING, logger="franka_sim_gym.fci"):
        c.send(O_T_EE_c=pose)
    assert "the commanded O_T_EE_c is not a homogeneous transformation" in caplog.text
    assert "non-finite" not in caplog.text
