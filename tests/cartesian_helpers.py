"""Shared by the in-process Cartesian tests (tests/fci/cartesian/): a started
Cartesian motion, its start pose, its errors, and +x pose streams."""

from __future__ import annotations

import numpy as np

from franka_sim_gym.fci.errors import error_names
from franka_sim_gym.fci.wire import MoveMotionGeneratorMode, RobotMode
from franka_sim_gym.fci.wire.protocol import MoveStatus
from tests.fci_helpers import LoopClient, make_controller

CP = MoveMotionGeneratorMode.kCartesianPosition
CV = MoveMotionGeneratorMode.kCartesianVelocity
DT = 1e-3


def start(generator, **config) -> LoopClient:
    """A controller with ``config`` and a loop client whose ``generator`` motion started."""
    ctrl = make_controller(**config)
    client = LoopClient(ctrl)
    assert client.start(generator) == MoveStatus.kMotionStarted
    return client


def pose0(client: LoopClient) -> np.ndarray:
    """The pose a libfranka pose generator starts from: state.O_T_EE_d, as float64."""
    return np.array(client.state["O_T_EE_d"], dtype=np.float64)


def errors(client: LoopClient) -> tuple[str, ...]:
    """The printed names of the client's robot's current errors."""
    return error_names(client.state["errors"])


def ramp_x(client: LoopClient, T0, v_max, a_max, j_max, cycles):
    """A +x pose ramp by a jerk-limited profile (libfranka limitRate-style budgets);
    returns the cycle (1-based) of the first abort, or None."""
    T, v, a = T0.copy(), 0.0, 0.0
    for k in range(1, cycles + 1):
        # Brake the acceleration at the jerk budget in time to meet v_max without a step.
        if v + a * a / (2.0 * j_max) >= v_max - 1e-12:
            a = max(a - j_max * DT, 0.0)
        else:
            a = min(a + j_max * DT, a_max)
        v = min(v + a * DT, v_max)
        T = T.copy()
        T[12] += v * DT
        client.send(O_T_EE_c=T)
        if client.state["robot_mode"] != RobotMode.kMove:
            return k
    return None


def accelerate_x(client: LoopClient, a: float, cycles: int) -> None:
    """From rest at the start pose, accelerate along +x at ``a`` [m/s^2] at once."""
    T = pose0(client)
    client.send(O_T_EE_c=T)
    v = 0.0
    for _ in range(cycles):
        v += a * DT
        T = T.copy()
        T[12] += v * DT
        client.send(O_T_EE_c=T)
