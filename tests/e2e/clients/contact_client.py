"""pylibfranka scenarios against the table: contact, collision reflexes, the estimate.

`python contact_client.py SCENARIO HOST` prints one JSON line (scenario_main.py).
"""

from __future__ import annotations

import math
import os
import time

import pylibfranka as fr
import scenario_main  # tests/e2e/clients/scenario_main.py: the shared entry point
from pylibfranka_client import connect, move_to, read_after_recovery

#: The flange pointing down 18 cm above the table (tests/sim/test_scene.py OVER_THE_TABLE).
OVER_THE_TABLE = [0.0, 0.6, 0.0, -1.9, 0.0, 2.5, math.pi / 4]
#: The descent's speed [m/s] and the time it takes to get there (a cosine ramp).
DESCENT_SPEED, RAMP = 0.05, 0.5


def thresholds() -> tuple[list[float], list[float], list[float], list[float]]:
    """SetCollisionBehavior's 4-argument form from FORCE="lower,upper" [N] (torques far
    above: the Cartesian thresholds decide)."""
    lower, upper = (float(v) for v in os.environ.get("FORCE", "20,20").split(","))
    torque = [100.0] * 7
    return torque, torque, [lower] * 6, [upper] * 6


def scenario_descend(host: str) -> dict:
    """Down onto the table at 5 cm/s under Cartesian velocity control until a reflex
    stops it (or 6 s pass); what the robot reported on the way."""
    robot = connect(host)
    move_to(robot, OVER_THE_TABLE, 2.0)
    robot.set_collision_behavior(*thresholds())
    control = robot.start_cartesian_velocity_control(fr.ControllerMode.JointImpedance)
    t, error = 0.0, None
    first_contact = None  # (t, z, F_z) when cartesian_contact[2] first read 1
    samples = []
    try:
        while t < 6.0:
            state, period = control.readOnce()
            t += period.to_sec()
            F_z = state.O_F_ext_hat_K[2]
            samples.append((t, state.O_T_EE[14], F_z))
            if first_contact is None and state.cartesian_contact[2] > 0:
                first_contact = (t, state.O_T_EE[14], F_z)
            v = DESCENT_SPEED * 0.5 * (1 - math.cos(math.pi * min(t / RAMP, 1.0)))
            command = fr.CartesianVelocities([0.0, 0.0, -v, 0.0, 0.0, 0.0])
            command.motion_finished = t >= 6.0
            control.writeOnce(command)
    except fr.ControlException as exc:
        error = str(exc)
    del control
    time.sleep(0.2)
    after = robot.read_once()
    result = {
        "error": error,
        "t_end": t,
        "first_contact": first_contact,
        "z_start": samples[0][1],
        "z_end": samples[-1][1],
        "F_z_last": samples[-1][2],
        "F_z_min": min(s[2] for s in samples),
        "robot_mode": after.robot_mode.name,
        "current_errors": str(after.current_errors),
        "cartesian_collision": list(after.cartesian_collision),
        "O_F_ext_hat_K_after": list(after.O_F_ext_hat_K),
    }
    robot.automatic_error_recovery()
    recovered = read_after_recovery(robot)
    result["mode_recovered"] = recovered.robot_mode.name
    result["cartesian_collision_recovered"] = list(recovered.cartesian_collision)
    return result


def scenario_rest(host: str) -> dict:
    """One second of states in free space at rest: the estimate and every flag."""
    robot = connect(host)
    worst_tau = worst_force = 0.0
    flags = 0.0
    for _ in range(100):
        state = robot.read_once()
        worst_tau = max(worst_tau, max(abs(v) for v in state.tau_ext_hat_filtered))
        worst_force = max(worst_force, max(abs(v) for v in state.O_F_ext_hat_K))
        flags += sum(state.joint_contact) + sum(state.cartesian_contact)
        flags += sum(state.joint_collision) + sum(state.cartesian_collision)
        time.sleep(0.01)
    return {"worst_tau": worst_tau, "worst_force": worst_force, "flags": flags}


def scenario_zero_torque(host: str) -> dict:
    """SetLoad(LOAD kg at 5 cm along the flange's z), then 1 s of zero commanded torque:
    how far the flange rose (the robot carries the configured weight; MuJoCo only what
    is there)."""
    robot = connect(host)
    mass = float(os.environ.get("LOAD", "0"))
    robot.set_load(mass, [0.0, 0.0, 0.05], [0.0] * 9)
    control = robot.start_torque_control()
    t, z0, z = 0.0, None, None
    try:
        while t < 1.0:
            state, period = control.readOnce()
            t += period.to_sec()
            z = state.O_T_EE[14]
            if z0 is None:
                z0 = z
            command = fr.Torques([0.0] * 7)
            command.motion_finished = t >= 1.0
            control.writeOnce(command)
    except fr.ControlException as exc:
        return {"error": str(exc)}
    return {"error": None, "rise": z - z0}


def scenario_impedance_press(host: str) -> dict:
    """Under ControllerMode::CartesianImpedance with K (env STIFFNESS N/m), a pose
    commanded 2 cm under the table (the flange starts 18 cm above it: 20 cm down in
    3 s, then held 1 s); the robot's own estimate of the force at the end."""
    robot = connect(host)
    move_to(robot, OVER_THE_TABLE, 2.0)
    stiffness = float(os.environ.get("STIFFNESS", "1000"))
    robot.set_cartesian_impedance([stiffness] * 3 + [300.0] * 3)
    robot.set_collision_behavior([100.0] * 7, [100.0] * 7, [100.0] * 6, [100.0] * 6)
    control = robot.start_cartesian_pose_control(fr.ControllerMode.CartesianImpedance)
    start: list[float] = []

    def pose_at(state, t: float):
        if not start:
            start.extend(state.O_T_EE_c)
        pose = list(start)
        pose[14] -= 0.2 * 0.5 * (1 - math.cos(math.pi * min(t / 3.0, 1.0)))
        return fr.CartesianPose(pose)

    t, error, state = 0.0, None, None
    try:
        while t < 4.0:
            state, period = control.readOnce()
            t += period.to_sec()
            command = pose_at(state, t)
            command.motion_finished = t >= 4.0
            control.writeOnce(command)
    except fr.ControlException as exc:
        error = str(exc)
    return {
        "error": error,
        "F_z": state.O_F_ext_hat_K[2],
        "z": state.O_T_EE[14],
        "z_commanded": state.O_T_EE_c[14],
    }


if __name__ == "__main__":
    scenario_main.run(globals())
