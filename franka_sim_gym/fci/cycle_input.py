"""What one cycle hands the generators: the commands that arrived and who is where.

The controller fills a :class:`CycleInput` as datagrams arrive (``receive``: the
X
each generator reads what it needs and clears ``first`` for the robots whose opening
command it judged. Nothing else of the controller is visible to them.
"""

from __future__ import annotations

import numpy as np


class CycleInput:
    """The open cycle's command candidates of n robots (the last datagram applied wins)."""

    def __init__(self, n: int) -> None:
        self.n = n
        #: (n, 7) commanded joint positions, velocities and torques
        self.q_c = np.zeros((n, 7))
        self.dq_c = np.zeros((n, 7))
        self.tau_c = np.zeros((n, 7))
        #: (n,) a command answering this cycle arrived (and was accepted)
        self.have = np.zeros(n, dtype=bool)
        #: (n,) the motion's opening command has not been judged yet
        self.first = np.zeros(n, dtype=bool)
        #: (n,) a non-finite command arrived (refused whatever the enforcement)
        self.refused = np.zeros(n, dtype=bool)
        #: (n,) of those, a Cartesian command refused for its elbow alone (named 17)
        self.refused_elbow = np.zeros(n, dtype=bool)
        #: (n,) of those, a generator's command under an external controller refused for
        #: its torque alone (named 34, as a torque-only command's)
        self.refused_torque = np.zeros(n, dtype=bool)
        #: (n,) the command that arrived ends the motion (motion_generation_finished)
        self.finish = np.zeros(n, dtype=bool)

    def start(self, i: int) -> None:
        """Robot i opens a motion: nothing arrived yet, its first command is pending."""
        self.have[i] = self.finish[i] = self.refused[i] = False
        self.first[i] = True

    def clear(self, i: int) -> None:
        """Robot i's motion ended: nothing pending."""
        self.have[i] = self.finish[i] = self.first[i] = self.refused[i] = False
