"""franka_ros2's hardware interface (franka_hardware) replayed with pylibfranka: the
libfranka calls it makes, in its order, through the same libfranka 0.21 underneath.

franka_hardware (franka_ros2, franka_hardware/src/robot.cpp and
franka_hardware_interface.cpp) connects with kIgnore where the kernel is not real-time
and loads the model; on activation reads one state; its parameter services send the
setters; a controller switch to the effort interface destroys any active control and
starts torque control (on a ControlException: AutomaticErrorRecovery, then again); each
ros2_control cycle reads the state through the active control and writes torques
limited by libfranka's limitRate(kMaxTorqueRate) against the last ones; a switch to the
position interface destroys the torque control mid-motion and starts joint position
control; a ControlException in read() stops the robot, and the error-recovery action
sends AutomaticErrorRecovery before the controller starts again.

Not replayed, as pylibfranka 0.21.3 does not expose them: Model::pose and the body
Jacobian (gravity, Coriolis, mass and the zero Jacobian are), and the 8-array form of
setCollisionBehavior (the 4-array form sends the same message with the nominal values
twice). `python franka_hardware_client.py replay HOST` prints one JSON line.
"""

from __future__ import annotations

import math

import numpy as np
import pylibfranka as fr
import scenario_main  # tests/e2e/clients/scenario_main.py: the shared entry point

#: franka_ros2's joint_impedance_example_controller gains.
K_GAINS = np.array([24.0, 24.0, 24.0, 24.0, 10.0, 6.0, 2.0])
D_GAINS = np.array([2.0, 2.0, 2.0, 1.0, 1.0, 1.0, 0.5])
#: libfranka rate_limiting.h kMaxTorqueRate [Nm/s], per 1 ms cycle (franka::kDeltaT).
TORQUE_STEP = 1000.0 * 1e-3


def limit_rate(tau: np.ndarray, last: np.ndarray) -> np.ndarray:
    """franka::limitRate(kMaxTorqueRate, tau, last): the step clipped per cycle."""
    return last + np.clip(tau - last, -TORQUE_STEP, TORQUE_STEP)


def start_torque_control(robot: fr.Robot):
    """Robot::initializeTorqueInterface: on a ControlException, recover and start again."""
    try:
        return robot.start_torque_control(), False
    except fr.ControlException:
        robot.automatic_error_recovery()
        return robot.start_torque_control(), True


def impedance_cycles(control, model: fr.Model, cycles: int, step_at: int | None = None) -> dict:
    """``cycles`` ros2_control cycles of the joint impedance example (joint 4 swinging by
    0.1 rad), with Coriolis from the model; at ``step_at`` a 5 Nm step on joint 1 written
    past the rate limiter (franka_hardware's limiter switched off)."""
    q_goal = None
    last = np.zeros(7)
    gravity_max = 0.0
    for k in range(cycles):
        state, _ = control.readOnce()
        q, dq = np.array(state.q), np.array(state.dq)
        if q_goal is None:
            q_goal = q.copy()
            last = np.array(state.tau_J_d)
        goal = q_goal.copy()
        goal[3] += 0.1 * math.sin(2 * math.pi * k / 1000.0)
        tau = K_GAINS * (goal - q) - D_GAINS * dq + np.array(model.coriolis(state))
        if k % 100 == 0:  # what a controller reads of the model now and then
            mass = np.array(model.mass(state))
            jacobian = np.array(model.zero_jacobian(state))
            gravity_max = max(gravity_max, float(np.max(np.abs(model.gravity(state)))))
            assert np.all(np.isfinite(mass)) and np.all(np.isfinite(jacobian))
        if step_at is not None and k == step_at:
            last = last.copy()
            last[0] += 5.0
            tau = last
        else:
            tau = last = limit_rate(tau, last)
        control.writeOnce(fr.Torques(tau.tolist()))
    return {"cycles": cycles, "gravity_max": gravity_max, "q_end": list(state.q)}


def scenario_replay(host: str) -> dict:
    result: dict = {}
    robot = fr.Robot(host, fr.RealtimeConfig.kIgnore)  # hasRealtimeKernel() false here
    model = robot.load_model()
    state = robot.read_once()  # on_activate: read()
    result["gravity_at_start"] = list(model.gravity(state))
    # The parameter services (franka_msgs SetJointStiffness ... SetForceTorqueCollisionBehavior).
    robot.set_joint_impedance([3000.0, 3000.0, 3000.0, 2500.0, 2500.0, 2000.0, 2000.0])
    robot.set_cartesian_impedance([3000.0, 3000.0, 3000.0, 300.0, 300.0, 300.0])
    robot.set_load(0.0, [0.0, 0.0, 0.0], [0.0] * 9)
    robot.set_EE([1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0.1034, 1.0])
    robot.set_K([1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 1.0])
    robot.set_collision_behavior([20.0] * 7, [20.0] * 7, [20.0] * 6, [20.0] * 6)
    # The effort interface claimed: torque control, 1 s of the impedance controller.
    control, recovered = start_torque_control(robot)
    result["torque"] = impedance_cycles(control, model, 1000)
    result["torque"]["recovered_to_start"] = recovered
    # Switch to the position interface: stopRobot() drops the torque control mid-motion.
    del control
    control = robot.start_joint_position_control(fr.ControllerMode.JointImpedance)
    for _ in range(300):
        state, _ = control.readOnce()
        control.writeOnce(fr.JointPositions(list(state.q_d)))
    del control
    # Back to effort; a bad command ends it in read() with a ControlException ...
    control, _ = start_torque_control(robot)
    try:
        impedance_cycles(control, model, 200, step_at=100)
        result["reflex"] = None
    except fr.ControlException as exc:
        result["reflex"] = str(exc)
    del control  # stopRobot()
    result["mode_after_reflex"] = robot.read_once().robot_mode.name
    # ... the error-recovery action, and the controller started again.
    robot.automatic_error_recovery()
    result["mode_recovered"] = robot.read_once().robot_mode.name
    control, recovered = start_torque_control(robot)
    result["again"] = impedance_cycles(control, model, 300)
    result["again"]["recovered_to_start"] = recovered
    del control
    result["mode_end"] = robot.read_once().robot_mode.name
    return result


if __name__ == "__main__":
    scenario_main.run(globals())
