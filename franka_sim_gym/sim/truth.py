"""The true arms and worlds under a reality draw: what the physics is, where the robot's
model and the task's nominal scene say otherwise (docs/reality.md).

The shared model stays the nominal one -- the robot's model, what GetRobotModel's URDF
says, whose weight MuJoCo's actuators compensate (``gravcomp``) as the robot compensates
its model's. On top of it, before every step, each robot's joints get

* the weight of its links' differences from the model (``model.*``: mass and centre of
  mass; :class:`LinkWeights`), which the drives do not carry: the arm sags until its servo
  takes it up, and the robot's estimate reads it at rest, as a real robot's reads its
  model's error;
* the friction in its drives (``friction.scale``): Gaz et al.'s law (sim/friction.py)
  against the motion.

Both are joint torques (``qfrc_applied``), so every robot still steps the one shared model:
the differences' inertia is the model's (docs/reality.md says what that leaves out). A world
with a scene (objects on the table) gives each robot its own copy of the model for its
draw's scene (``scene.*``): its objects' mass and sliding friction, its table's height;
a fixture's offset is applied where the task places it (envs/tasks/).
"""

from __future__ import annotations

import copy
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from .friction import RULES, JointFriction
from .scene import TABLE
from .views import ArmRows

if TYPE_CHECKING:
    from ..reality import DrawBatch
    from .arm import ArmPhysics


class LinkWeights:
    """The gravity torque of n arms' link differences from their model at the current
    state:

        dg_j(q) = g_arm_j(q) - g_model_j(q)
                = G (z_j x sum_{i >= j} [ dm_i (p_i - p_j) + R_i d(mc)_i ])_z,

    dm_i and d(mc)_i link i's differences in mass and first moment (link frame), z_j joint
    j's axis, p_i and R_i link i's origin and rotation (joint i sits at its link's
    origin), G the gravity's magnitude along -z; one C call a cycle for every arm
    (sim/_truth.c ``link_weights``; ``forces`` with the drives' friction). (Applied as
    link wrenches, ``xfrc_applied``, MuJoCo's step would map them at ~0.7 us a link-set
    per arm.)

    Args:
        physics: the arms (their nominal model, and the links' rotations gathered with the
            measured state after every step).
    """

    def __init__(self, physics: ArmPhysics) -> None:
        model, lay = physics.model, physics.layout
        n = physics.n
        gravity = np.asarray(model.opt.gravity, dtype=float)
        if np.any(gravity[:2] != 0.0) or gravity[2] >= 0.0:  # pragma: no cover - fr3.xml's
            raise ValueError(f"the model's gravity must point along -z, got {gravity}")
        self._g = float(-gravity[2])
        links = lay.link_body[0, 1:8]
        self._mass = model.body_mass[links].copy()
        self._com = model.body_ipos[links].copy()
        self._xmat = ArmRows([d.xmat for d in physics.datas], links)
        physics.gather_also(self._xmat)
        self._axes, self._origins = physics.joint_axes, physics.joint_anchors
        # G dm (n, 7, 1), G d(mc) (n, 7, 3), G sum_{i >= j} dm_i (n, 7, 1): the draws'
        self._dm = np.zeros((n, 7, 1))
        self._dmc = np.zeros((n, 7, 3))
        self._tail = np.zeros((n, 7, 1))
        self.out = np.zeros((n, 7))

    def set(self, robots, mass_scale, com_offset) -> None:
        """``robots``' links weigh the model's times ``mass_scale`` (k, 7), their centres
        of mass moved by ``com_offset`` (k, 7, 3, link frames)."""
        m0, c0 = self._mass, self._com
        m = m0 * np.asarray(mass_scale)
        dm = self._g * (m - m0)
        self._dm[robots, :, 0] = dm
        moment = m[..., None] * (c0 + np.asarray(com_offset))  # m c of the arm's links
        self._dmc[robots] = self._g * (moment - m0[:, None] * c0)
        self._tail[robots, :, 0] = np.cumsum(dm[..., ::-1], axis=-1)[..., ::-1]

    def torque(self) -> np.ndarray:
        """(n, 7) dg at the arms' current state (``out``, overwritten by the next call)."""
        return RULES.link_weights(*self.terms, self.out)

    @property
    def terms(self) -> tuple[np.ndarray, ...]:
        """What sim/_truth.c reads: the links' rotations (n, 7, 9), G d(mc), G dm, G's
        tail sums of dm, the joints' anchors and axes."""
        return self._xmat.out, self._dmc, self._dm, self._tail, self._origins, self._axes


class ArmTruth:
    """The true world of each of n robots (the module docstring).

    Args:
        physics: the arms; their shared model is the nominal world.
        scene: give every robot its own copy of the model for its scene's draw (a world
            with objects); False: the scene is the nominal one.
    """

    def __init__(self, physics: ArmPhysics, scene: bool) -> None:
        model, lay = physics.model, physics.layout
        n = physics.n
        #: the links' weight differences from the model
        self.weights = LinkWeights(physics)
        #: the friction in the drives
        self.friction = JointFriction(n)
        self._dq = physics.dq
        self._applied = ArmRows([d.qfrc_applied for d in physics.datas], lay.dof_adr[0])
        # The step's forces planned once (sim/_truth.c Forces: every array changes in place
        # only), written straight into each arm's qfrc_applied rows.
        self._forces = RULES.Forces(
            self._dq, *self.friction.terms, *self.weights.terms, tuple(self._applied.views)
        )
        #: (n,) each table's surface above the base plane [m]
        self.table_height = np.zeros(n)
        #: (n, 2) each fixture's x, y offset from where its task puts it [m]
        self.fixture_offset = np.zeros((n, 2))
        #: robot i's own model (None: every robot steps the shared one)
        self.models: tuple[mujoco.MjModel, ...] | None = None
        if not scene:
            return
        self.models = tuple(copy.copy(model) for _ in range(n))
        self._scratch = [mujoco.MjData(m) for m in self.models]  # mj_setConst's workspace
        # The scene's objects: the bodies of its free joints, and their geoms.
        adr = model.jnt_qposadr.tolist()
        joints = [adr.index(int(a[0])) for a in lay.scene_qpos_adr.values()]
        self.objects = np.array([model.jnt_bodyid[j] for j in joints], dtype=np.intp)
        self.object_geoms = np.flatnonzero(np.isin(model.geom_bodyid, self.objects))
        self._object_mass = model.body_mass[self.objects].copy()
        self._object_inertia = model.body_inertia[self.objects].copy()
        self._object_friction = model.geom_friction[self.object_geoms, 0].copy()
        self.table = model.geom(TABLE).id

    def apply(self, robots, draws: DrawBatch) -> None:
        """Give ``robots`` the true arm and world of their draws (rows of ``draws``);
        their worlds need an mj_forward before they are read (a reset does one)."""
        robots = np.atleast_1d(np.asarray(robots, dtype=np.intp))
        self.weights.set(robots, draws["model.mass_scale"], draws["model.com_offset"])
        # Applied against the motion: the law's torque with its sign turned.
        self.friction.set_scale(robots, -np.asarray(draws["friction.scale"]))
        if self.models is None:
            return
        for k, i in enumerate(robots.tolist()):
            m = self.models[i]
            scale = float(draws["scene.object_mass_scale"][k])
            m.body_mass[self.objects] = self._object_mass * scale
            m.body_inertia[self.objects] = self._object_inertia * scale
            friction = float(draws["scene.object_friction_scale"][k])
            m.geom_friction[self.object_geoms, 0] = self._object_friction * friction
            self.table_height[i] = draws["scene.table_height"][k]
            m.geom_pos[self.table, 2] = self.table_height[i]
            self.fixture_offset[i] = draws["scene.fixture_offset"][k]
            # The constants MuJoCo derives from the inertials (subtree masses, the
            # inverse weights that scale constraint softness), as compiling them would.
            mujoco.mj_setConst(m, self._scratch[i])

    def before_step(self) -> None:
        """The joints' extra forces for the next step, at the current (true) state: the
        drives' friction and the links' weight differences."""
        self._forces.apply()
