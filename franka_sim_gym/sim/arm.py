"""n FR3 arms in one MuJoCo world: the joint servo, the torque path, measurements.

This is the physics half of the robot. It knows nothing of the FCI (no modes,
errors or message ids): each cycle it is handed, per arm, a joint reference
for the internal joint impedance servo or an external torque, steps the world
by 1 ms, and exposes the measured state as (n, 7) arrays.

Gravity compensation is MuJoCo's own: every arm body has gravcomp="1" and
every joint actuatorgravcomp="true" (models/fr3.xml), so the gravity torque is
applied *through the actuators* and shows up in qfrc_actuator, which is why
the measured tau_J includes gravity exactly as the robot's torque sensors do.

The step is split as mj_step2 -> mj_step1 so that after a step the kinematics,
bias forces and Jacobian-ready positions describe the new state: the FCI reads
them to publish state k+1 and to compute the next cycle's servo torque.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from .cartesian_servo import NULLSPACE_STIFFNESS, CartesianTarget, damping_for, impedance_torque
from .dynamics import jacobian_at, weight_torque
from .views import strided_rows
from .world import FINGER_OPEN, HOME_Q, ArmLayout, build_world

#: Default stiffness [Nm/rad] of the internal joint servo: the joint impedance
#: libfranka's examples set (setJointImpedance({{3000, 3000, 3000, 2500, 2500,
#: 2000, 2000}}), e.g. examples/joint_impedance_control.cpp callers); the
#: robot's own factory value is not published.
DEFAULT_STIFFNESS = (3000.0, 3000.0, 3000.0, 2500.0, 2500.0, 2000.0, 2000.0)


class _ArmArray:
    """Read/write access to one (n, 7) slice of a flat MuJoCo array."""

    def __init__(self, flat: np.ndarray, adr: np.ndarray) -> None:
        self.flat = flat
        self.adr = adr
        self.view = strided_rows(flat, adr)  # None: addresses not evenly spaced

    def get(self) -> np.ndarray:
        return self.view if self.view is not None else self.flat[self.adr]

    def set(self, value: np.ndarray) -> None:
        if self.view is not None:
            self.view[...] = value
        else:
            self.flat[self.adr] = value


class ArmPhysics:
    """The simulated arms: one MuJoCo world, n FR3 arms, stepped 1 ms at a time.

    Args:
        n_arms: number of arms in the world (one per simulated robot).
        hand: mount the Franka Hand on every flange.
        spacing: distance between arm bases along x [m].
        object_width: a rigid object this wide [m] between every hand's fingers
            (the gripper's ``--gripper-object-width``); None: empty hands.
        scene: a scene fragment on every arm's table (a shipped name, "block" or
            "peg_in_hole", or an MJCF file; sim/scene.py); None: the bare table.
        payload: (mass, x, y, z) a mass on every flange, centre of mass in the flange
            frame, whose weight nothing compensates (``serve --payload``); None: none.
    """

    def __init__(
        self,
        n_arms: int = 1,
        hand: bool = False,
        spacing: float = 2.0,
        object_width: float | None = None,
        scene: str | Path | None = None,
        payload: tuple[float, float, float, float] | None = None,
    ) -> None:
        if n_arms < 1:
            raise ValueError(f"n_arms must be >= 1, got {n_arms}")
        self.model, self.layout = build_world(
            n_arms=n_arms,
            hand=hand,
            spacing=spacing,
            object_width=object_width,
            scene=scene,
            payload=payload,
        )
        self.data = mujoco.MjData(self.model)
        self.n = n_arms
        self.hand = hand
        lay: ArmLayout = self.layout
        self._qpos = _ArmArray(self.data.qpos, lay.qpos_adr)
        self._qvel = _ArmArray(self.data.qvel, lay.dof_adr)
        self._ctrl = _ArmArray(self.data.ctrl, lay.actuator_ids)
        self._bias = _ArmArray(self.data.qfrc_bias, lay.dof_adr)
        self._gravcomp = _ArmArray(self.data.qfrc_gravcomp, lay.dof_adr)
        self._actuator = _ArmArray(self.data.qfrc_actuator, lay.dof_adr)
        self.base_pos = np.asarray(lay.base_pos, dtype=np.float64)
        self.kp = np.empty((n_arms, 7))
        self.kd = np.empty((n_arms, 7))
        self.coriolis = np.zeros((n_arms, 7))
        #: (n, 7) the weight torque of a payload nobody configured (zero without one)
        self.payload_weight = np.zeros((n_arms, 7))
        self._tau = np.zeros((n_arms, 7))
        self._tmp = np.zeros((n_arms, 7))
        self._copies = any(
            a.view is None
            for a in (self._qpos, self._qvel, self._actuator, self._bias, self._gravcomp)
        )
        self._flange_sites = np.asarray(lay.flange_site)
        pos = strided_rows(self.data.site_xpos, self._flange_sites)
        mat = strided_rows(self.data.site_xmat, self._flange_sites)
        #: live views of the flange's world position (n, 3) and of its rotation
        #: transposed (n, 3, 3) -- the column-major wire layout of O_T_EE's block --
        #: when the sites are evenly spaced; None otherwise
        self.flange_views: tuple[np.ndarray, np.ndarray] | None = None
        R = None if mat is None else mat.reshape(n_arms, 3, 3)
        if pos is not None and R is not None and np.shares_memory(R, self.data.site_xmat):
            self.flange_views = (pos, R.transpose(0, 2, 1))
        self._effective_inertia, self._cartesian_inertia = self._home_inertia()
        self._nullspace_damping = damping_for(NULLSPACE_STIFFNESS, self._effective_inertia)
        self._joints = self.model.dof_jntid[np.asarray(lay.dof_adr)]
        self.set_stiffness(np.arange(n_arms), DEFAULT_STIFFNESS)
        self.reset_arms(np.arange(n_arms), np.broadcast_to(HOME_Q, (n_arms, 7)))

    # -- configuration -------------------------------------------------------------------------

    def _home_inertia(self) -> tuple[np.ndarray, np.ndarray]:
        """At home, arm 0: the diagonal of the joint-space inertia (armature included)
        and of the flange's Cartesian inertia (J M^-1 J^T)^-1, what the servos damp
        against."""
        data = mujoco.MjData(self.model)
        data.qpos[self.layout.qpos_adr[0]] = HOME_Q
        mujoco.mj_forward(self.model, data)
        full = np.zeros((self.model.nv, self.model.nv))
        mujoco.mj_fullM(self.model, data, full)
        dofs = self.layout.dof_adr[0]
        M = full[np.ix_(dofs, dofs)]
        jacp, jacr = np.zeros((3, self.model.nv)), np.zeros((3, self.model.nv))
        mujoco.mj_jacSite(self.model, data, jacp, jacr, self.layout.flange_site[0])
        J = np.vstack([jacp[:, dofs], jacr[:, dofs]])
        cartesian = np.linalg.inv(J @ np.linalg.solve(M, J.T))
        return np.diag(M).copy(), np.diag(cartesian).copy()

    def set_stiffness(self, arms: np.ndarray, stiffness: np.ndarray) -> None:
        """Set the joint servo stiffness K [Nm/rad] of ``arms``; damping follows critically.

        D = 2 sqrt(K m) with m the joint's effective inertia at home (armature
        included): a critically damped servo holds the idle pose without ring.
        """
        stiffness = np.asarray(stiffness, dtype=np.float64)
        self.kp[arms] = stiffness
        self.kd[arms] = 2.0 * np.sqrt(stiffness * self._effective_inertia)

    # -- state ---------------------------------------------------------------------------------

    def reset_arms(self, arms: np.ndarray, q: np.ndarray) -> None:
        """Teleport ``arms`` to joint positions ``q`` at rest (a reset, not a motion)."""
        arms = np.atleast_1d(np.asarray(arms, dtype=np.intp))
        q = np.asarray(q, dtype=np.float64).reshape(len(arms), 7)
        lay = self.layout
        self.data.qpos[lay.qpos_adr[arms]] = q
        self.data.qvel[lay.dof_adr[arms]] = 0.0
        self.data.qacc_warmstart[lay.dof_adr[arms]] = 0.0
        self.data.ctrl[lay.actuator_ids[arms]] = 0.0
        # Every dof of the arm's subtree restarts with no warm start, so an episode does
        # not depend on how long the world ran on after the arm's last one ended (the
        # vector env steps a stopped arm to the end of the step; a single env stops).
        if lay.finger_qpos_adr is not None:
            self.data.qpos[lay.finger_qpos_adr[arms]] = FINGER_OPEN
            self.data.qvel[lay.finger_dof_adr[arms]] = 0.0
            self.data.qacc_warmstart[lay.finger_dof_adr[arms]] = 0.0
            self.data.ctrl[lay.finger_actuator[arms]] = FINGER_OPEN
        # The arms' scene objects back where their fragment put them, at rest (a task
        # then places them for its episode).
        for joint, qadr in lay.scene_qpos_adr.items():
            rows = (qadr[arms][:, None] + np.arange(7)).ravel()
            self.data.qpos[rows] = self.model.qpos0[rows]
            dofs = (lay.scene_dof_adr[joint][arms][:, None] + np.arange(6)).ravel()
            self.data.qvel[dofs] = 0.0
            self.data.qacc_warmstart[dofs] = 0.0
        mujoco.mj_forward(self.model, self.data)
        self._refresh()

    def _refresh(self) -> None:
        """Measured quantities of the current MuJoCo state, as (n, 7) arrays.

        Where the arms' addresses are affine these are live views into MjData
        (no copy per cycle); otherwise copies made here.
        """
        self.q = self._qpos.get()
        self.dq = self._qvel.get()
        # qfrc_actuator is what mj_step2 applied; mj_step1 leaves it alone.
        self.tau_J = self._actuator.get()
        self._update_coriolis()

    def _update_coriolis(self) -> None:
        """C(q, dq) dq of the new state: the bias forces without the gravity MuJoCo's
        actuators compensate; a payload nobody configured (gravcomp 0) is not in that
        compensation, and its weight is not Coriolis: it is left to sag the arm."""
        np.subtract(self._bias.get(), self._gravcomp.get(), out=self.coriolis)
        if self.layout.payload_body is not None:
            self.payload_weight[...] = self._payload_weight()
            self.coriolis -= self.payload_weight

    def _payload_weight(self) -> np.ndarray:
        """(n, 7) the joint torques that would hold the payloads against gravity."""
        lay = self.layout
        J = self.jacobian(self.data.xipos[lay.payload_body] - self.base_pos)
        return weight_torque(J, self.model.body_mass[lay.payload_body], self.model.opt.gravity)

    def jacobian(self, point: np.ndarray) -> np.ndarray:
        """(n, 6, 7) geometric Jacobian of ``point`` (n, 3, each arm's base frame) on each
        arm's last link, from the joints' axes and anchors of the current state."""
        data = self.data
        anchors = data.xanchor[self._joints] - self.base_pos[:, None, :]
        return jacobian_at(data.xaxis[self._joints], anchors, point)

    def set_finger_width(self, arms: np.ndarray, width: np.ndarray) -> None:
        """Target opening width [m] of the hands of ``arms`` (the fingers' position servo
        takes half of it per finger: models/hand.xml)."""
        if self.layout.finger_actuator is None:
            raise ValueError("no hand is mounted (ArmPhysics(hand=True) mounts one)")
        self.data.ctrl[self.layout.finger_actuator[arms]] = np.asarray(width) / 2.0

    def finger_width(self) -> np.ndarray:
        """(n,) measured opening width [m]: the two finger joints summed."""
        if self.layout.finger_qpos_adr is None:
            raise ValueError("no hand is mounted")
        return self.data.qpos[self.layout.finger_qpos_adr].sum(axis=1)

    @property
    def time(self) -> float:
        """Simulated time [s]."""
        return float(self.data.time)

    # -- the cycle -----------------------------------------------------------------------------

    def step(
        self,
        q_ref: np.ndarray,
        dq_ref: np.ndarray | None,
        tau_external: np.ndarray | None = None,
        external: np.ndarray | bool | None = None,
        cartesian: CartesianTarget | None = None,
        compensation: np.ndarray | None = None,
    ) -> None:
        """Advance the world by one 1 ms cycle.

        Args:
            q_ref, dq_ref: (n, 7) joint reference of the internal joint impedance
                servo; ``dq_ref=None`` holds at rest (zero reference velocity).
            tau_external: (n, 7) commanded torque *without gravity*, applied where
                ``external`` says; gravity is added by the actuators.
            external: None or False (no arm under external torque), True (every
                arm), or an (n,) bool mask.
            cartesian: the arms (its ``mask``) whose internal servo is the Cartesian
                impedance (sim/cartesian_servo.py) holding K on a pose; their
                ``q_ref`` is the nullspace's joint target.
            compensation: (n, 7) a torque the drives add in every mode (the weight
                of a load configured with SetLoad, which MuJoCo does not know of).
        """
        tau, tmp = self._tau, self._tmp
        # The internal joint impedance servo: K (q_ref - q) + D (dq_ref - dq) + Coriolis.
        np.subtract(q_ref, self.q, out=tau)
        tau *= self.kp
        if dq_ref is None:
            np.multiply(self.kd, self.dq, out=tmp)
            tau -= tmp
        else:
            np.subtract(dq_ref, self.dq, out=tmp)
            tmp *= self.kd
            tau += tmp
        if cartesian is not None:
            tau = np.where(cartesian.mask[:, None], self._cartesian_servo(cartesian, q_ref), tau)
        tau += self.coriolis
        if external is True:
            tau = tau_external
        elif external is not None and external is not False:
            tau = np.where(external[:, None], tau_external, tau)
        if compensation is not None:
            tau = tau + compensation
        self._ctrl.set(tau)
        mujoco.mj_step2(self.model, self.data)
        mujoco.mj_step1(self.model, self.data)
        if self._copies:
            self._refresh()
        else:
            self._update_coriolis()

    def _cartesian_servo(self, target: CartesianTarget, q_ref: np.ndarray) -> np.ndarray:
        """(n, 7) the Cartesian impedance servo's torque (without Coriolis) of every arm."""
        flange_p, flange_R = self.flange_pose()
        k = target.flange_to_k
        rotation = flange_R @ k[:, :3, :3]
        position = flange_p + np.einsum("nij,nj->ni", flange_R, k[:, :3, 3])
        J = self.jacobian(position)
        damping = damping_for(target.stiffness, self._cartesian_inertia)
        return impedance_torque(
            J, position, rotation, target, damping, self.q, self.dq, q_ref, self._nullspace_damping
        )

    # -- kinematics ----------------------------------------------------------------------------

    def flange_pose_raw(self) -> tuple[np.ndarray, np.ndarray]:
        """Flange (link8) position (n, 3) in each arm's base frame, and its rotation as
        MuJoCo's row-major (n, 9) xmat (arm bases are not rotated)."""
        sites = self._flange_sites
        pos = self.data.site_xpos[sites] - self.base_pos
        return pos, self.data.site_xmat[sites]

    def flange_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """Flange (link8) position (n, 3) and rotation (n, 3, 3) in each arm's base frame."""
        pos, xmat = self.flange_pose_raw()
        return pos, xmat.reshape(self.n, 3, 3)
