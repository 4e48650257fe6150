"""Which arriving commands a cycle takes: fresh, late or answering nothing; finite.

docs/fci-behaviour.md "The cycle contract": a command answers the open cycle when it echoes the id
of the last published state (fresh); an older id of the running motion is late and still
applied; an id never published answers nothing (the cycle counts as lost). docs/fci-behaviour.md: a
non-finite command is refused whatever the enforcement, and reported as the
limits violation of the generator it arrived in; a Cartesian pose that is not a
homogeneous transformation (libfranka's isHomogeneousTransformation, NaN included)
is refused as 31; a non-finite elbow as 17.
"""

from __future__ import annotations

import numpy as np

from . import frames
from .cycle_input import CycleInput
from .log_limit import CycleLogLimit
from .modes import CARTESIAN_POSITION, CARTESIAN_VELOCITY, JOINT_POSITION, JOINT_VELOCITY, Modes


def classify(
    commands: np.ndarray,
    mask: np.ndarray,
    k: int,
    m: Modes,
    published: np.ndarray,
    motion_first_id: np.ndarray,
    cycle: CycleInput,
    warnings: CycleLogLimit,
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """(fresh, late, accepted) of the ``k`` commands delivered where ``mask`` (robots in
    motion); ``late`` is None when every one is fresh. Refused (non-finite) commands
    are marked in ``cycle.refused`` (and ``refused_elbow``), not accepted; both kinds
    are logged through ``warnings``, at most once a second each (a client can send
    them every cycle)."""
    n = m.n
    ids = commands["message_id"]
    fresh = ids == published
    if k < n:
        fresh &= mask
    late = None
    if np.count_nonzero(fresh) == k:
        accepted = fresh
    else:
        late = mask & (ids < published) & (ids >= motion_first_id)
        accepted = fresh | late
        for i in np.flatnonzero(mask & ~accepted).tolist():
            warnings.warning(
                int(published[i]),
                ("unanswerable", i),
                "robot %d: command with message_id %d answers no state of the running motion "
                "(last published %d); counted as lost",
                i,
                int(ids[i]),
                int(published[i]),
            )
    ok, refused_elbow, refused_torque = acceptable(commands, m)
    if ok is not None and np.count_nonzero(ok) < n:
        refused = accepted & ~ok
        for i in np.flatnonzero(refused).tolist():
            warnings.warning(
                int(published[i]),
                ("non-finite", i),
                "robot %d: %s; command refused",
                i,
                refusal_reason(commands[i], m, i),
            )
        cycle.refused |= refused
        if refused_elbow is not None:
            cycle.refused_elbow |= refused_elbow
        if refused_torque is not None:
            cycle.refused_torque |= refused_torque
        accepted = accepted & ok
    return fresh, late, accepted


#: The command fields each motion generator sends (libfranka's MotionGeneratorCommand).
_GENERATOR_FIELDS = {
    JOINT_POSITION: "q_c",
    JOINT_VELOCITY: "dq_c",
    CARTESIAN_POSITION: "O_T_EE_c",
    CARTESIAN_VELOCITY: "O_dP_EE_c",
}


def refusal_reason(command: np.void, m: Modes, i: int) -> str:
    """Why robot ``i``'s command was refused, naming the wire field: the first of its
    interface's fields (the generator's, the elbow if sent, the torque under an
    external controller) that is not finite, or a pose that is not a homogeneous
    transformation."""
    fields = []
    generator = _GENERATOR_FIELDS.get(int(m.motion_generator_mode[i]))
    if generator is not None:
        fields.append(generator)
    if m.cartesian[i] and command["valid_elbow"]:
        fields.append("elbow_c")
    if m.external[i]:
        fields.append("tau_J_d")
    for name in fields:
        if not np.isfinite(command[name]).all():
            return f"non-finite value in the commanded {name}"
    return "the commanded O_T_EE_c is not a homogeneous transformation"


def acceptable(
    commands: np.ndarray, m: Modes
) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None]:
    """Per robot, whether the active interface's command fields pass (finite; a pose that
    is a homogeneous transformation): (ok, refused_elbow, refused_torque). ``ok`` is None
    when every robot passes (the common case); ``refused_elbow`` (or None) marks the
    Cartesian commands that pass but for a non-finite elbow (named 17),
    ``refused_torque`` (or None) the generators' commands under an external controller
    that pass but for a non-finite tau_J_d (named 34)."""
    n = m.n
    if m.n_joint_position == n and not m.n_external:
        finite = np.isfinite(commands["q_c"])
        if np.count_nonzero(finite) == finite.size:  # the common case, without a reduce
            return None, None, None
        return finite.all(axis=1), None, None
    if m.n_external == n and m.n_torque_only == n:
        return _all_or_rows(np.isfinite(commands["tau_J_d"])), None, None
    if m.n_cartesian == n and not m.n_external and not np.count_nonzero(commands["valid_elbow"]):
        # Every robot in one Cartesian generator, no elbow: the common case.
        if m.n_cartesian_position == n:
            return frames.is_homogeneous_wire(commands["O_T_EE_c"]), None, None
        if m.n_cartesian_velocity == n:
            return _all_or_rows(np.isfinite(commands["O_dP_EE_c"])), None, None
    ok = np.ones(n, dtype=bool)
    if m.n_joint_position:
        ok &= ~m.joint_position | np.isfinite(commands["q_c"]).all(axis=1)
    if m.n_joint_velocity:
        ok &= ~m.joint_velocity | np.isfinite(commands["dq_c"]).all(axis=1)
    if m.n_cartesian_position:
        pose_ok = frames.is_homogeneous_wire(commands["O_T_EE_c"])
        if pose_ok is not None:
            ok &= ~m.cartesian_position | pose_ok
    if m.n_cartesian_velocity:
        ok &= ~m.cartesian_velocity | np.isfinite(commands["O_dP_EE_c"]).all(axis=1)
    refused_elbow = None
    if m.n_cartesian:
        finite_elbow = np.isfinite(commands["elbow_c"]).all(axis=1)
        elbow_ok = ~commands["valid_elbow"].astype(bool) | finite_elbow
        refused_elbow = m.cartesian & ok & ~elbow_ok
        ok &= ~m.cartesian | elbow_ok
    refused_torque = None
    if m.n_external:
        # Judged after the generator's fields, so that a torque refused beside a
        # finite generator command is named for the torque (34).
        finite_tau = np.isfinite(commands["tau_J_d"]).all(axis=1)
        refused_torque = m.external & ~m.torque_only & ok & ~finite_tau
        ok &= ~m.external | finite_tau
    return ok, refused_elbow, refused_torque


def _all_or_rows(finite: np.ndarray) -> np.ndarray | None:
    """None when every value is finite, else the (n,) rows that are."""
    if np.count_nonzero(finite) == finite.size:
        return None
    return finite.all(axis=1)
