"""The mounted Franka Hand as Desk's end-effector configuration: m_ee, F_x_Cee, I_ee, F_T_NE.

On the robot, Desk's end-effector configuration (the Franka Hand) sets these
RobotState fields: libfranka's Model adds the load to the URDF arm it computes
with (``franka::Model`` takes the total load of m_ee and m_load;
docs/wire-protocol.md §7.2), and the hand's TCP is the nominal end effector
frame F_T_NE, "configured outside of libfranka (in DESK)" (libfranka
include/franka/robot.h, "Nominal end effector frame NE"). The simulation's
hand is a real MuJoCo subtree (models/hand.xml, franka_description's
inertials and TCP), so both are read off the compiled model rather than
written down a second time.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from .layout import ArmLayout
from .world import HOME_Q


@dataclass(frozen=True)
class HandLoad:
    """The hand's mass properties and TCP in the flange frame (libfranka's conventions).

    Attributes:
        m_ee: total mass [kg] of the hand and its fingers.
        F_x_Cee: centre of mass [m] in the flange frame.
        I_ee: 3x3 inertia [kg m^2] about the centre of mass, flange axes.
        F_T_NE: row-major 4x4 pose of the hand's TCP (hand.xml site ``tcp``) in
            the flange frame: 0.1034 m along the flange z axis, rotated -pi/4
            about it (franka_description: hand_joint rpy 0 0 -pi/4,
            hand_tcp_joint xyz 0 0 0.1034). Desk's Franka Hand configuration
            is the same transform rounded to 4 digits, column-major [0.7071,
            -0.7071, 0, 0, 0.7071, 0.7071, 0, 0, 0, 0, 1, 0, 0, 0, 0.1034, 1].
    """

    m_ee: float
    F_x_Cee: np.ndarray
    I_ee: np.ndarray
    F_T_NE: np.ndarray

    def I_ee_wire(self) -> np.ndarray:
        """I_ee as the 9 column-major values of the RobotState field."""
        return self.I_ee.reshape(-1, order="F")


def hand_load(model: mujoco.MjModel, layout: ArmLayout, arm: int = 0) -> HandLoad:
    """The load and TCP of arm ``arm``'s hand, fingers as the model's keyframe sets them (open).

    The arm pose does not matter (the hand is rigid on the flange); home is used.
    """
    if layout.hand_body is None:
        raise ValueError("no hand is mounted")
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    data.qpos[layout.qpos_adr[arm]] = HOME_Q
    mujoco.mj_forward(model, data)
    root = int(layout.hand_body[arm])
    bodies = [b for b in range(model.nbody) if _in_subtree(model, b, root)]
    mass = float(sum(model.body_mass[b] for b in bodies))
    com = sum(model.body_mass[b] * data.xipos[b] for b in bodies) / mass
    inertia = np.zeros((3, 3))
    for b in bodies:
        R = data.ximat[b].reshape(3, 3)
        r = data.xipos[b] - com
        # Rotate each body's principal inertia to world axes, then shift it to the
        # common centre of mass (parallel axis theorem).
        inertia += R @ np.diag(model.body_inertia[b]) @ R.T
        inertia += model.body_mass[b] * (r @ r * np.eye(3) - np.outer(r, r))
    site = int(layout.flange_site[arm])
    F_R_O = data.site_xmat[site].reshape(3, 3).T  # world -> flange axes
    F_x_C = F_R_O @ (com - data.site_xpos[site])
    return HandLoad(
        m_ee=mass,
        F_x_Cee=F_x_C,
        I_ee=F_R_O @ inertia @ F_R_O.T,
        F_T_NE=_site_in_flange(data, site, int(layout.tcp_site[arm])),
    )


def _site_in_flange(data: mujoco.MjData, flange: int, site: int) -> np.ndarray:
    """Row-major 4x4 pose of ``site`` in the frame of the ``flange`` site."""
    F_R_O = data.site_xmat[flange].reshape(3, 3).T
    T = np.eye(4)
    T[:3, :3] = F_R_O @ data.site_xmat[site].reshape(3, 3)
    T[:3, 3] = F_R_O @ (data.site_xpos[site] - data.site_xpos[flange])
    # Clear the world-frame round-off (~1e-16) where the transform has exact zeros.
    T[np.abs(T) < 1e-12] = 0.0
    return T


def _in_subtree(model: mujoco.MjModel, body: int, root: int) -> bool:
    while body > 0:
        if body == root:
            return True
        body = int(model.body_parentid[body])
    return False


class HeldObjects:
    """Which hands hold their arm's object (both fingertips touching it), and that
    object's load in libfranka's SetLoad terms, for the env's ``configure_load``.

    Args:
        model, layout: the one-arm world every arm steps (with a hand) and the arms'
            layout (``ArmPhysics.layout``).
        body: (n,) each arm's object body (``layout.scene_body[name]``).
    """

    def __init__(self, model: mujoco.MjModel, layout: ArmLayout, body: np.ndarray) -> None:
        if layout.hand_body is None:
            raise ValueError("no hand is mounted")
        n = layout.n
        self.body = np.asarray(body, dtype=np.intp)
        self._flange = np.asarray(layout.flange_site, dtype=np.intp)
        # Every geom's role in the test: 1 the object, 2 the left tip, 3 the right tip.
        self._role = np.zeros(model.ngeom, dtype=np.int64)
        for role, name in ((2, "arm0/left_tip"), (3, "arm0/right_tip")):
            self._role[model.geom(name).id] = role
        self._role[np.flatnonzero(model.geom_bodyid == self.body[0])] = 1
        self.mass = model.body_mass[self.body].copy()
        self._inertia = model.body_inertia[self.body].copy()
        self.n = n

    def held(self, datas) -> np.ndarray:
        """(n,) True where both fingertips of arm i's hand touch arm i's object
        (``datas[i]``: arm i's MjData)."""
        touching = np.zeros((self.n, 4), dtype=bool)
        for i, data in enumerate(datas):
            if not data.ncon:
                continue
            roles = self._role[data.contact.geom]
            for a, b in ((0, 1), (1, 0)):
                touching[i, roles[roles[:, a] == 1, b]] = True
        return touching[:, 2] & touching[:, 3]

    def load(self, data: mujoco.MjData, i: int) -> tuple[float, np.ndarray, np.ndarray]:
        """Arm i's object (``data``: arm i's MjData) as SetLoad's (m_load, F_x_Cload,
        I_load): its mass, its centre of mass in the flange frame, and its inertia about
        that centre in flange axes (9 values, column-major: symmetric)."""
        b, site = int(self.body[i]), int(self._flange[i])
        F_R_O = data.site_xmat[site].reshape(3, 3).T
        com = F_R_O @ (data.xipos[b] - data.site_xpos[site])
        R = F_R_O @ data.ximat[b].reshape(3, 3)
        inertia = R @ np.diag(self._inertia[i]) @ R.T
        return float(self.mass[i]), com, inertia.reshape(-1, order="F")
