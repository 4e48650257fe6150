"""franky scenarios for `serve --lockstep`, each run in its own process by the tests.

`python franky_lockstep_client.py SCENARIO HOST` prints one JSON line (the scenario's
result) as its last line. franky's `Robot.move` runs libfranka's C++ `Robot::control`
loop (docs/libfranka-client.md §5).
"""

from __future__ import annotations

import time

import franky
import numpy as np
import scenario_main  # tests/e2e/clients/scenario_main.py: the shared entry point
from franky_client import connect


def scenario_joint_motion(host: str) -> dict:
    """JointMotion 0.3 rad on joints 1 and 4 at 0.1 of the dynamics (about 1.5 s of robot
    time): the wall time `move` took, and the target."""
    robot = connect(host)
    q_before = np.asarray(robot.current_joint_state.position, dtype=float)
    target = q_before.copy()
    target[[0, 3]] += 0.3
    motion = franky.JointMotion(
        franky.JointState(target), relative_dynamics_factor=franky.RelativeDynamicsFactor(0.1)
    )
    error = None
    t0 = time.monotonic()
    try:
        robot.move(motion)
    except Exception as exc:  # reported to the test
        error = f"{type(exc).__name__}: {exc}"
    duration = time.monotonic() - t0
    state = robot.state
    return {
        "target": target.tolist(),
        "q_after": list(map(float, state.q)),
        "robot_mode": state.robot_mode.name,
        "duration": duration,
        "error": error,
    }


if __name__ == "__main__":
    scenario_main.run(globals())
