"""Where every arm's elements sit in a compiled world: :class:`ArmLayout`, read once
from the model's names (:func:`read_layout`) and repeated for robots that each step
their own MjData of a one-arm world (:func:`repeat_layout`), so nothing downstream
looks a name up.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace

import mujoco
import numpy as np

from .scene import body_names, free_joint_names

#: The arm's joints and links as models/fr3.xml names them.
ARM_JOINTS = tuple(f"joint{k}" for k in range(1, 8))
ARM_LINKS = tuple(f"link{k}" for k in range(8))

#: docs/fci-behaviour.md "self_collision_avoidance_violation (2)": only links at least three
#: apart in the chain are monitored (sim/self_collision.py; the sensors below).
MIN_CHAIN_SEPARATION = 3


@dataclass(frozen=True)
class ArmLayout:
    """Indices of every arm's elements in the compiled world model.

    Rows are arms (:func:`repeat_layout`: n rows of the one arm of a one-arm world, each
    indexing that arm's own MjData); columns joints 1..7 (or links 0..7). ``geom_arm`` /
    ``geom_link`` map every geom to the arm and link it belongs to, -1 for
    geoms that are not arm-link geoms (the table, the hand, scene objects).
    ``scene_body`` / ``scene_qpos_adr`` map a scene fragment's body names and its
    free joints' names to their (n,) body ids and (n,) qpos addresses (7 values
    each: position, then the w-x-y-z quaternion), one per arm.
    """

    n: int
    hand: bool
    qpos_adr: np.ndarray  # (n, 7) qpos address of joint1..7
    dof_adr: np.ndarray  # (n, 7) dof (qvel) address of joint1..7
    actuator_ids: np.ndarray  # (n, 7) the joint torque motors
    flange_site: np.ndarray  # (n,) site id of libfranka's kFlange (URDF link8)
    base_pos: np.ndarray  # (n, 3) world position of link0 (bases are not rotated)
    link_body: np.ndarray  # (n, 8) body ids of link0..link7
    geom_arm: np.ndarray  # (ngeom,) arm index or -1
    geom_link: np.ndarray  # (ngeom,) link index 0..7 or -1
    finger_qpos_adr: np.ndarray | None = None  # (n, 2) finger_joint1/2
    finger_dof_adr: np.ndarray | None = None  # (n, 2)
    finger_actuator: np.ndarray | None = None  # (n,) the `fingers` position servo
    tcp_site: np.ndarray | None = None  # (n,) hand TCP site
    hand_body: np.ndarray | None = None  # (n,) the `hand` body (the palm; fingers below it)
    payload_body: np.ndarray | None = None  # (n,) the payload nobody configured, if any
    scene_body: dict[str, np.ndarray] = field(default_factory=dict)
    scene_qpos_adr: dict[str, np.ndarray] = field(default_factory=dict)
    scene_dof_adr: dict[str, np.ndarray] = field(default_factory=dict)  # (n,) 6 dofs each
    #: (n, 5) sensordata address of the link contact sensors world.py adds: each
    #: counts the reported contacts of link a with link a + 3 or beyond
    link_contact_adr: np.ndarray | None = None


#: Fields indexed by the model's geoms, not by robot: shared, never repeated.
_PER_MODEL = frozenset({"geom_arm", "geom_link"})


def _ids(model: mujoco.MjModel, kind: str, names: list[list[str]]) -> np.ndarray:
    lookup = getattr(model, kind)
    return np.array([[lookup(name).id for name in row] for row in names], dtype=np.int64)


def read_layout(
    model: mujoco.MjModel,
    n: int,
    hand: bool,
    fragment: mujoco.MjSpec | None = None,
    payload: bool = False,
) -> ArmLayout:
    """The layout of the compiled world ``model`` of ``n`` arms named ``arm{i}/`` (with
    hands, the scene ``fragment``'s bodies and a payload where world.build_world added
    them)."""
    pre = [f"arm{i}/" for i in range(n)]
    joints = _ids(model, "joint", [[p + j for j in ARM_JOINTS] for p in pre])
    link_body = _ids(model, "body", [[p + b for b in ARM_LINKS] for p in pre])
    geom_arm = np.full(model.ngeom, -1, dtype=np.int64)
    geom_link = np.full(model.ngeom, -1, dtype=np.int64)
    body_arm = np.full(model.nbody, -1, dtype=np.int64)
    body_link = np.full(model.nbody, -1, dtype=np.int64)
    body_arm[link_body] = np.arange(n)[:, None]
    body_link[link_body] = np.arange(8)[None, :]
    geom_arm[:] = body_arm[model.geom_bodyid]
    geom_link[:] = body_link[model.geom_bodyid]
    fingers = {}
    if hand:
        fjoints = _ids(model, "joint", [[p + "finger_joint1", p + "finger_joint2"] for p in pre])
        fingers = dict(
            finger_qpos_adr=model.jnt_qposadr[fjoints],
            finger_dof_adr=model.jnt_dofadr[fjoints],
            finger_actuator=_ids(model, "actuator", [[p + "fingers"] for p in pre])[:, 0],
            tcp_site=_ids(model, "site", [[p + "tcp"] for p in pre])[:, 0],
            hand_body=_ids(model, "body", [[p + "hand"] for p in pre])[:, 0],
        )
    scene = {}
    if fragment is not None:
        scene = dict(
            scene_body={
                b: _ids(model, "body", [[p + b] for p in pre])[:, 0] for b in body_names(fragment)
            },
            scene_qpos_adr={
                j: model.jnt_qposadr[_ids(model, "joint", [[p + j] for p in pre])[:, 0]]
                for j in free_joint_names(fragment)
            },
            scene_dof_adr={
                j: model.jnt_dofadr[_ids(model, "joint", [[p + j] for p in pre])[:, 0]]
                for j in free_joint_names(fragment)
            },
        )
    if payload:
        scene["payload_body"] = _ids(model, "body", [[p + "payload"] for p in pre])[:, 0]
    sensors = [[f"{p}link{a}_contacts" for a in range(8 - MIN_CHAIN_SEPARATION)] for p in pre]
    scene["link_contact_adr"] = model.sensor_adr[_ids(model, "sensor", sensors)]
    return ArmLayout(
        n=n,
        hand=hand,
        qpos_adr=model.jnt_qposadr[joints],
        dof_adr=model.jnt_dofadr[joints],
        actuator_ids=_ids(model, "actuator", [[p + j for j in ARM_JOINTS] for p in pre]),
        flange_site=_ids(model, "site", [[p + "flange"] for p in pre])[:, 0],
        base_pos=model.body_pos[link_body[:, 0]].copy(),
        link_body=link_body,
        geom_arm=geom_arm,
        geom_link=geom_link,
        **fingers,
        **scene,
    )


def repeat_layout(layout: ArmLayout, n: int) -> ArmLayout:
    """The layout of n robots that each step their own MjData of ``layout``'s one-arm
    world: n rows, every one the arm's (row i indexes robot i's MjData)."""
    if layout.n != 1:
        raise ValueError(f"repeat_layout needs a one-arm layout, got {layout.n} arms")
    if n < 1:
        raise ValueError(f"n must be >= 1, got {n}")

    changes: dict = {"n": n}
    for f in fields(ArmLayout):
        value = getattr(layout, f.name)
        if f.name in _PER_MODEL or not isinstance(value, (np.ndarray, dict)):
            continue
        if isinstance(value, dict):
            changes[f.name] = {k: np.repeat(v, n, axis=0) for k, v in value.items()}
        else:
            changes[f.name] = np.repeat(value, n, axis=0)
    return replace(layout, **changes)
