"""The backward differences a Cartesian command is judged on, as the rules read them: the
pose's (translation per axis, rotation as the body-frame rotation vector), the elbow's and
the IK solution's (the joint side), with their named views; and the elbow's differences.

Backward Euler over ``steps * dt`` as for q_c (docs/fci-behaviour.md "The difference
formulas"); the orientation's derivatives in the body frame, the frame the lost-cycle law
composes the rotation increment in (docs/fci-behaviour.md "What the sim does with a lost
cycle"). The pose's and the joint side's one text is C, over the Cartesian history's rows
(fci/cartesian/_history.c ``History.pose_derivatives`` and ``joint_side``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .record import interval


class Twist(NamedTuple):
    """Translational and rotational halves of a derivative, (n, 3) each."""

    linear: np.ndarray
    angular: np.ndarray


def _block(*index) -> property:
    """A read-only property: the view ``stacked[:, *index]`` of a stacked result."""
    return property(lambda self: self.stacked[(slice(None), *index)])


class PoseDerivatives(NamedTuple):
    """Backward differences of a commanded pose against its history."""

    #: (n, 3, 6): rows [v | omega], [a | alpha], [jerk | zeta]; the properties are its views
    stacked: np.ndarray

    v = _block(0, slice(0, 3))
    omega = _block(0, slice(3, 6))
    a = _block(1, slice(0, 3))
    alpha = _block(1, slice(3, 6))
    jerk = _block(2, slice(0, 3))
    zeta = _block(2, slice(3, 6))  # rotational jerk


class ElbowDerivatives(NamedTuple):
    """Backward differences of elbow_c[0] (n,) each."""

    v: np.ndarray
    a: np.ndarray
    jerk: np.ndarray


class ElbowStream(NamedTuple):
    """This cycle's elbow_c and the history it continues."""

    #: (n, 2) the commanded elbow (elbow[0] = joint 3's angle, elbow[1] the branch flag)
    command: np.ndarray
    #: (n,) this command carries an elbow (valid_elbow, or one extrapolated)
    has: np.ndarray
    #: (n,) the previous command carried one
    had: np.ndarray
    #: (n,) the previous command's branch flag
    prev_flag: np.ndarray
    #: elbow_c[0]'s backward differences
    derivatives: ElbowDerivatives


class JointSide(NamedTuple):
    """The IK solution and its differences, as the joint side judges them: its position
    (27) where ``solved``, its velocity (28), acceleration (29) and jerk (30) where
    ``checked`` (n,) each."""

    #: (n, 2, 7): rows ddq, dddq (the properties are its views)
    stacked: np.ndarray
    checked: np.ndarray
    #: (n, 2, 7): rows q, dq of the solution (None: the range and envelope rows are off)
    motion: np.ndarray | None = None
    #: (n, 7) the previous solution, where the velocity envelope is evaluated
    q_prev: np.ndarray | None = None
    #: (n,) a converged solution: its joint range is judged (the opening command too)
    solved: np.ndarray | None = None

    ddq = _block(0)
    dddq = _block(1)

    @property
    def q(self) -> np.ndarray:
        return self.motion[:, 0]

    @property
    def dq(self) -> np.ndarray:
        return self.motion[:, 1]


def elbow_derivatives(e_c, e_prev, de_prev, dde_prev, steps) -> ElbowDerivatives:
    """Backward differences of elbow_c[0] against its history."""
    h = np.reshape(interval(steps), -1)
    v = (e_c - e_prev) / h
    a = (v - de_prev) / h
    return ElbowDerivatives(v, a, (a - dde_prev) / h)
