"""pylibfranka's asynchronous joint-position control (AsyncPositionControlHandler) scenarios.

`python async_client.py SCENARIO HOST` prints one JSON line. The sequence is the one
libfranka's async example runs (configure with per-joint maximum velocities, then at
50 Hz: read the target feedback, set a target; stop_control at the end), written for
this project: the targets step between two poses around where the arm starts, and the
scenario records what the client saw (feedback statuses, q_d against the target).
"""

from __future__ import annotations

import math
import time

import pylibfranka as fr
import scenario_main  # tests/e2e/clients/scenario_main.py: the shared entry point

#: The example's caps: a quarter of the FR3's nameplate joint velocities [rad/s].
MAX_VELOCITIES = [0.655, 0.655, 0.655, 0.655, 1.315, 1.315, 1.315]
PERIOD = 0.020  # s: a target every 20 ms, the example's rate
OFFSET = 0.15  # rad: each target is the start pose +- this on every joint
#: s of wall time a target is held at most (0.3 rad at 0.655 rad/s takes ~0.55 s of the
#: robot's time; a loaded machine's server runs slower than its clock, down to ~0.5x)
HOLD = 10.0
#: periods a reached target is held on before the next (the robot stays there)
AFTER_REACHED = 10
TOLERANCE = 1e-3  # rad: libfranka's default goal tolerance


def handler(robot: fr.Robot, goal_tolerance: float = TOLERANCE):
    config = fr.AsyncPositionControlHandler.Configuration(
        maximum_joint_velocities=MAX_VELOCITIES, goal_tolerance=goal_tolerance
    )
    result = fr.AsyncPositionControlHandler.configure(robot, config)
    if result.error_message is not None:
        raise RuntimeError(f"configure failed: {result.error_message}")
    return result.handler


def target(q):
    return fr.AsyncPositionControlHandler.JointPositionTarget(joint_positions=list(q))


def scenario_sequence(host: str) -> dict:
    """Configure; feedback before any target; three targets, each sent at 50 Hz until reached
    and AFTER_REACHED periods more (HOLD s at most)
    (feedback, then target, per period); stop_control; the state afterwards; then a
    second asynchronous motion starts and stops at once (the robot took the first's end)."""
    robot = fr.Robot(host, fr.RealtimeConfig.kIgnore)
    start = list(robot.read_once().q)
    control = handler(robot)
    before = control.get_target_feedback()
    legs = []
    for sign in (1.0, -1.0, 1.0):
        goal = [q + sign * OFFSET for q in start]
        statuses, errors, reached_after = [], [], None
        t0 = time.monotonic()
        sent_once = False
        held = 0
        while time.monotonic() - t0 < HOLD and held < AFTER_REACHED:
            tick = time.monotonic()
            held += reached_after is not None
            feedback = control.get_target_feedback()
            if sent_once:  # (before that, the feedback is about the previous target)
                statuses.append(feedback.status.name)
            if feedback.error_message is not None:
                errors.append(feedback.error_message)
            if sent_once and feedback.status.name == "kTargetReached" and reached_after is None:
                reached_after = tick - t0
            sent = control.set_joint_position_target(target(goal))
            if sent.error_message is not None or not sent.was_successful:
                errors.append(sent.error_message)
            sent_once = True
            time.sleep(max(0.0, PERIOD - (time.monotonic() - tick)))
        legs.append(
            {
                "goal": goal,
                "statuses": sorted(set(statuses)),
                "last_status": statuses[-1],
                "reached_after": reached_after,
                "errors": errors,
            }
        )
    control.stop_control()
    after = control.get_target_feedback()
    state = robot.read_once()
    again = handler(robot)
    again.stop_control()
    final = robot.read_once()
    return {
        "start": start,
        "status_before_target": before.status.name,
        "legs": legs,
        "status_after_stop": after.status.name,
        "mode_after_stop": state.robot_mode.name,
        "q_d_after_stop": list(state.q_d),
        "dq_d_after_stop": list(state.dq_d),
        "last_motion_errors": str(state.last_motion_errors),
        "second_mode": final.robot_mode.name,
        "second_errors": str(final.last_motion_errors),
    }


def scenario_out_of_range(host: str) -> dict:
    """A target past joint 4's upper stop: what the feedback and the state say, and
    whether a further target is taken."""
    robot = fr.Robot(host, fr.RealtimeConfig.kIgnore)
    start = list(robot.read_once().q)
    control = handler(robot)
    control.get_target_feedback()
    goal = list(start)
    goal[3] = 0.1  # FR3 joint 4 range: [-3.0481, -0.1458] rad
    control.set_joint_position_target(target(goal))
    feedback = None
    for _ in range(50):
        time.sleep(PERIOD)
        feedback = control.get_target_feedback()
        if feedback.status.name == "kAborted":
            break
    state = robot.read_once()
    further = control.set_joint_position_target(target(start))
    return {
        "status": feedback.status.name,
        "feedback_error": feedback.error_message,
        "mode": state.robot_mode.name,
        "last_motion_errors": str(state.last_motion_errors),
        "further_successful": further.was_successful,
        "further_error": further.error_message,
        "q4": state.q[3],
        "start_q4": start[3],
    }


def scenario_sparse_targets(host: str) -> dict:
    """One target, then silence for 0.5 s (500 cycles with no datagram): the robot's
    generator answers the cycles, so no communication_constraints_violation; then the
    feedback at 50 Hz until TargetReached (the first states read after the silence are
    the oldest the socket kept)."""
    robot = fr.Robot(host, fr.RealtimeConfig.kIgnore)
    start = list(robot.read_once().q)
    control = handler(robot)
    control.get_target_feedback()
    goal = [q + 0.05 for q in start]
    control.set_joint_position_target(target(goal))
    time.sleep(0.5)
    statuses = []
    for _ in range(100):
        feedback = control.get_target_feedback()
        statuses.append(feedback.status.name)
        if feedback.status.name in ("kTargetReached", "kAborted"):
            break
        time.sleep(PERIOD)
    state = robot.read_once() if feedback.status.name == "kAborted" else None
    control.stop_control()
    final = robot.read_once()
    return {
        "status": feedback.status.name,
        "statuses": sorted(set(statuses)),
        "error": feedback.error_message,
        "mode_if_aborted": state.robot_mode.name if state else None,
        "final_mode": final.robot_mode.name,
        "final_errors": str(final.last_motion_errors),
        "distance": math.dist(final.q_d, goal),
    }


if __name__ == "__main__":
    scenario_main.run(globals())
