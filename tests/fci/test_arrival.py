"""fci/arrival.py (its rules' one text, fci/_arrival.c): a refused command's log line names
the wire field that was refused; a pose is judged in the wire's order; each interface
ends its motion by its own flag; a command answering no state of the motion is logged
and its cycle lost; a command array of another layout is refused by name.

docs/fci-behaviour.md: a non-finite command is refused whatever the enforcement; the
server's log is what a user reads to find which field their client broke.
"""

from __future__ import annotations

import logging

import numpy as np
import pytest

from franka_sim_gym.fci.errors import Error
from franka_sim_gym.fci.wire import ROBOT_COMMAND_DTYPE, MoveMotionGeneratorMode, RobotMode
from franka_sim_gym.fci.wire.protocol import MoveStatus
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


@pytest.mark.parametrize("slot", [3, 7, 11, 12, 14])
def test_a_pose_command_is_judged_in_the_wires_column_major_order(slot, caplog):
    """The wire's O_T_EE_c is column-major: slots 3, 7 and 11 are the bottom row (a tiny
    value there is no homogeneous transformation: refused, 31), 12 and 14 the translation
    (a tiny step there is a valid pose, taken)."""
    ctrl = make_controller()
    c = LoopClient(ctrl)
    c.start(CP, IMP)
    pose = _pose(c)
    pose[slot] += 1e-9
    with caplog.at_level(logging.WARNING, logger="franka_sim_gym.fci"):
        c.send(O_T_EE_c=pose)
    latched = np.flatnonzero(ctrl.violations.take()[0]).tolist()
    if slot in (3, 7, 11):
        assert "the commanded O_T_EE_c is not a homogeneous transformation" in caplog.text
        assert latched == [int(Error.cartesian_position_motion_generator_invalid_frame)]
    else:
        assert "command refused" not in caplog.text
        assert latched == []
        assert int(ctrl.states[0]["robot_mode"]) == int(RobotMode.kMove)  # still running


@pytest.mark.parametrize("generator", ["torque", "joint position"])
def test_each_interface_ends_its_motion_by_its_own_flag(generator):
    """libfranka ends a torque-only motion with torque_command_finished and a generator's
    with motion_generation_finished; the other flag alone ends nothing."""
    own, other = "torque_command_finished", "motion_generation_finished"
    start = (NONE, EXT) if generator == "torque" else (JP, IMP)
    if generator != "torque":
        own, other = other, own
    ctrl = make_controller()
    c = LoopClient(ctrl)
    c.start(*start)
    command = {"q_c": c.state["q_d"], "tau_J_d": np.zeros(7)}
    for _ in range(3):
        c.command[0] = np.zeros((), dtype=c.command.dtype)
        c.command["message_id"][0] = c.state["message_id"]
        for name, value in command.items():
            c.command[name][0] = value
        c.command[other][0] = True
        ctrl.receive(c.command, np.ones(1, dtype=bool))
        c.events += ctrl.step()
    assert c.move_statuses() == []
    c.command[own][0] = True
    c.command["message_id"][0] = c.state["message_id"]
    ctrl.receive(c.command, np.ones(1, dtype=bool))
    c.events += ctrl.step()
    assert c.move_statuses() == [int(MoveStatus.kSuccess)]


@pytest.mark.parametrize("echo", ["a state before the motion", "a state never published"])
def test_a_command_answering_no_state_of_the_motion_is_logged_and_lost(echo, caplog):
    """docs/fci-behaviour.md "The cycle contract": an id never published, or one from
    before the motion began, answers nothing: logged with its id, the cycle lost."""
    ctrl = make_controller()
    c = LoopClient(ctrl)
    first = int(c.state["message_id"])
    c.start(JP, IMP)
    for _ in range(5):
        c.send(q_c=c.state["q_d"])
    assert float(c.state["control_command_success_rate"]) == 1.0
    published = int(c.state["message_id"])
    wrong = first - 1 if echo == "a state before the motion" else published + 5
    with caplog.at_level(logging.WARNING, logger="franka_sim_gym.fci"):
        c.send(q_c=c.state["q_d"], message_id=wrong)
    assert (
        f"robot 0: command with message_id {wrong} answers no state of the running motion "
        f"(last published {published}); counted as lost" in caplog.text
    )
    assert float(c.state["control_command_success_rate"]) == pytest.approx(5 / 6)


def test_commands_of_another_layout_are_refused_by_name():
    ctrl = make_controller(2)
    LoopClient(ctrl).start(JP, IMP)
    mask = np.ones(2, dtype=bool)
    with pytest.raises(ValueError, match="commands: .* bytes, expected 2 commands"):
        ctrl.receive(np.zeros(3, dtype=ROBOT_COMMAND_DTYPE), np.ones(3, dtype=bool)[:2])
    with pytest.raises(ValueError, match="commands: expected a C-contiguous"):
        ctrl.receive(np.zeros(4, dtype=ROBOT_COMMAND_DTYPE)[::2], mask)
    with pytest.raises(ValueError, match="mask: expected a uint8 or bool array of shape"):
        ctrl.receive(np.zeros(2, dtype=ROBOT_COMMAND_DTYPE), np.ones(3, dtype=bool))
