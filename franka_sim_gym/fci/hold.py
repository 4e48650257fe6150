"""The idle hold: what the robot's internal controller holds when no motion drives the arm.

docs/robot-state.md "The idle hold". The internal controllers track the desired
signals of the motion generator (libfranka ``docs/overview.rst``, "Motion
Generators": the joint impedance controller follows q_d, the Cartesian impedance
controller O_T_EE_d), and the state reports the "last desired" pose of motion
generation (``robot_state.h``, ``O_T_EE_d``). So when a motion ends the robot keeps
the servo that ran it, with its gains, on the motion's last desired configuration:

* a motion that finished (kSuccess) under an internal controller: its servo (joint or
  Cartesian impedance) on its last reference (q_d, or the IK solution of the last
  commanded pose), so a press on the table stays the press it was;
* a motion that ended otherwise (reflex, StopMove, preemption, a disconnect) or ran an
  external controller: the joint servo at the measured configuration -- nothing the
  robot commanded is left to hold, and a reflex releases what pressed;
* a Move holds on until its first command arrives (libfranka sends none on the first
  cycles, docs/libfranka-client.md §5: the robot holds its position until then), and a
  motion that ends before one keeps the hold it found; AutomaticErrorRecovery keeps it.

So every switch between the robot's controllers is continuous in what the physics sees:
the servo, its gains and its reference change only where a command says so.
"""

from __future__ import annotations

import numpy as np

from .modes import CARTESIAN_IMPEDANCE, JOINT_IMPEDANCE


class IdleHold:
    """The hold of n robots: reference, servo and gains, captured at each switch.

    Args:
        q: (n, 7) the configuration held at the start (the measured one).
        kp, kd: (n, 7) the joint servo's gains to hold with.
        stiffness: (n, 6) the Cartesian servo's K_x to hold with.
    """

    def __init__(self, q: np.ndarray, kp: np.ndarray, kd: np.ndarray, stiffness) -> None:
        n = len(q)
        #: (n, 7) the joint configuration held (the Cartesian servo holds its forward
        #: kinematics at K, and the configuration itself in its nullspace)
        self.q = np.array(q, dtype=np.float64)
        #: (n,) the holding servo, as the state's controller mode (JOINT_IMPEDANCE or
        #: CARTESIAN_IMPEDANCE)
        self.controller = np.full(n, JOINT_IMPEDANCE, dtype=np.uint8)
        #: (n, 7) the joint servo's gains, (n, 6) the Cartesian servo's stiffness
        self.kp = np.array(kp, dtype=np.float64)
        self.kd = np.array(kd, dtype=np.float64)
        self.stiffness = np.array(np.broadcast_to(stiffness, (n, 6)), dtype=np.float64)
        self._regroup()

    def keep(self, i: int, q, controller: int, kp, kd, stiffness) -> None:
        """From now on robot i is held at ``q`` by ``controller`` with these gains."""
        self.q[i] = q
        self.controller[i] = controller
        self.kp[i] = kp
        self.kd[i] = kd
        self.stiffness[i] = stiffness
        self._regroup()

    def _regroup(self) -> None:
        #: (n,) robots the Cartesian servo holds, and how many (at switches only)
        self.cartesian = self.controller == CARTESIAN_IMPEDANCE
        self.n_cartesian = int(np.count_nonzero(self.cartesian))


def held_by(
    generator_ended: bool, internal: bool, controller: int, reference: np.ndarray, measured
) -> tuple[np.ndarray, int]:
    """What a motion that drove the arm leaves to the hold: (configuration, servo).

    ``generator_ended``: the motion finished (kSuccess) with a generator's reference to
    hold (``reference``, its last q_d or IK solution); ``internal``: it ran an internal
    controller (``controller``). Otherwise the joint servo at the ``measured`` q.
    """
    if generator_ended and internal:
        return reference, controller
    return measured, JOINT_IMPEDANCE
