"""The true arms and worlds under a reality draw: what the physics is, where the robot's
model and the task's nominal scene say otherwise (docs/reality.md).

Each robot steps its own copy of the one-arm world's MjModel (the shared model stays the
nominal one: the robot's model, what GetRobotModel's URDF says), with its draw applied:

* its links' masses, centres of mass and inertias (``model.*``);
* its scene objects' masses and sliding friction, its table's height (``scene.*``;
  a fixture's offset is applied where the task places it, envs/tasks/);
* the friction in its drives, Gaz et al.'s law scaled (sim/friction.py), applied as a
  joint torque against the motion before every step (``friction.scale``).

MuJoCo's gravity compensation (``gravcomp``) then carries the true links' weight; the
robot's own compensation of its model's is the controller's business (fci/reality/).
"""

from __future__ import annotations

import copy
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from .friction import JointFriction
from .scene import TABLE
from .views import ArmRows

if TYPE_CHECKING:
    from ..reality import DrawBatch
    from .arm import ArmPhysics


class ArmTruth:
    """The true world of each of n robots (the module docstring).

    Args:
        physics: the arms; their shared model is the nominal world, copied per robot.
    """

    def __init__(self, physics: ArmPhysics) -> None:
        model, lay = physics.model, physics.layout
        n = physics.n
        #: robot i's own MjModel (a copy of the nominal one-arm world)
        self.models: tuple[mujoco.MjModel, ...] = tuple(copy.copy(model) for _ in range(n))
        # mj_setConst's workspace (it runs the kinematics on the data it is given)
        self._scratch = [mujoco.MjData(m) for m in self.models]
        #: body ids of links 1..7 (link0 is welded to the world)
        self.links = lay.link_body[0, 1:8].copy()
        self._mass = model.body_mass[self.links].copy()
        self._com = model.body_ipos[self.links].copy()
        self._inertia = model.body_inertia[self.links].copy()
        # The scene's objects: the bodies of its free joints, and their geoms.
        joints = [model.jnt_qposadr.tolist().index(int(a[0])) for a in lay.scene_qpos_adr.values()]
        self.objects = np.array([model.jnt_bodyid[j] for j in joints], dtype=np.intp)
        self.object_geoms = np.flatnonzero(np.isin(model.geom_bodyid, self.objects))
        self._object_mass = model.body_mass[self.objects].copy()
        self._object_inertia = model.body_inertia[self.objects].copy()
        self._object_friction = model.geom_friction[self.object_geoms, 0].copy()
        self.table = model.geom(TABLE).id
        #: (n,) each table's surface above the base plane [m]
        self.table_height = np.zeros(n)
        #: (n, 2) each fixture's x, y offset from where its task puts it [m]
        self.fixture_offset = np.zeros((n, 2))
        #: the friction in the drives (its torque applied against the motion)
        self.friction = JointFriction(n)
        self._dq = physics.dq
        self._applied = ArmRows([d.qfrc_applied for d in physics.datas], lay.dof_adr[0])

    def apply(self, robots, draws: DrawBatch) -> None:
        """Give ``robots`` the true arm and world of their draws (rows of ``draws``);
        their worlds need an mj_forward before they are read (a reset does one)."""
        robots = np.atleast_1d(np.asarray(robots, dtype=np.intp))
        for k, i in enumerate(robots.tolist()):
            m = self.models[i]
            links = self.links
            m.body_mass[links] = self._mass * draws["model.mass_scale"][k]
            m.body_ipos[links] = self._com + draws["model.com_offset"][k]
            m.body_inertia[links] = self._inertia * draws["model.inertia_scale"][k][:, None]
            if len(self.objects):
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
        # Applied against the motion: the law's torque with its sign turned.
        self.friction.set_scale(robots, -np.asarray(draws["friction.scale"]))

    def before_step(self) -> None:
        """The drives' friction at the current (true) velocity, applied for the next step."""
        self._applied.scatter(self.friction.torque(self._dq))
