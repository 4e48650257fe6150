"""pylibfranka runs the motion of its own cartesian_velocity_example.py (pylibfranka 0.21).

That example sets SetCollisionBehavior (20/40 Nm, 10/20 N), the joint and Cartesian
impedances, moves in joint positions under ControllerMode::CartesianImpedance to its
``q_goal``, sets the joint impedance and thresholds of 20 N again, then runs 8 s of
Cartesian velocity: a cosine speed profile (peak 0.1 m/s) along x = z, out for 4 s and
back for 4 s. Written for this project: the same calls and profile, the moves to a
goal given by the scenario.

`python example_motion_client.py SCENARIO HOST` prints one JSON line (scenario_main.py).
"""

from __future__ import annotations

import math

import pylibfranka as fr
import scenario_main  # tests/e2e/clients/scenario_main.py: the shared entry point
from pylibfranka_client import connect

#: libfranka's C++ examples' q_goal (examples/*.cpp), the simulated robot's start pose.
READY = [0.0, -math.pi / 4, 0.0, -3 * math.pi / 4, 0.0, math.pi / 2, math.pi / 4]
#: A free-space pose 0.3 to 0.7 rad from READY in every joint.
ELSEWHERE = [0.5, -0.2, 0.4, -2.1, -0.3, 2.2, 1.2]
#: pylibfranka's example's q_goal: joint 2 at +pi/4, the wrist at the table plane.
EXAMPLE_GOAL = [0.0, math.pi / 4, 0.0, -3 * math.pi / 4, 0.0, math.pi / 2, math.pi / 4]


class Sensed:
    """Peak |estimate| and the contact flags raised in the states a client read."""

    def __init__(self) -> None:
        self.tau = [0.0] * 7
        self.force = [0.0] * 6
        self.flags = 0.0

    def __call__(self, state) -> None:
        self.tau = [
            max(a, abs(b)) for a, b in zip(self.tau, state.tau_ext_hat_filtered, strict=True)
        ]
        self.force = [max(a, abs(b)) for a, b in zip(self.force, state.O_F_ext_hat_K, strict=True)]
        self.flags += sum(state.joint_contact) + sum(state.cartesian_contact)


def joint_move(robot: fr.Robot, goal: list[float], duration: float, sensed: Sensed) -> None:
    """A cosine-blended joint-position move under ControllerMode::CartesianImpedance."""
    control = robot.start_joint_position_control(fr.ControllerMode.CartesianImpedance)
    t, q0 = 0.0, None
    while True:
        state, period = control.readOnce()
        sensed(state)
        t += period.to_sec()
        if q0 is None:
            q0 = list(state.q_d)
        s = 0.5 * (1 - math.cos(math.pi * min(t / duration, 1.0)))
        command = fr.JointPositions([a + s * (b - a) for a, b in zip(q0, goal, strict=True)])
        command.motion_finished = t >= duration
        control.writeOnce(command)
        if command.motion_finished:
            return


def cartesian_motion(robot: fr.Robot, sensed: Sensed) -> None:
    """The example's 8 s Cartesian velocity motion."""
    control = robot.start_cartesian_velocity_control(fr.ControllerMode.CartesianImpedance)
    t, t_max, v_max = 0.0, 4.0, 0.1
    while True:
        state, period = control.readOnce()
        sensed(state)
        t += period.to_sec()
        v = (1 if t < t_max else -1) * v_max / 2 * (1 - math.cos(2 * math.pi / t_max * t))
        v_xz = math.cos(math.pi / 4) * v
        command = fr.CartesianVelocities([v_xz, 0.0, v_xz, 0.0, 0.0, 0.0])
        command.motion_finished = t >= 2 * t_max
        control.writeOnce(command)
        if command.motion_finished:
            return


def setup(robot: fr.Robot) -> None:
    """The example's settings before its first motion."""
    robot.set_collision_behavior([20.0] * 7, [40.0] * 7, [10.0] * 6, [20.0] * 6)
    robot.set_joint_impedance([3000.0, 3000.0, 3000.0, 2500.0, 2500.0, 2000.0, 2000.0])
    robot.set_cartesian_impedance([3000.0, 3000.0, 3000.0, 300.0, 300.0, 300.0])


def run(host: str, goals: list[list[float]]) -> dict:
    robot = connect(host)
    sensed = Sensed()
    setup(robot)
    error, stage = None, "joint"
    try:
        for goal in goals:
            joint_move(robot, goal, 1.5, sensed)
        stage = "cartesian"
        robot.set_joint_impedance([3000.0, 3000.0, 3000.0, 2500.0, 2500.0, 2000.0, 2000.0])
        torque, force = [20.0, 20.0, 18.0, 18.0, 16.0, 14.0, 12.0], [20.0] * 3 + [25.0] * 3
        robot.set_collision_behavior(torque, torque, force, force)
        cartesian_motion(robot, sensed)
    except fr.ControlException as exc:
        error = str(exc)
    state = robot.read_once()
    return {
        "error": error,
        "stage": stage,
        "tau_peak": sensed.tau,
        "force_peak": sensed.force,
        "flags": sensed.flags,
        "z": state.O_T_EE[14],
        "robot_mode": state.robot_mode.name,
    }


def scenario_free(host: str) -> dict:
    """The example's sequence with its joint moves in free space (away and back to READY)."""
    return run(host, [ELSEWHERE, READY])


def scenario_example_goal(host: str) -> dict:
    """The example's sequence with its own q_goal."""
    return run(host, [EXAMPLE_GOAL])


if __name__ == "__main__":
    scenario_main.run(globals())
