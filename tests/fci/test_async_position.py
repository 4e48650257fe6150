"""The asynchronous joint-position generator (docs/motion-limits.md "The asynchronous
generator"): Move acceptance, the profile's bounds, targets, the finish, and its errors."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.fci.errors import Error
from franka_sim_gym.fci.events import EventKind
from franka_sim_gym.fci.tables import FR3
from franka_sim_gym.fci.wire import ROBOT_COMMAND_DTYPE, MotionGeneratorMode, RobotMode
from franka_sim_gym.fci.wire.protocol import MoveStatus
from franka_sim_gym.sim.world import HOME_Q
from tests.fci_helpers import EXT, IMP, JP, JV, LoopClient, make_controller

CAPS = np.array([0.655, 0.655, 0.655, 0.655, 1.315, 1.315, 1.315])


class AsyncClient:
    """Plays pylibfranka's AsyncPositionControlHandler on robot 0, cycle by cycle."""

    def __init__(self, **config) -> None:
        config.setdefault("enforce_motion_limits", True)
        config.setdefault("enforce_comm_constraints", True)
        self.ctrl = make_controller(**config)
        self.command = np.zeros(1, dtype=ROBOT_COMMAND_DTYPE)
        self.events: list = []
        self.trace: list[tuple[np.ndarray, ...]] = []

    def start(self, caps=CAPS, generator=JP, controller=IMP) -> MoveStatus:
        return self.ctrl.move(0, int(controller), int(generator), True, tuple(caps))

    @property
    def state(self):
        return self.ctrl.states[0]

    def run(self, cycles: int, target=None, every: int = 20, finished=False, echo=None) -> None:
        """``cycles`` cycles; a datagram (``target``) every ``every`` cycles from the first."""
        for k in range(cycles):
            if target is not None and k % every == 0:
                self.command["q_c"][0] = target
                self.command["message_id"][0] = (
                    int(self.state["message_id"]) if echo is None else echo
                )
                self.command["motion_generation_finished"][0] = finished
                self.ctrl.receive(self.command, np.ones(1, dtype=bool))
            self.events += self.ctrl.step()
            s = self.state
            self.trace.append(
                (s["q_d"].astype(float), s["dq_d"].astype(float), s["ddq_d"].astype(float))
            )

    def statuses(self) -> list[int]:
        return [e.status for e in self.events if e.kind is EventKind.MOVE_FINISHED]

    def reached(self, target, tolerance: float = 1e-3) -> bool:
        """pylibfranka's TargetReached: |q_d - target| < tolerance and |dq_d| < 0.01 rad/s."""
        s = self.state
        return bool(
            np.linalg.norm(s["q_d"] - target) < tolerance and np.linalg.norm(s["dq_d"]) < 0.01
        )


@pytest.mark.parametrize(
    ("caps", "generator", "controller"),
    [
        ((np.nan,) + (0.5,) * 6, JP, IMP),
        ((-0.1,) + (0.5,) * 6, JP, IMP),
        ((0.0,) * 7, JP, IMP),
        (CAPS, JV, IMP),
        (CAPS, JP, EXT),
    ],
    ids=["nan-cap", "negative-cap", "all-zero", "joint-velocity", "external"],
)
def test_a_move_the_generator_cannot_run_is_an_invalid_argument(caps, generator, controller):
    c = AsyncClient()
    assert c.start(caps, generator, controller) == MoveStatus.kInvalidArgumentRejected
    assert int(c.state["robot_mode"]) == RobotMode.kIdle


def test_the_motion_runs_the_joint_position_generator_and_holds_until_a_target():
    c = AsyncClient()
    assert c.start() == MoveStatus.kMotionStarted
    assert int(c.state["motion_generator_mode"]) == MotionGeneratorMode.kJointPosition
    c.run(300)  # no datagram at all: the robot answers its own cycles
    assert int(c.state["robot_mode"]) == RobotMode.kMove
    np.testing.assert_allclose(c.state["q_d"], HOME_Q, atol=1e-6)
    assert not np.any(c.state["dq_d"])
    assert c.state["control_command_success_rate"] == 1.0
    assert c.ctrl.errors.sum() == 0 and c.statuses() == []


def test_a_target_is_reached_inside_the_caps_and_the_robots_limits():
    c = AsyncClient()
    caps = CAPS.copy()
    caps[2] = 0.2  # one joint slower than the others
    c.start(caps)
    target = HOME_Q + 0.3
    c.run(3000, target)
    assert c.reached(target)
    q, dq, ddq = (np.array(x) for x in zip(*c.trace, strict=True))
    assert np.all(np.abs(dq) <= caps + 1e-6)
    assert np.abs(dq[:, 2]).max() == pytest.approx(0.2, abs=1e-3)  # its cap is reached
    assert np.abs(ddq).max() <= 0.9 * FR3.ddq_max.max() + 1e-3
    jerk = np.diff(ddq, axis=0) / 1e-3
    assert np.abs(jerk).max() <= 0.9 * FR3.dddq_max.max() + 1.0
    assert np.all(np.sign(target - q[0]) * (q - target) <= 1e-6)  # no overshoot
    assert c.ctrl.violations.take().sum() == 0 and c.statuses() == []


def test_a_new_target_mid_motion_reverses_inside_the_limits():
    c = AsyncClient()
    c.start()
    c.run(300, HOME_Q + 0.3)  # at speed
    assert np.abs(c.state["dq_d"]).max() > 0.5
    c.trace.clear()
    target = HOME_Q - 0.3
    c.run(3000, target)
    assert c.reached(target)
    q, dq, ddq = (np.array(x) for x in zip(*c.trace, strict=True))
    assert np.all(dq[0] > 0.5) and np.all(dq[-1] == pytest.approx(0.0, abs=0.01))  # turned
    assert np.abs(ddq).max() <= 0.9 * FR3.ddq_max.max() + 1e-3
    assert np.all(q >= target - 1e-6)  # braked in time: no overshoot past the new target
    assert c.ctrl.violations.take().sum() == 0 and c.statuses() == []


@pytest.mark.parametrize("side", ["upper", "lower"])
def test_a_target_at_the_joint_stop_is_approached_inside_the_envelope(side):
    c = AsyncClient()
    c.start((2.6,) * 7)
    target = HOME_Q.copy()
    # joint 4's stops: -0.1458 rad (2.2 rad away), -3.0481 rad (0.7 rad away)
    target[3] = FR3.q_upper[3] if side == "upper" else FR3.q_lower[3]
    c.run(5000, target)
    q, dq, _ = (np.array(x) for x in zip(*c.trace, strict=True))
    upper, lower = FR3.velocity_envelope(q)
    assert np.all(dq[1:] <= upper[:-1]) and np.all(dq[1:] >= lower[:-1])  # at the previous q_d
    assert FR3.q_lower[3] < q[:, 3].min() and q[:, 3].max() < FR3.q_upper[3]
    assert abs(q[-1, 3] - target[3]) < 0.05  # it got close
    assert c.ctrl.violations.take().sum() == 0 and c.statuses() == []


@pytest.mark.parametrize("side", ["upper", "lower"])
def test_a_target_outside_the_joint_range_is_12_at_arrival(side):
    c = AsyncClient()
    c.start()
    target = HOME_Q.copy()
    # joint 4, 1 mrad past one of its stops (-0.1458 / -3.0481 rad)
    target[3] = FR3.q_upper[3] + 1e-3 if side == "upper" else FR3.q_lower[3] - 1e-3
    c.run(5, target)
    assert c.statuses() == [MoveStatus.kReflexAborted]
    assert int(c.state["robot_mode"]) == RobotMode.kReflex
    assert np.flatnonzero(c.ctrl.errors[0]).tolist() == [
        Error.joint_motion_generator_position_limits_violation
    ]
    np.testing.assert_allclose(c.state["q_d"], HOME_Q, atol=1e-6)  # it never headed there


def test_a_non_finite_target_is_refused_as_12():
    c = AsyncClient()
    c.start()
    target = HOME_Q.copy()
    target[0] = np.nan
    c.run(5, target)
    assert c.statuses() == [MoveStatus.kReflexAborted]
    assert np.flatnonzero(c.ctrl.errors[0]).tolist() == [
        Error.joint_motion_generator_position_limits_violation
    ]


def test_unenforced_a_bad_target_is_logged_and_ignored():
    c = AsyncClient(enforce_motion_limits=False)
    c.start()
    outside = HOME_Q.copy()
    outside[3] = 0.1
    c.run(100, outside)
    seen = c.ctrl.violations.take()[0]
    assert np.flatnonzero(seen).tolist() == [Error.joint_motion_generator_position_limits_violation]
    np.testing.assert_allclose(c.state["q_d"], HOME_Q, atol=1e-6)
    assert int(c.state["robot_mode"]) == RobotMode.kMove


def test_a_target_echoing_an_id_never_published_is_dropped():
    c = AsyncClient()
    c.start()
    c.run(200, HOME_Q + 0.2, echo=int(c.state["message_id"]) + 1000)
    np.testing.assert_allclose(c.state["q_d"], HOME_Q, atol=1e-6)
    assert c.statuses() == []


def test_a_target_echoing_a_state_before_the_motion_is_dropped():
    c = AsyncClient()
    for _ in range(5):
        c.ctrl.step()
    before = int(c.state["message_id"]) - 1  # an idle state published before the Move
    c.start()
    c.run(200, HOME_Q + 0.2, echo=before)
    np.testing.assert_allclose(c.state["q_d"], HOME_Q, atol=1e-6)
    assert c.statuses() == []


def test_finish_brakes_to_rest_without_jumping_to_the_zero_target():
    c = AsyncClient()
    c.start()
    c.run(400, HOME_Q + 0.3)  # moving at the caps
    moving = c.state["q_d"].astype(float)
    assert np.abs(c.state["dq_d"]).max() > 0.5
    c.trace.clear()
    c.run(400, np.zeros(7), every=1, finished=True)  # stop_control: zeros + finished
    assert c.statuses() == [MoveStatus.kSuccess]
    q, dq, ddq = (np.array(x) for x in zip(*c.trace, strict=True))
    ended = int(np.argmax(np.all(dq == 0, axis=1)))
    assert 0 < ended < 150  # braking took cycles (no jump to rest), not a run to the target
    assert np.abs(ddq).max() <= 0.9 * FR3.ddq_max.max() + 1e-3
    # Stopped within its braking distance, far from the zero target and short of the old one.
    assert np.abs(q[-1] - moving).max() < 0.05
    assert int(c.state["robot_mode"]) == RobotMode.kIdle
    assert c.ctrl.errors.sum() == 0
    np.testing.assert_allclose(c.ctrl.hold.q[0], q[ended - 1], atol=1e-6)


def test_after_an_asynchronous_motion_a_joint_motion_loses_cycles_as_usual():
    c = AsyncClient()
    c.start()
    c.run(100, HOME_Q + 0.05)
    assert c.ctrl.stop_move(0) is not None
    loop = LoopClient(c.ctrl)
    assert loop.start(JP) == MoveStatus.kMotionStarted
    q = c.state["q_d"].astype(float).copy()
    loop.send(q_c=q)
    for _ in range(25):
        loop.send(deliver=False)
    assert loop.move_statuses()[-1] == MoveStatus.kReflexAborted
    assert c.ctrl.errors[0, Error.communication_constraints_violation]


def test_two_robots_one_asynchronous_one_joint_motion_each_reach_their_own_targets():
    ctrl = make_controller(n=2, enforce_motion_limits=True, enforce_comm_constraints=True)
    assert ctrl.move(0, int(IMP), int(JP), True, tuple(CAPS)) == MoveStatus.kMotionStarted
    loop = LoopClient(ctrl, 1)
    assert loop.start(JP) == MoveStatus.kMotionStarted
    command = np.zeros(2, dtype=ROBOT_COMMAND_DTYPE)
    target = HOME_Q - 0.2
    q1 = ctrl.states["q_d"][1].astype(float).copy()
    for k in range(2000):
        command["message_id"] = ctrl.states["message_id"]
        command["q_c"][0] = target
        command["q_c"][1] = q1 + 0.1 * (1 - np.cos(np.pi * min(k / 1000, 1.0))) / 2
        mask = np.array([k % 20 == 0, True])  # robot 0: a target every 20 cycles
        ctrl.receive(command, mask)
        assert not ctrl.step()
    s = ctrl.states
    assert np.linalg.norm(s["q_d"][0] - target) < 1e-3 and np.linalg.norm(s["dq_d"][0]) < 0.01
    np.testing.assert_allclose(s["q_d"][1], q1 + 0.1, atol=1e-6)
    assert ctrl.errors.sum() == 0 and ctrl.violations.take().sum() == 0
