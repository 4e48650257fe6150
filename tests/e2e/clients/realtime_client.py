"""pylibfranka with its default RealtimeConfig (kEnforce), as unchanged programs construct it.

`python realtime_client.py SCENARIO HOST` prints one JSON line. Run directly on an ordinary
kernel the constructor throws; run through `franka-sim-gym run-client --` it connects.
"""

from __future__ import annotations

import pylibfranka as fr
import scenario_main  # tests/e2e/clients/scenario_main.py: the shared entry point


def scenario_enforced(host: str) -> dict:
    """Robot(host) with the default kEnforce; a state; 200 cycles holding q_d; finished."""
    robot = fr.Robot(host)
    state = robot.read_once()
    control = robot.start_joint_position_control(fr.ControllerMode.JointImpedance)
    q = None
    for k in range(200):
        state, _ = control.readOnce()
        q = list(state.q_d) if q is None else q
        command = fr.JointPositions(q)
        command.motion_finished = k == 199
        control.writeOnce(command)
    final = robot.read_once()
    return {"mode": final.robot_mode.name, "errors": str(final.last_motion_errors)}


if __name__ == "__main__":
    scenario_main.run(globals())
