"""The joint generators' cycle: a robot's reference does not depend on the other robots.

When every robot runs one joint generator and sent a command, the generators take an
unmasked path (fci/joint_generators.py); a lost cycle or an abort elsewhere in the batch
takes the masked one. Either way a robot's published reference (q_d, dq_d, ddq_d) is
what its own commands make of it, bit for bit.
"""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.fci.wire import ROBOT_COMMAND_DTYPE, RobotMode
from tests.fci_helpers import IMP, JP, JV, make_controller

CYCLES = 200


def _run(generator, other: str) -> tuple[bytes, int]:
    """Two robots in one generator; robot 0 always sends, robot 1 as ``other`` says:
    "always", "lossy" (every 5th cycle lost) or "jump" (a discontinuity at cycle 100).
    Robot 0's reference over the run, and robot 1's final robot mode."""
    ctrl = make_controller(n=2, enforce_motion_limits=True)
    for i in range(2):
        ctrl.move(i, int(IMP), int(generator))
    for _ in range(2):
        ctrl.step()
    field = "q_c" if generator == JP else "dq_c"
    start = ctrl.states["q_d"].astype(np.float64) if generator == JP else np.zeros((2, 7))
    commands = np.zeros(2, dtype=ROBOT_COMMAND_DTYPE)
    mask = np.ones(2, dtype=bool)
    reference = []
    for k in range(1, CYCLES):
        bump = 0.05 * (1 - np.cos(2 * np.pi * k * 1e-3))
        if generator == JV:
            bump = 0.05 * 2 * np.pi * np.sin(2 * np.pi * k * 1e-3)
        value = start.copy()
        value[:, 3] += bump
        if other == "jump" and k == 100:
            value[1, 3] += 0.5
        commands[field] = value
        commands["message_id"] = ctrl.states["message_id"]
        mask[1] = not (other == "lossy" and k % 5 == 0)
        ctrl.receive(commands, mask)
        ctrl.step()
        s = ctrl.states[0]
        reference.append(s["q_d"].tobytes() + s["dq_d"].tobytes() + s["ddq_d"].tobytes())
    return b"".join(reference), int(ctrl.states[1]["robot_mode"])


@pytest.mark.parametrize("generator", [JP, JV], ids=["joint_position", "joint_velocity"])
@pytest.mark.parametrize("other", ["lossy", "jump"])
def test_reference_does_not_depend_on_the_other_robot(generator, other):
    every, mode = _run(generator, "always")
    assert mode == RobotMode.kMove
    masked, mode = _run(generator, other)
    assert mode == (RobotMode.kReflex if other == "jump" else RobotMode.kMove)
    assert masked == every
