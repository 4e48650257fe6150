"""pylibfranka against `serve --reality`: the robot at rest, and libfranka's
joint_impedance_control example's logic (issue 37).

`python reality_client.py SCENARIO HOST` prints one JSON line (scenario_main.py).

``rest``: read the state for 1 s of the robot's time: tau_J's standard deviation per
joint, the mean external wrench and torque, any contact flag.

``joint_impedance``: libfranka's examples/joint_impedance_control.cpp as a readOnce /
writeOnce torque loop (pylibfranka has no motion generator beside a torque controller):
the same collision thresholds, gains (K 600, 600, 600, 600, 250, 150, 50; D 50, 50, 50,
50, 30, 25, 15), control law tau_d = K (q_d - q) - D dq + coriolis, rate-limited at
libfranka's kMaxTorqueRate, and the same torque error, tau_d + gravity - tau_J (the
command computed from a state against the torque that state measured). The example's
q_d is the robot's IK of a circle (radius 5 cm in y-z at up to 0.25 m/s); here the
client integrates the circle's velocity through the Jacobian (pseudo-inverse of its
translational rows), a reference as smooth. Shortened: 0.5 s ramps, 2 s at speed.
"""

from __future__ import annotations

import math

import numpy as np
import pylibfranka as fr
import scenario_main  # tests/e2e/clients/scenario_main.py: the shared entry point
from pylibfranka_client import connect

#: libfranka examples/joint_impedance_control.cpp
RADIUS, VEL_MAX = 0.05, 0.25
K_GAINS = np.array([600.0, 600.0, 600.0, 600.0, 250.0, 150.0, 50.0])
D_GAINS = np.array([50.0, 50.0, 50.0, 50.0, 30.0, 25.0, 15.0])
THRESHOLDS = [20.0, 20.0, 18.0, 18.0, 16.0, 14.0, 12.0]
#: libfranka include/franka/rate_limiting.h: kMaxTorqueRate = 1000 - kLimitEps
MAX_TORQUE_RATE = 1000.0 - 1e-3
#: shortened from the example's 2 s ramps and 20 s at speed
RAMP, RUN = 0.5, 2.5


def scenario_rest(host: str) -> dict:
    """One second of states of a robot nobody drives."""
    robot = connect(host)
    states = [robot.read_once()]
    while states[-1].time.to_sec() - states[0].time.to_sec() < 1.0:
        states.append(robot.read_once())
    tau_J = np.array([s.tau_J for s in states])
    F = np.array([s.O_F_ext_hat_K for s in states])
    tau_ext = np.array([s.tau_ext_hat_filtered for s in states])
    return {
        "samples": len(states),
        "tau_J_std": tau_J.std(axis=0).tolist(),
        "F_mean": F.mean(axis=0).tolist(),
        "F_norm": float(np.linalg.norm(F.mean(axis=0)[:3])),
        "tau_ext_mean": tau_ext.mean(axis=0).tolist(),
        "contact": any(any(s.joint_contact) or any(s.cartesian_contact) for s in states),
    }


def scenario_joint_impedance(host: str) -> dict:
    """The example's control loop; the RMS of its printed torque error over the motion."""
    robot = connect(host)
    robot.set_collision_behavior(THRESHOLDS, THRESHOLDS, [20.0] * 6, [20.0] * 6)
    model = robot.load_model()
    control = robot.start_torque_control()
    t, vel, angle = 0.0, 0.0, 0.0
    q_ref = None
    errors, contact, error = [], False, None
    try:
        while True:
            state, period = control.readOnce()
            dt = period.to_sec()
            t += dt
            q = np.array(state.q)
            if q_ref is None:
                q_ref = q.copy()
            # the example's velocity profile along the circle
            if vel < VEL_MAX and t < RUN:
                vel += dt * VEL_MAX / RAMP
            if vel > 0.0 and t > RUN:
                vel -= dt * VEL_MAX / RAMP
            vel = min(max(vel, 0.0), VEL_MAX)
            angle += dt * vel / RADIUS
            v = np.array([0.0, vel * math.sin(angle), vel * math.cos(angle)])
            J = np.array(model.zero_jacobian(state)).reshape(7, 6).T  # column-major
            q_ref = q_ref + np.linalg.pinv(J[:3]) @ v * dt
            coriolis = np.array(model.coriolis(state))
            tau = K_GAINS * (q_ref - q) - D_GAINS * np.array(state.dq) + coriolis
            last = np.array(state.tau_J_d)
            limited = last + np.clip(tau - last, -MAX_TORQUE_RATE * 1e-3, MAX_TORQUE_RATE * 1e-3)
            # the example's print: tau_d + gravity - tau_J of the same state
            e = limited + np.array(model.gravity(state)) - np.array(state.tau_J)
            errors.append(float(np.sqrt(np.mean(e**2))))
            contact |= any(state.joint_contact) or any(state.cartesian_contact)
            command = fr.Torques(limited.tolist())
            command.motion_finished = t >= RUN + RAMP
            control.writeOnce(command)
            if command.motion_finished:
                break
    except fr.ControlException as exc:
        error = str(exc)
    errors = np.array(errors)
    return {
        "cycles": len(errors),
        "rms": float(np.sqrt(np.mean(errors**2))),
        "max": float(errors.max()),
        "contact": bool(contact),
        "error": error,
    }


if __name__ == "__main__":
    scenario_main.run(globals())
