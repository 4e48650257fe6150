"""The controller configuration: the switches of docs/fci-behaviour.md, their environment variables,
the robots."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.fci.config import ControllerConfig
from franka_sim_gym.fci.errors import Error
from franka_sim_gym.fci.wire import RobotMode
from tests.fci_helpers import IMP, JV, LoopClient, make_controller


def test_environment_variables_turn_the_switches_on(monkeypatch):
    monkeypatch.setenv("FRANKA_SIM_ENFORCE_MOTION_LIMITS", "1")
    monkeypatch.setenv("FRANKA_SIM_ENFORCE_COMM_CONSTRAINTS", "1")
    monkeypatch.setenv("FRANKA_SIM_JOINT_DISCONTINUITY_SCALE", "0.8")
    config = ControllerConfig.from_environment()
    assert config.enforce_motion_limits and config.enforce_comm_constraints
    assert config.joint_discontinuity_scale == 0.8


def test_the_flag_wins_over_the_environment_variable(monkeypatch):
    monkeypatch.setenv("FRANKA_SIM_JOINT_DISCONTINUITY_SCALE", "0.8")
    monkeypatch.setenv("FRANKA_SIM_ENFORCE_MOTION_LIMITS", "0")
    config = ControllerConfig.from_environment(
        joint_discontinuity_scale=1.2, enforce_motion_limits=True
    )
    assert config.joint_discontinuity_scale == 1.2 and config.enforce_motion_limits


def test_malformed_values_are_clear_errors(monkeypatch):
    monkeypatch.setenv("FRANKA_SIM_JOINT_DISCONTINUITY_SCALE", "fast")
    with pytest.raises(ValueError, match="FRANKA_SIM_JOINT_DISCONTINUITY_SCALE"):
        ControllerConfig.from_environment()
    with pytest.raises(ValueError, match="unknown robot 'ur5'"):
        ControllerConfig(robot="ur5")
    with pytest.raises(ValueError, match="joint_discontinuity_scale"):
        ControllerConfig(joint_discontinuity_scale=-1.0)


def ramp_joint_1_to(c: LoopClient, target: float) -> None:
    v, a = 0.0, 0.0
    c.send(dq_c=np.zeros(7))
    for _ in range(1000):
        a = min(9.0, a + 4.0) if v < target - 0.45 else max(0.5, a - 4.0)
        v = min(target, v + a * 1e-3)
        c.send(dq_c=[v, 0, 0, 0, 0, 0, 0])
        if c.state["robot_mode"] != RobotMode.kMove or v >= target:
            return


@pytest.mark.parametrize(("robot", "refused"), [("fr3", False), ("fer", True)])
def test_robot_tables_are_selectable_fr3_allows_2_3_rad_per_s_fer_does_not(robot, refused):
    # FR3 (v10): 2.62 rad/s on joint 1 away from the stops; FER (v5): 2.175 rad/s.
    ctrl = make_controller(robot=robot, enforce_motion_limits=True)
    c = LoopClient(ctrl)
    c.start(JV, IMP)
    ramp_joint_1_to(c, 2.3)
    if refused:
        assert c.state["robot_mode"] == RobotMode.kReflex
        assert c.state["reflex_reason"][Error.joint_motion_generator_velocity_limits_violation]
    else:
        assert c.state["robot_mode"] == RobotMode.kMove
