"""Compose FR3 arms, optionally with Franka Hands, into a MuJoCo world.

The simulator's physics is a world of ONE arm at the origin (:func:`build_world` with
``n_arms=1``): every simulated robot steps its own MjData of that one model
(sim/arm.py), so robot i's arithmetic is exactly a single robot's. Worlds of n arms
are for kinematics alone (sim/kinematics.py stacks n arms at the origin, where each
arm's frames are computed exactly as in the one-arm world) and for tests.

Arm i is models/fr3.xml attached with the name prefix ``arm{i}/`` at
(spacing * i, 0, 0), unrotated; with ``hand=True`` models/hand.xml is attached
to each arm's ``flange`` site rotated Rz(-pi/4), as franka_description mounts
it (docs/fr3-model.md §5); ``object_width`` adds the gripper's rigid virtual object
between each hand's fingertips (:func:`_add_object`). Every arm stands on the
table (scene.py), and a scene fragment (``scene``) adds one copy of its bodies
per arm. :class:`~.layout.ArmLayout` (sim/layout.py) holds every index the rest of the
simulator needs, so nothing downstream looks names up.
"""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np

from .layout import MIN_CHAIN_SEPARATION, ArmLayout, read_layout
from .scene import add_table, load_scene

MODEL_DIR: Path = Path(__file__).resolve().parent / "models"
FR3_XML: Path = MODEL_DIR / "fr3.xml"
HAND_XML: Path = MODEL_DIR / "hand.xml"
#: The URDF GetRobotModel serves to libfranka clients (arm only, no hand).
URDF_PATH: Path = MODEL_DIR / "fr3.urdf"

#: The home pose (docs/fr3-model.md §6), read-only.
HOME_Q: np.ndarray = np.array(
    [0.0, -math.pi / 4, 0.0, -3 * math.pi / 4, 0.0, math.pi / 2, math.pi / 4]
)
HOME_Q.flags.writeable = False

#: Finger position (m, per finger) of an open hand: finger_joint1/2 upper limit.
FINGER_OPEN = 0.04
#: The safety controller's self-collision distance (m): arm-arm geom pairs closer
#: than this are reported in data.contact without any force (see fr3.xml).
SELF_COLLISION_DISTANCE = 0.05
#: franka_description hand_joint: rpy (0, 0, -pi/4) relative to the flange.
HAND_QUAT = (math.cos(-math.pi / 8), 0.0, 0.0, math.sin(-math.pi / 8))
#: The fingertip pads' centre in the hand frame: finger body z 0.0584 + tip box
#: z 0.04525 (models/hand.xml); the virtual object sits there.
_TIP_Z = 0.0584 + 0.04525
#: Half extents (x, z) of the virtual object: slightly wider than the 8.75 mm
#: tip pads in x and 9 mm in z, so both pads meet it face to face.
_OBJECT_HALF_XZ = (0.01, 0.009)
#: Contact of the object with the fingertips: MuJoCo's stiffest safe time
#: constant (2 timesteps) and impedance near 1, so 100 N press it in < 0.1 mm
#: (MuJoCo's default solref 0.02 would let 20 N push the fingers ~1 cm in).
_OBJECT_SOLREF = (0.002, 1.0)
_OBJECT_SOLIMP = (0.99, 0.999, 0.0001, 0.5, 2.0)
#: The finger coupling's: the same stiffest safe time constant and near-1 impedance.
_COUPLING_SOLREF = (0.002, 1.0)
_COUPLING_SOLIMP = (0.99, 0.999, 0.0001)

_ARM_GEOM_CLASS = "arm_collision"


def _mujoco_version() -> tuple[int, int]:
    major, minor = mujoco.__version__.split(".")[:2]
    return int(major), int(minor)


def report_band_params(version: tuple[int, int] | None = None) -> tuple[float, float]:
    """(margin, gap) per arm geom that reports pairs within 50 mm, force-free.

    MuJoCo >= 3.9: force when dist < margin, reported while dist < margin + gap;
    >= 3.5: a pair's margin/gap are the sums of the two geoms' values; before
    3.5 the maxima, and before 3.9 gap was subtracted from margin instead.
    fr3.xml carries the >= 3.9 values.
    """
    version = version or _mujoco_version()
    band = SELF_COLLISION_DISTANCE
    if version >= (3, 9):
        return 0.0, band / 2
    if version >= (3, 5):
        return band / 2, band / 2
    return band, band


def _arm_spec() -> mujoco.MjSpec:
    """One arm as a spec, with the report band of this MuJoCo version."""
    arm = mujoco.MjSpec.from_file(str(FR3_XML))
    margin, gap = report_band_params()
    for geom in arm.geoms:
        if geom.classname.name == _ARM_GEOM_CLASS:
            geom.margin, geom.gap = margin, gap
    return arm


def build_world(
    n_arms: int = 1,
    hand: bool = False,
    spacing: float = 2.0,
    object_width: float | None = None,
    scene: str | Path | None = None,
    payload: tuple[float, float, float, float] | None = None,
) -> tuple[mujoco.MjModel, ArmLayout]:
    """Build a world of ``n_arms`` FR3 arms on the table.

    ``object_width`` (needs ``hand``) puts a rigid box that wide between every
    hand's fingertips; None or 0 leaves the hands empty. ``scene`` names a shipped
    scene fragment (scene.SCENES: "block", "peg_in_hole") or an MJCF file of one;
    each arm gets its own copy, placed in its base frame. ``payload`` (mass [kg] and
    centre of mass x, y, z [m] in the flange frame) fixes a mass to every flange that
    the robot does not know of: nothing compensates its weight unless a client
    configures it with SetLoad (:func:`_add_payload`).

    Keyframe ``home`` puts every arm at HOME_Q with the fingers open; callers
    should start from it (mj_resetDataKeyframe) or set data.qpos themselves:
    mj_resetData gives q = 0, outside the joint-4 and joint-6 ranges. qpos0 is
    left at 0 on purpose: MuJoCo's hinge kinematics rotate by qpos - qpos0.
    """
    if n_arms < 1:
        raise ValueError(f"n_arms must be >= 1, got {n_arms}")
    if object_width is not None and not (
        hand and math.isfinite(object_width) and 0.0 <= object_width <= 2 * FINGER_OPEN
    ):
        raise ValueError(f"object width {object_width}: needs a hand and 0-{2 * FINGER_OPEN} m")
    spec = mujoco.MjSpec()
    spec.modelname = "franka_sim_gym"
    spec.copy_during_attach = True  # the same arm (and hand) spec is attached n times
    spec.compiler.degree = False
    # 1 ms = one FCI cycle; implicitfast as in fr3.xml (attach does not copy <option>).
    spec.option.timestep = 0.001
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    # Always the sparse constraint Jacobian: MuJoCo's "auto" picks dense below 60 dofs
    # and sparse above, and the two sum in different orders (~1e-14 apart): one choice
    # for every world this builds, whatever its size.
    spec.option.jacobian = mujoco.mjtJacobian.mjJAC_SPARSE
    world = spec.worldbody
    add_table(spec)
    world.add_light(
        name="sun", type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL, pos=[0, 0, 3], dir=[0, 0, -1]
    )
    arm = _arm_spec()
    hand_spec = mujoco.MjSpec.from_file(str(HAND_XML)) if hand else None
    fragment = load_scene(scene) if scene is not None else None
    for i in range(n_arms):
        prefix = f"arm{i}/"
        spec.attach(arm, prefix=prefix, frame=world.add_frame(pos=[spacing * i, 0.0, 0.0]))
        if fragment is not None:
            spec.attach(fragment, prefix=prefix, frame=world.add_frame(pos=[spacing * i, 0.0, 0.0]))
        if hand_spec is not None:
            # Same prefix, so the hand's names read arm{i}/hand, arm{i}/fingers, ...
            flange = spec.site(prefix + "flange")
            mount = spec.body(prefix + "link7").add_frame(pos=flange.pos, quat=HAND_QUAT)
            spec.attach(hand_spec, prefix=prefix, frame=mount)
            if object_width:
                _add_object(spec, prefix, object_width)
        if payload is not None:
            _add_payload(spec, prefix, payload)
        _add_link_contact_sensors(spec, prefix)
    spec.add_key(name="home")
    model = spec.compile()
    if hand:
        # The fingers are geared to one another on the real hand: a rigid coupling, not
        # MuJoCo's soft default (solref 0.02), which lets a 20 N grasp of an object off
        # the hand's centre line slide both fingers ~7 mm sideways, the object with them.
        couplings = [model.equality(f"arm{i}/finger_coupling").id for i in range(n_arms)]
        model.eq_solref[couplings] = _COUPLING_SOLREF
        model.eq_solimp[couplings, :3] = _COUPLING_SOLIMP
    layout = read_layout(model, n_arms, hand, fragment, payload is not None)
    _set_home(model, layout)
    return model, layout


def _add_link_contact_sensors(spec: mujoco.MjSpec, prefix: str) -> None:
    """Five contact sensors per arm, sensor a counting the contacts MuJoCo reports between
    link a's geoms and those of link a + 3's subtree (the links beyond it and the hand):
    every self-collision pair is in one of them (sim/self_collision.py reads the contact
    list only of arms whose count is not zero). Sensors add nothing to the dynamics."""
    for a in range(8 - MIN_CHAIN_SEPARATION):
        spec.add_sensor(
            name=f"{prefix}link{a}_contacts",
            type=mujoco.mjtSensor.mjSENS_CONTACT,
            objtype=mujoco.mjtObj.mjOBJ_BODY,
            objname=f"{prefix}link{a}",
            reftype=mujoco.mjtObj.mjOBJ_XBODY,  # the subtree of link a + 3
            refname=f"{prefix}link{a + MIN_CHAIN_SEPARATION}",
            intprm=[1, 0, 1],  # data "found", no reduction, one slot
        )


#: Radius [m] of the payload's inertia: a solid sphere, 2/5 m r^2 about each axis.
_PAYLOAD_RADIUS = 0.02


def _add_payload(spec: mujoco.MjSpec, prefix: str, payload: tuple[float, ...]) -> None:
    """A mass rigidly fixed to the flange, with gravcomp 0: unlike the arm's and the
    hand's bodies, MuJoCo's actuators do not carry its weight. It collides with nothing
    (its geom is a marker), so it is a load, not an object in the scene."""
    mass, *com = (float(v) for v in payload)
    if not (np.isfinite([mass, *com]).all() and mass > 0.0):
        raise ValueError(f"payload {payload}: needs a positive mass and a finite centre")
    flange = spec.site(prefix + "flange")
    body = spec.body(prefix + "link7").add_body(
        name=prefix + "payload", pos=np.asarray(flange.pos) + com
    )
    inertia = 0.4 * mass * _PAYLOAD_RADIUS**2
    body.add_geom(
        type=mujoco.mjtGeom.mjGEOM_SPHERE,
        size=[_PAYLOAD_RADIUS, 0, 0],
        contype=0,
        conaffinity=0,
        group=1,
        mass=0.0,
        rgba=[0.2, 0.7, 0.3, 1.0],
    )
    body.mass = mass
    body.inertia = [inertia, inertia, inertia]
    body.explicitinertial = True


def _add_object(spec: mujoco.MjSpec, prefix: str, width: float) -> None:
    """A rigid box ``width`` wide between the fingertips, fixed to the palm.

    It is a geom of the hand body, so it moves with the hand and adds no mass
    (the body's inertial is explicit). It collides with nothing but the two
    fingertip pads (contype/conaffinity 0, two explicit contact pairs), so the
    arm, the table and the rest of the hand pass through it; the pads' inner
    faces sit at the finger joint positions, so the fingers stall at a summed
    finger position of ``width`` (+ 0.04 mm: the pads' faces are 0.02 mm
    behind the joint origin).
    """
    half_x, half_z = _OBJECT_HALF_XZ
    spec.body(prefix + "hand").add_geom(
        name=prefix + "object",
        type=mujoco.mjtGeom.mjGEOM_BOX,
        pos=[0.0, 0.0, _TIP_Z],
        size=[half_x, width / 2, half_z],
        contype=0,
        conaffinity=0,
        group=1,
        rgba=[0.9, 0.45, 0.1, 1.0],
    )
    for tip in ("left_tip", "right_tip"):
        pair = spec.add_pair(geomname1=prefix + "object", geomname2=prefix + tip)
        pair.solref = list(_OBJECT_SOLREF)
        pair.solimp = list(_OBJECT_SOLIMP)


def _set_home(model: mujoco.MjModel, layout: ArmLayout) -> None:
    """Keyframe `home`: arms at HOME_Q, fingers open, zero motor torque."""
    qpos = model.qpos0.copy()
    qpos[layout.qpos_adr] = HOME_Q
    ctrl = np.zeros(model.nu)
    if layout.hand:
        qpos[layout.finger_qpos_adr] = FINGER_OPEN
        ctrl[layout.finger_actuator] = FINGER_OPEN
    key = model.key("home").id
    model.key_qpos[key] = qpos
    model.key_qvel[key] = 0.0
    model.key_ctrl[key] = ctrl
