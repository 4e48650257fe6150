"""Joint friction in the FR3's drives: the law Gaz et al. identified on the Panda.

C. Gaz, M. Cognetti, A. Oliva, P. Robuffo Giordano, A. De Luca, "Dynamic Identification
of the Franka Emika Panda Robot With Retrieval of Feasible Parameters Using Penalty-Based
Optimization", IEEE RA-L 4(4), 2019: the measured joint torques carry, besides the rigid
body's M ddq + C dq + g, a friction torque per joint

    tau_f(dq) = A / (1 + exp(-alpha (dq + phi))) - A / (1 + exp(-alpha phi)),

zero at rest, rising like a smoothed Coulomb friction of about A / 2 either way. Written
here with 1 / (1 + e^-x) = (1 + tanh(x / 2)) / 2, the same function:

    tau_f(dq) = A / 2 (tanh(alpha / 2 (dq + phi)) - tanh(alpha phi / 2)).

The physics applies ``scale`` times it against the motion (sim/truth.py); the robot adds
its own compensation, ``compensation`` times it on its measured velocity, to every torque
it commands (libfranka docs, "Under the hood": tau_c = tau_d + tau_f + tau_g, "tau_f the
torque to compensate the motor friction"; fci/reality/).
"""

from __future__ import annotations

import numpy as np

from .. import native

#: The law's one text (sim/_truth.c ``friction``; issue 38).
RULES = native.require("sim._truth", "friction", "link_weights", "Forces", "Friction")

#: Gaz et al. 2019's friction parameters, joints 1..7, as the authors publish them with
#: their model (github.com/marcocognetti/FrankaEmikaPandaDynModel,
#: cpp/panda_dyn_model_example/include/franka_model.h, FI_1i, FI_2i, FI_3i):
#: A [Nm], alpha [s/rad], phi [rad/s].
GAZ_A = np.array([0.54615, 0.87224, 0.64068, 1.2794, 0.83904, 0.30301, 0.56489])
GAZ_ALPHA = np.array([5.1181, 9.0657, 10.136, 5.5903, 8.3469, 17.133, 10.336])
GAZ_PHI = np.array([0.039533, 0.025882, -0.04607, 0.036194, 0.026226, -0.021047, 0.0035526])
for _a in (GAZ_A, GAZ_ALPHA, GAZ_PHI):
    _a.flags.writeable = False


class JointFriction:
    """The friction law of n robots, scaled per robot and joint (:meth:`set_scale`):
    ``torque(dq)`` is the module docstring's tau_f(dq) times the scale, in one C call
    (sim/_truth.c).

    Args:
        n: robots.
    """

    def __init__(self, n: int) -> None:
        #: (n, 7) the factor on Gaz et al.'s A / 2 (the sign and the scale)
        self.gain = np.zeros((n, 7))
        self._half_alpha = np.broadcast_to(GAZ_ALPHA / 2.0, (n, 7)).copy()
        self._shift = self._half_alpha * GAZ_PHI
        self.out = np.zeros((n, 7))
        # (the arrays are changed in place only: one tuple serves every call)
        self._terms = (self.gain, self._half_alpha, self._shift)
        self._tail = (*self._terms, self.out)

    def set_scale(self, robots, scale) -> None:
        """The friction of ``robots`` is ``scale`` (rows, (k, 7)) times Gaz et al.'s."""
        self.gain[robots] = np.asarray(scale) * (GAZ_A / 2.0)

    def torque(self, dq: np.ndarray) -> np.ndarray:
        """(n, 7) the friction torque at joint velocity ``dq`` (``out``, overwritten by
        the next call)."""
        return RULES.friction(dq, *self._tail)

    def planned(self, dq: np.ndarray):
        """The law at the velocity array ``dq`` (n, 7; its values change, not its memory)
        planned once: ``.torque()`` is :meth:`torque` of ``dq``'s current values."""
        return RULES.Friction(dq, *self._tail)

    @property
    def terms(self) -> tuple[np.ndarray, ...]:
        """The law's per-robot terms as sim/_truth.c takes them: the gain (scale A / 2),
        alpha / 2 and alpha phi / 2."""
        return self._terms
