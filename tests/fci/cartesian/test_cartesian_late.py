"""Late Cartesian datagrams, in-process and cycle by cycle (docs/fci-behaviour.md "Communication
constraints", "A datagram that turns up late replaces the guess it stood in for").

The datagram an extrapolated run is missing rewinds the pose / twist history (and the
IK joint history) to the last real sample and is judged against it; any other late
datagram is judged against the history published in the state it answers, drives the
servo for its cycle and is never recorded; a fresh command after a real pause is
judged against the extrapolated reference.
"""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.fci import frames
from franka_sim_gym.fci.errors import ERROR_NAMES, Error, error_names
from franka_sim_gym.fci.wire import ROBOT_COMMAND_DTYPE, MoveMotionGeneratorMode, RobotMode
from franka_sim_gym.fci.wire.protocol import MoveStatus
from tests.fci_helpers import IMP, LoopClient, make_controller

CP = MoveMotionGeneratorMode.kCartesianPosition
CV = MoveMotionGeneratorMode.kCartesianVelocity
DT = 1e-3
#: the constant acceleration of the streams [m/s^2] (well inside every row)
A = 0.5


def start(generator, **config) -> LoopClient:
    client = LoopClient(make_controller(**config))
    assert client.start(generator) == MoveStatus.kMotionStarted
    return client


def pose0(client: LoopClient) -> np.ndarray:
    """The pose a libfranka pose generator starts from: state.O_T_EE_d, as float64."""
    return np.array(client.state["O_T_EE_d"], dtype=np.float64)


def fields_at(generator, T0: np.ndarray, k: int, jerk: float = 0.0) -> dict:
    """The k-th command of a stream along +x from rest at T0, at constant acceleration
    A (plus a constant ``jerk``, which the lost-cycle law does not continue): the pose
    x(k) = x0 + A t^2 / 2 + jerk t^3 / 6, or the twist v(k) = A t + jerk t^2 / 2."""
    t = k * DT
    if generator == CP:
        T = T0.copy()
        T[12] += 0.5 * A * t * t + jerk * t**3 / 6.0
        return {"O_T_EE_c": T}
    return {"O_dP_EE_c": [A * t + 0.5 * jerk * t * t, 0, 0, 0, 0, 0]}


def deliver(c: LoopClient, items: list[tuple[int, dict]]) -> None:
    """Several datagrams reaching the robot within one cycle, in the given order; then
    the cycle closes."""
    ctrl = c.ctrl
    command = np.zeros(1, dtype=ROBOT_COMMAND_DTYPE)
    for message_id, fields in items:
        command[0] = np.zeros((), dtype=ROBOT_COMMAND_DTYPE)
        command["message_id"][0] = message_id
        for name, value in fields.items():
            command[name][0] = value
        ctrl.receive(command, np.ones(1, dtype=bool))
    c.events += ctrl.step()


def history(c: LoopClient) -> np.ndarray:
    """Every value the next Cartesian command is differenced against (pose, twist,
    elbow, reported twist, IK joint history), as one row."""
    return c.ctrl.cartesian.reference.buffer[0].copy()


def names(seen: np.ndarray) -> set[str]:
    return {ERROR_NAMES[int(e)] for e in np.flatnonzero(seen[0])}


def stream_with_stall(generator, reorder=None, jerk: float = 0.0, **config) -> LoopClient:
    """100 cycles of the stream, then its receive path stalls for 6 cycles (the client
    answered every state; nothing arrived, the robot extrapolated); the backlog arrives
    within one cycle with the fresh answer last (``reorder``: which of the stalled ones,
    in which order), then 13 more cycles. 120 commands in all, as ``undelayed``."""
    c = start(generator, **config)
    T0 = pose0(c)
    for k in range(100):
        c.send(**fields_at(generator, T0, k, jerk))
    stalled = []
    for k in range(100, 106):
        stalled.append((int(c.state["message_id"]), fields_at(generator, T0, k, jerk)))
        c.send(deliver=False)
    now = int(c.state["message_id"])
    backlog = reorder(stalled) if reorder else stalled
    deliver(c, [*backlog, (now, fields_at(generator, T0, 106, jerk))])
    reference = c.ctrl.cartesian.reference
    # the fresh answer was the last real sample, the run of guesses is gone
    assert (int(reference.real_echo[0]), int(reference.run[0])) == (now, 0)
    for k in range(107, 120):
        c.send(**fields_at(generator, T0, k, jerk))
    return c


def undelayed(generator, jerk: float = 0.0, **config) -> LoopClient:
    c = start(generator, **config)
    T0 = pose0(c)
    for k in range(120):
        c.send(**fields_at(generator, T0, k, jerk))
    return c


# -- the rewind --------------------------------------------------------------------------------


@pytest.mark.parametrize("jerk", [0.0, 5.0], ids=["constant-acceleration", "constant-jerk"])
@pytest.mark.parametrize("generator", [CP, CV], ids=["pose", "twist"])
def test_a_backlog_draining_in_order_gets_the_rewind_no_error_and_the_undelayed_history(
    generator, jerk
):
    c = stream_with_stall(generator, jerk=jerk, enforce_motion_limits=True)
    assert c.state["robot_mode"] == RobotMode.kMove
    assert not c.ctrl.violations.take().any()
    assert c.ctrl.accounting.lost_total[0] == 6
    # every stalled datagram replaced the guess it stood in for: the history is the one
    # the undelayed stream built, bit for bit (the guesses are exact only to rounding,
    # and not at all under a jerk)
    expected = undelayed(generator, jerk=jerk, enforce_motion_limits=True)
    np.testing.assert_array_equal(history(c), history(expected))
    assert c.state["O_T_EE_c"].tobytes() == expected.state["O_T_EE_c"].tobytes()
    assert c.state["O_dP_EE_c"].tobytes() == expected.state["O_dP_EE_c"].tobytes()


@pytest.mark.parametrize("generator", [CP, CV], ids=["pose", "twist"])
def test_a_reordered_backlog_is_judged_against_the_states_it_answers_and_drains_clean(
    generator,
):
    # The run's oldest datagram comes last: the others are judged against the guesses
    # published in the states they answer (exact for this stream), then it rewinds.
    c = stream_with_stall(generator, reorder=lambda s: s[1:] + s[:1], enforce_motion_limits=True)
    assert c.state["robot_mode"] == RobotMode.kMove
    assert not c.ctrl.violations.take().any()


@pytest.mark.parametrize("generator", [CP, CV], ids=["pose", "twist"])
def test_a_partial_backlog_is_guessed_again_up_to_the_present(generator):
    """Only the first 3 of 6 stalled datagrams ever arrive: each rewinds, and the cycles
    from the last of them to the present are guessed again from it, so the fresh command
    is differenced against a history that stands for the state it answers (left 3
    cycles behind, its one-cycle velocity would be four times the stream's)."""
    c = stream_with_stall(generator, reorder=lambda s: s[:3], enforce_motion_limits=True)
    assert c.state["robot_mode"] == RobotMode.kMove
    assert not c.ctrl.violations.take().any()
    # the guesses are exact to rounding for this stream: the undelayed history, nearly
    # (the IK's second differences amplify the solver's last bits by 1 / dt^2)
    expected = undelayed(generator, enforce_motion_limits=True)
    np.testing.assert_allclose(history(c), history(expected), rtol=1e-6, atol=1e-8)


def test_a_rewinding_datagram_is_judged_by_every_row_including_the_joint_side():
    """The stalled stream starts accelerating at 2 m/s^2 at once: a Cartesian jerk of
    2000 m/s^3 (< 4500) but an IK joint jerk of ~6500 rad/s^3 (> 5000): the rewinding
    datagram, differenced against the real sample at rest, trips 30 alone. (Left to the
    fresh command against the at-rest guesses it would have been a Cartesian jerk of
    8000 m/s^3: 20.)"""
    c = start(CP, enforce_motion_limits=True)
    T0 = pose0(c)
    for _ in range(50):
        c.send(O_T_EE_c=T0)
    stalled, T, v = [], T0.copy(), 0.0
    for _ in range(3):
        v += 2.0 * DT
        T = T.copy()
        T[12] += v * DT
        stalled.append((int(c.state["message_id"]), {"O_T_EE_c": T}))
        c.send(deliver=False)
    v += 2.0 * DT
    T = T.copy()
    T[12] += v * DT
    deliver(c, [*stalled, (int(c.state["message_id"]), {"O_T_EE_c": T})])
    assert error_names(c.state["errors"]) == (
        "cartesian_motion_generator_joint_acceleration_discontinuity",
    )
    assert c.move_statuses() == [MoveStatus.kReflexAborted]


# -- replays, duplicates: judged, applied for the cycle, never recorded ------------------------


@pytest.mark.parametrize("generator", [CP, CV], ids=["pose", "twist"])
def test_replays_and_duplicates_never_touch_the_history_and_are_judged_clean(generator):
    c = start(generator)
    T0 = pose0(c)
    for k in range(50):
        c.send(**fields_at(generator, T0, k))
    now = int(c.state["message_id"])
    # a replay of the datagram that answered 20 states ago, a duplicate of the last
    # one, then the regular fresh one, all in one cycle
    deliver(
        c,
        [
            (now - 20, fields_at(generator, T0, 30)),
            (now - 1, fields_at(generator, T0, 49)),
            (now, fields_at(generator, T0, 50)),
        ],
    )
    for k in range(51, 60):
        c.send(**fields_at(generator, T0, k))
    # each was judged against the history published in the state it answers, where it
    # is consistent (against the history as it stands, both would be discontinuities)
    assert not c.ctrl.violations.take().any()
    # and none of them is a sample of the trajectory: the history is the stream's own
    c2 = start(generator)
    for k in range(60):
        c2.send(**fields_at(generator, T0, k))
    np.testing.assert_array_equal(history(c), history(c2))
    # they answered nothing: the window counts the fresh ones only
    assert c.state["control_command_success_rate"] == pytest.approx(1.0)


@pytest.mark.parametrize(
    "generator, error",
    [
        (CP, Error.cartesian_motion_generator_velocity_discontinuity),
        (CV, Error.cartesian_motion_generator_acceleration_discontinuity),
    ],
    ids=["pose", "twist"],
)
def test_an_inconsistent_replay_is_judged_and_reported_and_leaves_the_history(generator, error):
    """An old id carrying today's command: 20 cycles of motion in one against the state
    it answers (pose: a 0.41 m/s step in one cycle is 19; twist: a 0.01 m/s step is an
    acceleration of 10 m/s^2, 20)."""
    c = start(generator)  # enforcement off: logged, not aborted
    T0 = pose0(c)
    for k in range(50):
        c.send(**fields_at(generator, T0, k))
    now = int(c.state["message_id"])
    before = history(c)
    c.send(deliver=False)  # the next cycle is lost: it is extrapolated ...
    guessed = history(c)
    assert not np.array_equal(guessed, before)
    # ... and in the one after, only the replay arrives
    deliver(c, [(now - 20, fields_at(generator, T0, 70))])
    assert names(c.ctrl.violations.take()) == {ERROR_NAMES[error]}
    assert c.state["robot_mode"] == RobotMode.kMove
    # the replay was not recorded: this cycle was extrapolated like the one before
    expected = start(generator)
    for k in range(50):
        expected.send(**fields_at(generator, T0, k))
    expected.send(deliver=False)
    expected.send(deliver=False)
    np.testing.assert_array_equal(history(c), history(expected))


def test_an_inconsistent_replay_aborts_under_enforcement():
    c = start(CP, enforce_motion_limits=True)
    T0 = pose0(c)
    for k in range(50):
        c.send(**fields_at(CP, T0, k))
    now = int(c.state["message_id"])
    deliver(c, [(now - 20, fields_at(CP, T0, 70)), (now, fields_at(CP, T0, 50))])
    assert error_names(c.state["errors"]) == ("cartesian_motion_generator_velocity_discontinuity",)
    assert c.move_statuses() == [MoveStatus.kReflexAborted]


def test_a_late_pose_drives_the_servo_for_its_cycle_unless_a_fresh_one_arrives():
    c = start(CP)
    T0 = pose0(c)
    cartesian = c.ctrl.cartesian
    solutions = {}  # the IK solution each published state carried
    for k in range(50):
        c.send(**fields_at(CP, T0, k))
        solutions[int(c.state["message_id"])] = cartesian.reference.q_ik[0].copy()
    late_id = int(c.state["message_id"]) - 3  # echoes a state the history is built on
    late_T = fields_at(CP, T0, 47)["O_T_EE_c"].copy()
    late_T[13] += 1e-4  # its intent: 0.1 mm off the stream
    # the IK of the late pose, solved from the solution of the state it answers
    target = frames.from_wire(late_T[None])
    intent = cartesian.stepper.kinematics.solve(target, solutions[late_id][None]).q[0]
    deliver(c, [(late_id, {"O_T_EE_c": late_T})])
    # the cycle was lost: the history is the extrapolated one, the servo had the intent
    np.testing.assert_array_equal(c.ctrl.servo_q[0], intent)
    assert not np.array_equal(cartesian.reference.q_ik[0], intent)
    # with a fresh command in the same cycle, the fresh one is the servo's target
    now = int(c.state["message_id"])
    deliver(c, [(late_id, {"O_T_EE_c": late_T}), (now, fields_at(CP, T0, 51))])
    np.testing.assert_array_equal(c.ctrl.servo_q[0], cartesian.reference.q_ik[0])
    # and in the next cycle, without any late datagram, the history drives it again
    c.send(**fields_at(CP, T0, 52))
    np.testing.assert_array_equal(c.ctrl.servo_q[0], cartesian.reference.q_ik[0])


# -- a real pause: no rewind -------------------------------------------------------------------


@pytest.mark.parametrize("generator", [CP, CV], ids=["pose", "twist"])
def test_a_fresh_command_after_a_real_pause_is_judged_against_the_extrapolated_reference(
    generator,
):
    """The trap: the client pauses (nothing is sent), the reference keeps moving, and the
    client resumes where *it* left off: differenced against the extrapolation, unrewound
    (pose: the 5 mm/s the reference travelled is undone in one cycle, 19; twist: the
    twist falls back by 10 cycles of 0.5 m/s^2, 20)."""
    expected = {
        CP: ("cartesian_motion_generator_velocity_discontinuity",),
        CV: ("cartesian_motion_generator_acceleration_discontinuity",),
    }[generator]
    c = start(generator, enforce_motion_limits=True)
    T0 = pose0(c)
    for k in range(200):
        c.send(**fields_at(generator, T0, k))
    for _ in range(10):
        c.send(deliver=False)
    c.send(**fields_at(generator, T0, 200))
    assert error_names(c.state["errors"]) == expected
    # the remedy: resuming on the stream's clock (its waypoint for this cycle) is clean
    c = start(generator, enforce_motion_limits=True)
    for k in range(200):
        c.send(**fields_at(generator, T0, k))
    for _ in range(10):
        c.send(deliver=False)
    c.send(**fields_at(generator, T0, 210))
    assert c.state["robot_mode"] == RobotMode.kMove
    assert not c.ctrl.violations.take().any()


# -- several arms --------------------------------------------------------------------------------


def _two_arms(stall: bool) -> np.ndarray:
    """Arm 0 streams poses, arm 1 twists, in one controller; with ``stall`` arm 0's
    datagrams of 6 cycles arrive as a backlog in the 7th. Returns both histories."""
    ctrl = make_controller(n=2, enforce_motion_limits=True)
    for i, generator in enumerate((CP, CV)):
        assert ctrl.move(i, int(IMP), int(generator)) == MoveStatus.kMotionStarted
    ctrl.step()
    ctrl.step()
    T0 = ctrl.states["O_T_EE_d"][0].astype(np.float64)
    command = np.zeros(2, dtype=ROBOT_COMMAND_DTYPE)
    backlog = []

    def fill(i: int, generator, k: int, message_id: int) -> None:
        command[i] = np.zeros((), dtype=ROBOT_COMMAND_DTYPE)
        command["message_id"][i] = message_id
        for name, value in fields_at(generator, T0, k).items():
            command[name][i] = value

    for k in range(120):
        now = int(ctrl.states["message_id"][0])
        fill(1, CV, k, now)
        if stall and 100 <= k < 106:
            backlog.append((k, now))  # arm 0's datagram is held up
            ctrl.receive(command, np.array([False, True]))
        else:
            if stall and k == 106:  # it arrives, in order, before the fresh one
                for k_late, id_late in backlog:
                    fill(0, CP, k_late, id_late)
                    ctrl.receive(command, np.array([True, False]))
            fill(0, CP, k, now)
            ctrl.receive(command, np.ones(2, dtype=bool))
        ctrl.step()
    assert (ctrl.modes.robot_mode == int(RobotMode.kMove)).all()
    assert not ctrl.violations.take().any()
    return ctrl.cartesian.reference.buffer.copy()


def test_a_backlog_on_one_arm_rewinds_that_arm_alone():
    np.testing.assert_array_equal(_two_arms(stall=True), _two_arms(stall=False))
