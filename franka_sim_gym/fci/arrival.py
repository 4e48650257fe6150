"""Which arriving commands a cycle takes: fresh, late or answering nothing; finite.

docs/fci-behaviour.md "The cycle contract": a command answers the open cycle when it echoes the id
of the last published state (fresh); an older id of the running motion is late and still
applied; an id never published answers nothing (the cycle counts as lost). docs/fci-behaviour.md: a
non-finite command is refused whatever the enforcement, and reported as the
limits violation of the generator it arrived in; a Cartesian pose that is not a
homogeneous transformation (libfranka's isHomogeneousTransformation, NaN included)
is refused as 31; a non-finite elbow as 17.

The rules' only text is C (fci/_arrival.c, issue 38): :class:`Arrival` builds its plan
over the controller's arrays and logs what it found, at most once a second per robot
and kind (a client can send such commands every cycle).
"""

from __future__ import annotations

import numpy as np

from .. import native
from .frames import HOMOGENEOUS_TOL
from .log_limit import CycleLogLimit
from .modes import (
    CARTESIAN_POSITION,
    CARTESIAN_VELOCITY,
    EXTERNAL,
    JOINT_POSITION,
    JOINT_VELOCITY,
    NONE,
    Modes,
)
from .wire import ROBOT_COMMAND_DTYPE, RobotMode

_C = native.require("fci._arrival", "Arrival")

#: ``Arrival.arrive``'s code: some command answered nothing or was refused (to log) ...
LOG = 1
#: ... some late command of a joint or Cartesian generator is left to its generator
LATE = 2

#: The log's words for fci/_arrival.c's refusal reasons (REASON_*), by code.
REASONS = (
    None,
    "non-finite value in the commanded q_c",
    "non-finite value in the commanded dq_c",
    "non-finite value in the commanded O_T_EE_c",
    "non-finite value in the commanded O_dP_EE_c",
    "non-finite value in the commanded elbow_c",
    "non-finite value in the commanded tau_J_d",
    "the commanded O_T_EE_c is not a homogeneous transformation",
)

#: The RobotCommand fields the plan reads, in fci/_arrival.c's layout order.
_FIELDS = (
    "message_id",
    "q_c",
    "dq_c",
    "O_T_EE_c",
    "O_dP_EE_c",
    "elbow_c",
    "valid_elbow",
    "motion_generation_finished",
    "tau_J_d",
    "torque_command_finished",
)


class Arrival:
    """The arrival of RobotCommands at n robots: one C call a datagram batch.

    Args:
        modes: the robots' modes (their three uint8 arrays are read).
        published: (n,) ids of the last published states; ``first_id``: each motion's
            first id a command may echo (the accounting's).
        answered, started: the accounting's flags (written).
        cycle: the open cycle's input (its flags and joint candidates are written).
        cartesian: the Cartesian candidates (T_cmd, twist_cmd, elbow_cmd, elbow_valid).
    """

    def __init__(
        self,
        modes: Modes,
        published: np.ndarray,
        first_id: np.ndarray,
        answered: np.ndarray,
        started: np.ndarray,
        cycle,
        cartesian: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    ) -> None:
        n = modes.n
        #: (n,) the last ``arrive``'s late commands, accepted ones, ones answering nothing
        self.late = np.zeros(n, dtype=bool)
        self.accepted = np.zeros(n, dtype=bool)
        self.unanswerable = np.zeros(n, dtype=bool)
        #: (n,) why a command was refused (an index into REASONS; 0: it was not)
        self.reason = np.zeros(n, dtype=np.uint8)
        fields = ROBOT_COMMAND_DTYPE.fields
        layout = (ROBOT_COMMAND_DTYPE.itemsize, *(fields[name][1] for name in _FIELDS))
        values = (
            int(RobotMode.kMove),
            JOINT_POSITION,
            JOINT_VELOCITY,
            CARTESIAN_POSITION,
            CARTESIAN_VELOCITY,
            NONE,
            EXTERNAL,
        )
        self._plan = _C.Arrival(
            modes.robot_mode, modes.motion_generator_mode, modes.controller_mode,
            published, first_id, answered, started,
            cycle.have, cycle.finish, cycle.refused, cycle.refused_elbow, cycle.refused_torque,
            cycle.q_c, cycle.dq_c, cycle.tau_c, *cartesian,
            self.late, self.accepted, self.unanswerable, self.reason,
            layout, values, HOMOGENEOUS_TOL,
        )  # fmt: skip
        #: fci/_arrival.c's two entries (see its header)
        self.arrive = self._plan.arrive
        self.take = self._plan.take
        self.close = self._plan.close

    def log(self, commands: np.ndarray, published: np.ndarray, warnings: CycleLogLimit) -> None:
        """Log the last ``arrive``'s commands that answered nothing or were refused."""
        ids = commands["message_id"]
        for i in np.flatnonzero(self.unanswerable).tolist():
            warnings.warning(
                int(published[i]),
                ("unanswerable", i),
                "robot %d: command with message_id %d answers no state of the running motion "
                "(last published %d); counted as lost",
                i,
                int(ids[i]),
                int(published[i]),
            )
        for i in np.flatnonzero(self.reason).tolist():
            warnings.warning(
                int(published[i]),
                ("non-finite", i),
                "robot %d: %s; command refused",
                i,
                REASONS[int(self.reason[i])],
            )
