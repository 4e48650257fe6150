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
from tests.fci_helpers import IMP, JP, JV, LoopClient, make_controller

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


def test_the_opening_command_rebases_the_history_at_rest():
    # docs/fci-behaviour.md "The difference formulas": the opening command (within the
    # start tolerance of q_d) is recorded at rest, whatever it differs from q_d by; the
    # next command is differenced against it.
    ctrl = make_controller(enforce_motion_limits=True)
    c = LoopClient(ctrl)
    c.start(JP, IMP)
    q = c.state["q_d"].astype(np.float64)
    q[1] += 0.01  # 10 rad/s over one cycle, were it differenced
    c.send(q_c=q)
    assert c.state["robot_mode"] == RobotMode.kMove
    np.testing.assert_array_equal(ctrl.reference.q[0], q)
    assert not ctrl.reference.dq[0].any() and not ctrl.reference.ddq[0].any()
    q[1] += 1e-6
    c.send(q_c=q)
    assert ctrl.reference.dq[0, 1] == pytest.approx(1e-3, rel=1e-6)
    assert ctrl.reference.ddq[0, 1] == pytest.approx(1.0, rel=1e-6)


def test_the_opening_velocity_command_rebases_the_acceleration_at_rest():
    ctrl = make_controller(enforce_motion_limits=True)
    c = LoopClient(ctrl)
    c.start(JV, IMP)
    dq = np.zeros(7)
    dq[3] = 0.05  # within the start-velocity tolerance; 50 rad/s^2 were it differenced
    c.send(dq_c=dq)
    assert c.state["robot_mode"] == RobotMode.kMove
    assert ctrl.reference.dq[0, 3] == 0.05
    assert not ctrl.reference.ddq[0].any()


def test_a_backlog_drained_in_order_leaves_the_history_of_its_real_samples():
    # docs/fci-behaviour.md "A datagram that turns up late replaces the guess it stood in
    # for": a stream with a jerk, so that the guesses (at the frozen acceleration) are not
    # its waypoints. After the backlog, q_d, dq_d and ddq_d are the backward differences of
    # the real samples, not of the guesses they replaced.
    ctrl = make_controller(enforce_motion_limits=True)
    c = LoopClient(ctrl)
    c.start(JP, IMP)
    q0 = c.state["q_d"].astype(np.float64)

    def waypoint(k: int) -> np.ndarray:
        t = k * 1e-3
        q = q0.copy()
        q[1] += 0.5 * 2.0 * t * t + 50.0 * t**3 / 6
        return q

    for k in range(0, 100):
        c.send(q_c=waypoint(k))
    stalled = []
    for k in range(100, 106):
        stalled.append((int(c.state["message_id"]), waypoint(k)))
        c.send(deliver=False)
    command = np.zeros(1, dtype=ROBOT_COMMAND_DTYPE)
    for message_id, q in [*stalled, (int(c.state["message_id"]), waypoint(106))]:
        command[0] = np.zeros((), dtype=ROBOT_COMMAND_DTYPE)
        command["message_id"][0] = message_id
        command["q_c"][0] = q
        ctrl.receive(command, np.ones(1, dtype=bool))
    ctrl.step()
    assert c.state["robot_mode"] == RobotMode.kMove
    dq = [(waypoint(k)[1] - waypoint(k - 1)[1]) / 1e-3 for k in (105, 106)]
    ref = ctrl.reference
    assert ref.q[0, 1] == waypoint(106)[1]
    assert ref.dq[0, 1] == pytest.approx(dq[1], abs=1e-9)
    assert ref.ddq[0, 1] == pytest.approx((dq[1] - dq[0]) / 1e-3, abs=1e-5)
    # differenced against the guess for cycle 105 instead, dq_d would be off by more
    w = [waypoint(k)[1] for k in (97, 98, 99)]
    v, a = (w[2] - w[1]) / 1e-3, ((w[2] - w[1]) - (w[1] - w[0])) / 1e-6
    guess = w[2]
    for _ in range(6):
        v += a * 1e-3
        guess += v * 1e-3
    assert abs((waypoint(106)[1] - guess) / 1e-3 - dq[1]) > 1e-4


def test_the_joint_cycle_refuses_arrays_by_name():
    """The cycle's C plan (fci/limits/_joint.c JointCycle) names a wrong argument."""
    ctrl = make_controller(n=2)
    g, m, cycle = ctrl.joint, ctrl.modes, ctrl.cycle_input
    good = (cycle.q_c, cycle.dq_c, cycle.have, ctrl.accounting.started, m.tracking,
            m.joint_position, m.joint_velocity, ctrl.writer.message_id, True, 0.1, 0.1)  # fmt: skip
    assert g._cycle.advance(*good) == 0  # nothing in motion: nothing judged
    with pytest.raises(ValueError, match=r"q_c: axis 1 has length 6, expected 7"):
        g._cycle.advance(np.zeros((2, 6)), *good[1:])
    with pytest.raises(ValueError, match=r"started: expected a uint8 or bool array of shape"):
        g._cycle.advance(*good[:3], np.zeros(3, dtype=bool), *good[4:])
    with pytest.raises(ValueError, match="echo: expected an int64 or uint64 array"):
        g._cycle.advance(*good[:7], np.zeros(2), *good[8:])
    with pytest.raises(TypeError, match=r"advance\(\) takes 11 arguments \(10 given\)"):
        g._cycle.advance(*good[:10])


@pytest.mark.parametrize(
    "generator, pose_tolerance, velocity_tolerance, expected",
    [
        (JP, 0.3, 0.1, ()),
        (JP, 0.1, 0.3, ("joint_position_motion_generator_start_pose_invalid",)),
        (JV, 0.1, 0.3, ()),
        (JV, 0.3, 0.1, ("joint_motion_generator_acceleration_discontinuity",)),
    ],
)
def test_each_generator_judges_its_first_command_by_its_own_configured_tolerance(
    generator, pose_tolerance, velocity_tolerance, expected
):
    """docs/motion-limits.md: the opening q_c within start_pose_tolerance of q_d (else 11), the
    opening dq_c within start_velocity_tolerance of dq_d (else 15), the config's own."""
    ctrl = make_controller(
        enforce_motion_limits=True,
        start_pose_tolerance=pose_tolerance,
        start_velocity_tolerance=velocity_tolerance,
    )
    ctrl.move(0, int(IMP), int(generator))
    ctrl.step()
    commands = np.zeros(1, dtype=ROBOT_COMMAND_DTYPE)
    field = "q_c" if generator == JP else "dq_c"
    value = ctrl.states["q_d"].astype(np.float64) if generator == JP else np.zeros((1, 7))
    value[0, 6] += 0.2  # between the two tolerances
    commands[field] = value
    commands["message_id"] = ctrl.states["message_id"]
    ctrl.receive(commands, np.ones(1, dtype=bool))
    ctrl.step()
    assert ctrl.error_names(0) == expected
