"""Move the arm with pylibfranka: the same script runs against a real FR3.

    python examples/pylibfranka_joint_motion.py --host 127.0.0.1

Reads the state, then runs a 3 s cosine joint-position motion (the shape of
libfranka's generate_joint_position_motion example: joints 4, 5 and 7 swing
by pi/8 and come back) through pylibfranka's readOnce/writeOnce loop.
"""

from __future__ import annotations

import argparse
import math

import pylibfranka as fr


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--host", default="127.0.0.1", help="robot (or simulator) address")
    parser.add_argument("--duration", type=float, default=3.0, help="motion duration [s]")
    args = parser.parse_args()

    robot = fr.Robot(args.host, fr.RealtimeConfig.kIgnore)
    state = robot.read_once()
    print("connected: robot_mode", state.robot_mode.name)
    print("q      ", " ".join(f"{v:+.4f}" for v in state.q))
    print("O_T_EE translation", " ".join(f"{v:+.4f}" for v in list(state.O_T_EE)[12:15]))
    model = robot.load_model()
    print("gravity", " ".join(f"{v:+.3f}" for v in model.gravity(state)))

    control = robot.start_joint_position_control(fr.ControllerMode.JointImpedance)
    t, q0, max_err, rate = 0.0, None, 0.0, 0.0
    while True:
        state, period = control.readOnce()
        t += period.to_sec()
        if q0 is None:
            q0 = list(state.q_d)
        max_err = max(max_err, max(abs(a - b) for a, b in zip(state.q, state.q_d, strict=True)))
        rate = state.control_command_success_rate
        delta = math.pi / 8 * (1 - math.cos(2 * math.pi * t / args.duration))
        q = list(q0)
        for joint in (3, 4, 6):
            q[joint] += delta
        command = fr.JointPositions(q)
        if t >= args.duration:
            command.motion_finished = True
            control.writeOnce(command)
            break
        control.writeOnce(command)
    print(
        f"motion finished after {t:.3f} s: max tracking error {max_err:.2e} rad, "
        f"control_command_success_rate {rate:.3f}"
    )


if __name__ == "__main__":
    main()
