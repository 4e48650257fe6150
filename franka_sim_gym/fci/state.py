"""State assembly: where every RobotState field comes from, in one place.

The published states live in an (n,) array of the v10 wire dtype; the server
sends ``states[i].tobytes()`` and the env reads fields out of it. Per cycle we
write only what changes; configuration fields (F_T_EE, NE_T_EE, EE_T_K, loads)
are written when a setter changes them, constants once. docs/robot-state.md
lists every field with its source.
"""

from __future__ import annotations

import numpy as np

from ..sim.arm import ArmPhysics
from . import frames
from .tables import DELTA_T, GRAVITY
from .wire import ROBOT_STATE_DTYPE


class StateWriter:
    """Owns the (n,) RobotState array and the frames/loads reported in it."""

    def __init__(self, n: int) -> None:
        self.n = n
        self.states = np.zeros(n, dtype=ROBOT_STATE_DTYPE)
        s = self.states
        # Field views (structured-array fields are views: writing them writes the wire bytes).
        self._f = {name: s[name] for name in ROBOT_STATE_DTYPE.names}
        #: id of the last published state per robot (message ids start at 1: seed
        #: "The cycle contract" — the first state can be answered like any other)
        self.message_id = np.zeros(n, dtype=np.uint64)
        #: F_T_EE = F_T_NE · NE_T_EE (libfranka Robot::setEE), row-major 4x4 per robot
        self.F_T_EE = np.tile(np.eye(4), (n, 1, 1))
        self._F_T_EE_identity = np.ones(n, dtype=bool)
        self._tau_J_prev = np.zeros((n, 7))
        self._first = True
        # Constants: libfranka docs fix O_ddP_O at (0, 0, -9.81), and
        # Model::gravity(state) uses it as the gravity vector.
        self._f["O_ddP_O"][:] = GRAVITY
        for i in range(n):
            self.reset_configuration(i)

    # -- configuration fields -------------------------------------------------------------------

    def reset_configuration(self, i: int) -> None:
        """Identity frames, no load: a fresh connection's configuration."""
        for name in ("F_T_EE", "EE_T_K", "F_T_NE", "NE_T_EE"):
            self._f[name][i] = frames.IDENTITY16
        self.F_T_EE[i] = np.eye(4)
        self._F_T_EE_identity[i] = True
        self._f["m_load"][i] = 0.0
        self._f["F_x_Cload"][i] = 0.0
        self._f["I_load"][i] = 0.0

    def set_end_effector(self, i: int, NE_T_EE=None, EE_T_K=None) -> None:
        """SetNEToEE / SetEEToK: F_T_EE follows NE_T_EE (F_T_NE is identity: no hand configured)."""
        if NE_T_EE is not None:
            self._f["NE_T_EE"][i] = NE_T_EE
            F_T_NE = frames.from_wire(self._f["F_T_NE"][i].astype(np.float64))
            F_T_EE = F_T_NE @ frames.from_wire(NE_T_EE)
            self.F_T_EE[i] = F_T_EE
            self._F_T_EE_identity[i] = bool(np.array_equal(F_T_EE, np.eye(4)))
            self._f["F_T_EE"][i] = frames.to_wire(F_T_EE)
        if EE_T_K is not None:
            self._f["EE_T_K"][i] = EE_T_K

    def set_load(self, i: int, m_load: float, F_x_Cload: np.ndarray, I_load: np.ndarray) -> None:
        """SetLoad: reflected back in later states."""
        self._f["m_load"][i] = m_load
        self._f["F_x_Cload"][i] = F_x_Cload
        self._f["I_load"][i] = I_load

    # -- per-cycle fields -----------------------------------------------------------------------

    def O_T_EE(self, physics: ArmPhysics) -> np.ndarray:
        """Measured EE pose at F_T_EE, (n, 4, 4) row-major, in each arm's base frame."""
        pos, rot = physics.flange_pose()
        T = np.zeros((self.n, 4, 4))
        T[:, :3, :3] = rot
        T[:, :3, 3] = pos
        T[:, 3, 3] = 1.0
        if not self._F_T_EE_identity.all():
            T = T @ self.F_T_EE
        return T

    def write_cycle(
        self,
        physics: ArmPhysics,
        q_d: np.ndarray,
        dq_d: np.ndarray,
        ddq_d: np.ndarray,
        tau_J_d: np.ndarray,
        motion_generator_mode: np.ndarray,
        controller_mode: np.ndarray,
        robot_mode: np.ndarray,
        errors: np.ndarray,
        reflex_reason: np.ndarray,
        success_rate: np.ndarray,
    ) -> None:
        """Write state k+1 for all robots."""
        f = self._f
        self.message_id += 1
        f["message_id"][:] = self.message_id
        q, dq, tau_J = physics.q, physics.dq, physics.tau_J
        f["q"][:] = q
        f["theta"][:] = q  # no joint elasticity is modelled: motor side reads the link side
        f["dq"][:] = dq
        f["dtheta"][:] = dq
        f["tau_J"][:] = tau_J
        if self._first:
            self._first = False
        else:
            f["dtau_J"][:] = (tau_J - self._tau_J_prev) / DELTA_T
        self._tau_J_prev = tau_J
        f["q_d"][:] = q_d
        f["dq_d"][:] = dq_d
        f["ddq_d"][:] = ddq_d
        f["tau_J_d"][:] = tau_J_d
        O_T_EE = frames.to_wire(self.O_T_EE(physics))
        f["O_T_EE"][:] = O_T_EE
        # Idle and joint motions: the desired / commanded pose is the measured one.
        f["O_T_EE_d"][:] = O_T_EE
        f["O_T_EE_c"][:] = O_T_EE
        elbow = frames.elbow_of(q)
        f["elbow"][:] = elbow
        f["elbow_d"][:] = elbow
        f["elbow_c"][:] = elbow
        f["motion_generator_mode"][:] = motion_generator_mode
        f["controller_mode"][:] = controller_mode
        f["robot_mode"][:] = robot_mode
        f["errors"][:] = errors
        f["reflex_reason"][:] = reflex_reason
        f["control_command_success_rate"][:] = success_rate

    def write_modes(self, i, motion_generator_mode, controller_mode, robot_mode, errors, reflex):
        """Refresh one robot's mode bytes and error arrays between cycles."""
        f = self._f
        f["motion_generator_mode"][i] = motion_generator_mode
        f["controller_mode"][i] = controller_mode
        f["robot_mode"][i] = robot_mode
        f["errors"][i] = errors
        f["reflex_reason"][i] = reflex
