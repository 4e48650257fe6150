"""State assembly: where every RobotState field comes from, in one place.

The published states live in an (n,) array of the v10 wire dtype; the server
sends ``states[i].tobytes()`` and the env reads fields out of it.

All 320 float32 values of the wire state (bytes 8..1287: O_T_EE ... dtheta)
have a float64 *shadow* (n, 320) in the same order. The controller computes
into named views of the shadow in place (q_d / dq_d / ddq_d and tau_J_d live
there), and publishing is one C call (fci/_publish.c) that casts the shadow into
the wire bytes: the hot path pays one call per field it changes, not one per field.
Mode bytes and error arrays are written only when they change.
docs/robot-state.md lists every field with its source.
"""

from __future__ import annotations

import numpy as np

from .. import native
from ..sim.arm import ArmPhysics
from . import frames
from .tables import DELTA_T, GRAVITY
from .wire import ROBOT_STATE_DTYPE, ROBOT_STATE_SIZE

#: the measured joint fields' one text (fci/_measured.c)
_MEASURED = native.require("fci._measured", "measured")
#: what publishing a state copies, its one text (fci/_publish.c)
_PUBLISH = native.require("fci._publish", "Publishing")
#: dtau_J's backward difference over one cycle, as a factor (1 / dt)
_RATE = 1.0 / DELTA_T

_FLOAT_BEGIN, _FLOAT_END = 8, 1288  # docs/wire-protocol.md §7: O_T_EE ... dtheta, all float32


class StateWriter:
    """Owns the (n,) RobotState array, its float64 shadow and the reported frames and loads."""

    def __init__(self, n: int, ee_load=None) -> None:
        self.n = n
        #: the mounted hand's mass, centre of mass, inertia and TCP (sim.hand_load.HandLoad),
        #: reported in m_ee / F_x_Cee / I_ee / F_T_NE; None for a bare flange
        self.ee_load = ee_load
        #: the nominal end effector (row-major): the hand's TCP, as Desk configures it
        #: for a mounted Franka Hand; identity on a bare flange
        self.F_T_NE = np.eye(4) if ee_load is None else np.array(ee_load.F_T_NE, dtype=np.float64)
        self.states = np.zeros(n, dtype=ROBOT_STATE_DTYPE)
        self.shadow = np.zeros((n, (_FLOAT_END - _FLOAT_BEGIN) // 4))
        views = {}
        for name in ROBOT_STATE_DTYPE.names:
            dtype, offset = ROBOT_STATE_DTYPE.fields[name][:2]
            if dtype.base == np.dtype("<f4") and _FLOAT_BEGIN <= offset < _FLOAT_END:
                start = (offset - _FLOAT_BEGIN) // 4
                size = dtype.itemsize // 4
                views[name] = self.shadow[:, start : start + size].reshape(n, *dtype.shape)
        #: float64 views of every float field of the state, by wire name
        self.field = views
        self.q, self.dq, self.theta, self.dtheta = (
            views[k] for k in ("q", "dq", "theta", "dtheta")
        )
        self.q_d, self.dq_d, self.ddq_d = views["q_d"], views["dq_d"], views["ddq_d"]
        #: the shadow's columns from q_d to ddq_d (q_d, dq, dq_d, ddq_d: adjacent on the
        #: wire), and where q_d, dq_d and ddq_d start in it: the commanded reference in one
        #: slice, which the joint reference's ring copies at once
        first = ROBOT_STATE_DTYPE.fields["q_d"][1]
        end = ROBOT_STATE_DTYPE.fields["ddq_d"][1] + 7 * 4
        a = (first - _FLOAT_BEGIN) // 4
        self.reference_columns = (
            self.shadow[:, a : a + (end - first) // 4],
            tuple((ROBOT_STATE_DTYPE.fields[k][1] - first) // 4 for k in ("q_d", "dq_d", "ddq_d")),
        )
        self.tau_J, self.tau_J_d, self.dtau_J = views["tau_J"], views["tau_J_d"], views["dtau_J"]
        self.O_T_EE, self.O_T_EE_d, self.O_T_EE_c = (
            views[k] for k in ("O_T_EE", "O_T_EE_d", "O_T_EE_c")
        )
        self.elbow, self.elbow_d, self.elbow_c = views["elbow"], views["elbow_d"], views["elbow_c"]
        #: id of the last published state per robot (message ids start at 1: docs/fci-behaviour.md
        #: "The cycle contract" — the first state can be answered like any other)
        self.message_id = np.zeros(n, dtype=np.uint64)
        #: F_T_EE = F_T_NE · NE_T_EE (libfranka Robot::setEE), row-major 4x4 per robot
        self.F_T_EE = np.tile(np.eye(4), (n, 1, 1))
        self._custom_ee = np.zeros(n, dtype=bool)
        self.any_custom_ee = False
        # O_T_EE's constant entries (bottom row 0 0 0 1 in column-major).
        self.O_T_EE[:, 15] = 1.0
        # libfranka docs fix O_ddP_O at (0, 0, -9.81), and Model::gravity(state)
        # uses it as the gravity vector.
        views["O_ddP_O"][:] = GRAVITY
        fields = ROBOT_STATE_DTYPE.fields
        self._publishing = _PUBLISH.Publishing(
            self.O_T_EE, self.O_T_EE_d, self.O_T_EE_c, self.elbow, self.elbow_d, self.elbow_c,
            self.q_d, self.shadow, self.states, self.message_id,
            (ROBOT_STATE_SIZE, _FLOAT_BEGIN, fields["message_id"][1],
             fields["control_command_success_rate"][1]),
        )  # fmt: skip
        for i in range(n):
            self.reset_configuration(i)

    # -- configuration fields -------------------------------------------------------------------

    def reset_configuration(self, i: int) -> None:
        """A fresh connection's configuration: what a client sets is reset, Desk's stays.

        NE_T_EE and EE_T_K return to identity and the payload to none; the
        nominal end effector F_T_NE and the end-effector load (Desk's, on the
        robot: the mounted hand here) stay, so F_T_EE = F_T_NE.
        """
        for name in ("EE_T_K", "NE_T_EE"):
            self.field[name][i] = frames.IDENTITY16
        self._set_F_T_EE(i, self.F_T_NE)
        self.field["F_T_NE"][i] = frames.to_wire(self.F_T_NE)
        for name in ("m_load", "F_x_Cload", "I_load"):
            self.field[name][i] = 0.0
        load = self.ee_load
        if load is not None:  # the hand the arm carries (its weight is in the measured tau_J)
            self.field["m_ee"][i] = load.m_ee
            self.field["F_x_Cee"][i] = load.F_x_Cee
            self.field["I_ee"][i] = load.I_ee_wire()

    def set_end_effector(self, i: int, NE_T_EE=None, EE_T_K=None) -> None:
        """SetNEToEE / SetEEToK: F_T_EE = F_T_NE · NE_T_EE (libfranka Robot::setEE).

        NE_T_EE is relative to the nominal end effector: with the hand mounted,
        to its TCP, as on a robot whose Desk configures the Franka Hand.
        """
        if NE_T_EE is not None:
            self.field["NE_T_EE"][i] = NE_T_EE
            self._set_F_T_EE(
                i, self.F_T_NE @ frames.from_wire(np.asarray(NE_T_EE, dtype=np.float64))
            )
        if EE_T_K is not None:
            self.field["EE_T_K"][i] = EE_T_K

    def _set_F_T_EE(self, i: int, F_T_EE: np.ndarray) -> None:
        """Robot i's EE frame (row-major), where write_measured measures O_T_EE."""
        self.F_T_EE[i] = F_T_EE
        self._custom_ee[i] = not np.array_equal(F_T_EE, np.eye(4))
        self.any_custom_ee = bool(self._custom_ee.any())
        self.field["F_T_EE"][i] = frames.to_wire(F_T_EE)

    def set_load(self, i: int, m_load: float, F_x_Cload: np.ndarray, I_load: np.ndarray) -> None:
        """SetLoad: reflected back in later states."""
        self.field["m_load"][i] = m_load
        self.field["F_x_Cload"][i] = F_x_Cload
        self.field["I_load"][i] = I_load

    # -- per-cycle fields -----------------------------------------------------------------------

    def write_measured(self, physics: ArmPhysics, noise: np.ndarray | None = None) -> None:
        """This cycle's physics into q, dq, theta, dtheta, tau_J, dtau_J (plus the sensors'
        ``noise``, (n, 21) q | dq | tau_J, or None: fci/_measured.c, their one text), then
        O_T_EE and the elbow from the measured q."""
        _MEASURED.measured(
            physics.q, physics.dq, physics.tau_J, noise, self.q, self.theta, self.dq,
            self.dtheta, self.tau_J, self.dtau_J, _RATE,
        )  # fmt: skip
        self.write_pose(physics, self.q)

    def write_pose(self, physics: ArmPhysics, q: np.ndarray) -> None:
        """O_T_EE from the physics' flange (and F_T_EE), the elbow from the joints ``q``."""
        # Straight from MjData's arrays (the flange's position and rotation transposed:
        # bases at their worlds' origins), the elbow (q_3, the sign of q_4: docs/
        # fci-behaviour.md "RobotState fields"), one C call (fci/_publish.c).
        position, rotation = physics.flange_views
        self._publishing.pose(position, rotation, q)
        if self.any_custom_ee:
            pose = self.O_T_EE
            pose[...] = frames.to_wire(frames.from_wire(pose) @ self.F_T_EE)

    def copy_for_publish(self, q: np.ndarray, keeps_q_d: np.ndarray) -> None:
        """docs/fci-behaviour.md "RobotState fields": the desired and commanded pose and
        elbow are the measured ones (a Cartesian generator writes its own after this),
        and q_d is the measured ``q`` (n, 7) but where ``keeps_q_d`` ((n,) bool: a joint
        generator's or an external controller's motion holds a reference). One C call
        (fci/_publish.c)."""
        self._publishing.copies(q, keeps_q_d)

    def publish(self, success_rate: np.ndarray | None) -> None:
        """Make state k+1 the published one: new message id, floats cast to the wire.

        The history the next command is differenced against stays float64 (docs/fci-behaviour.md: a
        constant-acceleration stream is extrapolated onto its own waypoints exactly); the wire
        carries it rounded to float32 (fci/_publish.c, one call).
        """
        self._publishing.publish(success_rate)

    def write_modes(self, i, motion_generator_mode, controller_mode, robot_mode, errors, reflex):
        """Write one robot's mode bytes and error arrays (they change only at transitions)."""
        s = self.states
        s["motion_generator_mode"][i] = motion_generator_mode
        s["controller_mode"][i] = controller_mode
        s["robot_mode"][i] = robot_mode
        s["errors"][i] = errors
        s["reflex_reason"][i] = reflex
