"""n FR3 arms, each in its own MuJoCo world: the joint servo, the torque path, measurements.

Every robot steps its own MjData of ONE shared model: a world of one arm at the origin
with its hand, its table and its scene objects (sim/world.py). Robot i's arithmetic is
then exactly a single robot's, bit for bit, whatever n is (docs/env.md, "Native vector
env"). The measured state is gathered from the n MjData into (n, 7) arrays after every
step.

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

from .. import native
from .cartesian_servo import NULLSPACE_STIFFNESS, CartesianTarget, damping_for, impedance_torque
from .dynamics import jacobian_at, weight_torque
from .layout import ArmLayout, repeat_layout
from .libmujoco import function_address
from .truth import ArmTruth
from .views import ArmRows, Gathering
from .world import FINGER_OPEN, HOME_Q, build_world

#: The joint servo and a cycle's physics of every arm, one C call (sim/_stepping.c: their
#: one text).
STEPPING = native.require("sim._stepping", "Steps")

#: Default stiffness [Nm/rad] of the internal joint servo: the joint impedance
#: libfranka's examples set (setJointImpedance({{3000, 3000, 3000, 2500, 2500,
#: 2000, 2000}}), e.g. examples/joint_impedance_control.cpp callers); the
#: robot's own factory value is not published.
DEFAULT_STIFFNESS = (3000.0, 3000.0, 3000.0, 2500.0, 2500.0, 2000.0, 2000.0)


class ArmPhysics:
    """The simulated arms: n FR3 arms, each stepping its own MjData of one shared
    one-arm world, 1 ms at a time.

    Args:
        n_arms: number of arms (one per simulated robot).
        hand: mount the Franka Hand on every flange.
        object_width: a rigid object this wide [m] between every hand's fingers
            (the gripper's ``--gripper-object-width``); None: empty hands.
        scene: a scene fragment on every arm's table (a shipped name, "block" or
            "peg_in_hole", or an MJCF file; sim/scene.py); None: the bare table.
        payload: (mass, x, y, z) a mass on every flange, centre of mass in the flange
            frame, whose weight nothing compensates (``serve --payload``); None: none.

    ``model`` is the shared one-arm world, ``datas[i]`` robot i's MjData (``data`` is
    robot 0's), ``layout`` has one row per robot, every row indexing that robot's own
    MjData. Every arm's base is its world's origin, so world and base frames coincide.
    """

    def __init__(
        self,
        n_arms: int = 1,
        hand: bool = False,
        object_width: float | None = None,
        scene: str | Path | None = None,
        payload: tuple[float, float, float, float] | None = None,
    ) -> None:
        if n_arms < 1:
            raise ValueError(f"n_arms must be >= 1, got {n_arms}")
        self.model, one = build_world(
            n_arms=1, hand=hand, object_width=object_width, scene=scene, payload=payload
        )
        self.layout: ArmLayout = repeat_layout(one, n_arms)
        #: robot i's MjData (all of the one model)
        self.datas: tuple[mujoco.MjData, ...] = tuple(
            mujoco.MjData(self.model) for _ in range(n_arms)
        )
        #: robot 0's MjData (the socket server's one robot; rendering)
        self.data = self.datas[0]
        #: the model robot i steps: the shared one, or its own under a reality draw
        #: (:meth:`enable_truth`)
        self.models: tuple[mujoco.MjModel, ...] = (self.model,) * n_arms
        #: the true arms and worlds of a reality draw (sim/truth.py); None: the model is
        #: the arm (the ideal robot)
        self.truth: ArmTruth | None = None
        self._own_models = False
        self._steps = None  # the C plan of a cycle's physics, made at the first step
        self.n = n_arms
        self.hand = hand
        #: (n, 3) every base at its world's origin (zeros, read-only)
        self.base_pos = np.zeros((n_arms, 3))
        self.base_pos.flags.writeable = False
        datas = self.datas

        def rows(field: str, index) -> ArmRows:
            return ArmRows([getattr(d, field) for d in datas], index)

        self._qpos = rows("qpos", one.qpos_adr[0])
        self._qvel = rows("qvel", one.dof_adr[0])
        self._ctrl = rows("ctrl", one.actuator_ids[0])
        self._bias = rows("qfrc_bias", one.dof_adr[0])
        self._gravcomp = rows("qfrc_gravcomp", one.dof_adr[0])
        self._actuator = rows("qfrc_actuator", one.dof_adr[0])
        self._flange_pos = rows("site_xpos", one.flange_site[0])
        self._flange_mat = rows("site_xmat", one.flange_site[0])
        self._joints = self.model.dof_jntid[np.asarray(one.dof_adr[0])]
        self._axes = rows("xaxis", self._joints)
        self._anchors = rows("xanchor", self._joints)
        self._fingers = None
        #: (n,) every hand's finger force limit [N] (None: no hand), applied to the shared
        #: model's actuator force range before each arm's world steps
        self.finger_force: np.ndarray | None = None
        if one.finger_qpos_adr is not None:
            self._fingers = rows("qpos", one.finger_qpos_adr[0])
            self._finger_ctrl = rows("ctrl", one.finger_actuator[:1])
            self._finger_act = int(one.finger_actuator[0])
            self.finger_force = np.full(n_arms, self.model.actuator_forcerange[self._finger_act, 1])
            # the limit the shared model holds now (1,): set by forward and by the steps
            self._applied_force = self.finger_force[:1].copy()
        self._payload = None if one.payload_body is None else rows("xipos", one.payload_body[0])
        self._link_contacts = rows("sensordata", one.link_contact_adr[0])
        #: (n, 7) measured joint positions, velocities and torques (refreshed in place
        #: after every step and reset)
        self.q = self._qpos.out
        self.dq = self._qvel.out
        self.tau_J = self._actuator.out
        # What the internal servos read of the joints: the true state, or the robot's
        # measurement of it under a reality draw (:meth:`sense_with`).
        self._servo_q, self._servo_dq = self.q, self.dq
        # every arm's 7 ctrl rows as a contiguous float64 view of its MjData: the C servo
        # writes them (sim/_stepping.c servo_run)
        views = self._ctrl.views
        if views is None or not all(v.flags.c_contiguous and v.shape == (7,) for v in views):
            raise ValueError("the arm's 7 torque actuators must be adjacent in the model")
        self.kp = np.empty((n_arms, 7))
        self.kd = np.empty((n_arms, 7))
        self.coriolis = np.zeros((n_arms, 7))
        #: (n, 7) the weight torque of a payload nobody configured (zero without one)
        self.payload_weight = np.zeros((n_arms, 7))
        self._all_arms = np.ones(n_arms, dtype=bool)  # external=True's mask
        #: the flange's position (n, 3) and its rotation transposed (n, 3, 3) -- the
        #: column-major wire layout of O_T_EE's block -- refreshed after every step
        self.flange_views: tuple[np.ndarray, np.ndarray] = (
            self._flange_pos.out,
            self._flange_mat.out.reshape(n_arms, 3, 3).transpose(0, 2, 1),
        )
        # Every slice the cycle reads after a step, copied in one call (sim/_rows.c):
        # the measured state, the bias forces, the joints' axes and anchors of the
        # Jacobians, the link contact sensors, and what the readers added (gather_also).
        self._after_step = [self._qpos, self._qvel, self._actuator, self._flange_pos]
        self._after_step += [self._flange_mat, self._bias, self._gravcomp, self._axes]
        self._after_step += [self._anchors, self._link_contacts]
        if self._payload is not None:
            self._after_step.append(self._payload)
        self._gathering = Gathering(self._after_step)
        self._effective_inertia, self._cartesian_inertia = self._home_inertia()
        self._nullspace_damping = damping_for(NULLSPACE_STIFFNESS, self._effective_inertia)
        self.set_stiffness(np.arange(n_arms), DEFAULT_STIFFNESS)
        self.reset_arms(np.arange(n_arms), np.broadcast_to(HOME_Q, (n_arms, 7)))

    # -- configuration -------------------------------------------------------------------------

    def _home_inertia(self) -> tuple[np.ndarray, np.ndarray]:
        """At home: the diagonal of the joint-space inertia (armature included) and of
        the flange's Cartesian inertia (J M^-1 J^T)^-1, what the servos damp against."""
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

    def enable_truth(self, scene: bool = False) -> ArmTruth:
        """The arms become their reality draws' (sim/truth.py): extra joint forces every
        step, and with ``scene`` every robot its own copy of the world's model for its
        draw's scene (the shared ``model`` stays the nominal one). Once."""
        if self.truth is None:
            self.truth = ArmTruth(self, scene)
            if self.truth.models is not None:
                self.models = self.truth.models
                self._own_models = True
                self._steps = None
                if self.finger_force is not None:
                    for i in range(self.n):
                        self._set_model_finger_force(i)
        return self.truth

    def sense_with(self, q: np.ndarray, dq: np.ndarray) -> None:
        """The internal servos read ``q``, ``dq`` (n, 7; arrays updated in place: the
        robot's measurements) instead of the true joint state."""
        self._servo_q, self._servo_dq = q, dq
        self._steps = None  # the C plan reads the servo's arrays

    # -- state ---------------------------------------------------------------------------------

    def reset_arms(self, arms: np.ndarray, q: np.ndarray) -> None:
        """Teleport ``arms`` to joint positions ``q`` at rest (a reset, not a motion)."""
        arms = np.atleast_1d(np.asarray(arms, dtype=np.intp))
        q = np.asarray(q, dtype=np.float64).reshape(len(arms), 7)
        lay = self.layout
        for k, i in enumerate(arms.tolist()):
            data = self.datas[i]
            model = self.models[i]
            data.qpos[lay.qpos_adr[i]] = q[k]
            data.qvel[lay.dof_adr[i]] = 0.0
            data.qacc_warmstart[lay.dof_adr[i]] = 0.0
            data.ctrl[lay.actuator_ids[i]] = 0.0
            # Every dof of the arm's world restarts with no warm start, so an episode does
            # not depend on how long the world ran on after the arm's last one ended (the
            # vector env steps a stopped arm to the end of the step; a single env stops).
            if lay.finger_qpos_adr is not None:
                data.qpos[lay.finger_qpos_adr[i]] = FINGER_OPEN
                data.qvel[lay.finger_dof_adr[i]] = 0.0
                data.qacc_warmstart[lay.finger_dof_adr[i]] = 0.0
                data.ctrl[lay.finger_actuator[i]] = FINGER_OPEN
            # The scene objects back where their fragment put them, at rest (a task then
            # places them for its episode).
            for joint, qadr in lay.scene_qpos_adr.items():
                adr, dof = int(qadr[i]), int(lay.scene_dof_adr[joint][i])
                data.qpos[adr : adr + 7] = model.qpos0[adr : adr + 7]
                data.qvel[dof : dof + 6] = 0.0
                data.qacc_warmstart[dof : dof + 6] = 0.0
        self.forward(arms)

    def forward(self, arms: np.ndarray) -> None:
        """mj_forward on the worlds of ``arms`` (after their state was set: a reset, an
        object placed), and the measured arrays refreshed."""
        for i in np.atleast_1d(np.asarray(arms, dtype=np.intp)).tolist():
            self._apply_finger_force(i)
            mujoco.mj_forward(self.models[i], self.datas[i])
        self._refresh()

    def set_finger_force(self, arms, force) -> None:
        """The finger force limit [N] of the hands of ``arms`` from the next step on (the
        fingers' position servo saturates there: models/hand.xml)."""
        if self.finger_force is None:
            raise ValueError("no hand is mounted (ArmPhysics(hand=True) mounts one)")
        self.finger_force[arms] = force
        if self._own_models:  # every arm's own model holds its own limit
            for i in np.atleast_1d(np.arange(self.n)[arms]).tolist():
                self._set_model_finger_force(i)

    def _set_model_finger_force(self, i: int) -> None:
        force = float(self.finger_force[i])
        self.models[i].actuator_forcerange[self._finger_act] = (-force, force)

    def _apply_finger_force(self, i: int) -> None:
        """The shared model's finger force range set to arm i's (only when it differs:
        sim/_stepping.c, the rule's one text)."""
        if self._own_models or self.finger_force is None:
            return
        self._planned_steps().limit(i, self.finger_force)

    def gather_also(self, *rows: ArmRows) -> None:
        """Refresh ``rows`` (slices of these arms' MjData, e.g. sim/dynamics.py's model
        terms) with the measured state after every step, reset and forward, in the same
        call; gathered once now."""
        self._after_step.extend(rows)
        self._gathering = Gathering(self._after_step)
        for r in rows:
            r.gather()

    def _refresh(self) -> None:
        """Gather the measured quantities of every robot's MjData into the (n, ...) arrays
        (in place: references to ``q``, ``dq``, ``tau_J``, ``flange_views`` stay valid).
        qfrc_actuator is what mj_step2 applied; mj_step1 leaves it alone."""
        self._gathering.gather()
        self._update_coriolis()

    def _update_coriolis(self) -> None:
        """C(q, dq) dq of the new state: the bias forces without the gravity MuJoCo's
        actuators compensate; a payload nobody configured (gravcomp 0) is not in that
        compensation, and its weight is not Coriolis: it is left to sag the arm."""
        np.subtract(self._bias.out, self._gravcomp.out, out=self.coriolis)
        if self._payload is not None:
            self.payload_weight[...] = self._payload_weight()
            self.coriolis -= self.payload_weight

    def _payload_weight(self) -> np.ndarray:
        """(n, 7) the joint torques that would hold the payloads against gravity."""
        lay = self.layout
        J = self.jacobian(self._payload.out)
        return weight_torque(J, self.model.body_mass[lay.payload_body], self.model.opt.gravity)

    @property
    def joint_axes(self) -> np.ndarray:
        """(n, 7, 3) the joints' unit axes in each arm's base frame (refreshed in place)."""
        return self._axes.out

    @property
    def joint_anchors(self) -> np.ndarray:
        """(n, 7, 3) a point of each joint's axis (its body's origin), base frame."""
        return self._anchors.out

    def jacobian(self, point: np.ndarray) -> np.ndarray:
        """(n, 6, 7) geometric Jacobian of ``point`` (n, 3, each arm's base frame) on each
        arm's last link, from the joints' axes and anchors of the current state."""
        return jacobian_at(self._axes.out, self._anchors.out, point)

    def link_contacts(self) -> np.ndarray:
        """(n,) bool: arm i's world reports a contact of a link with a link three or more
        further down the chain, or with the hand (world.py's contact sensors): the arms
        whose contact list a self-collision check must read."""
        return self._link_contacts.out.any(axis=1)

    def any_link_contact(self) -> bool:
        """Whether any arm's world reports a link contact (:meth:`link_contacts`): the
        usual answer, no, in one look."""
        return bool(np.count_nonzero(self._link_contacts.out))

    def set_finger_width(self, arms: np.ndarray, width: np.ndarray) -> None:
        """Target opening width [m] of the hands of ``arms`` (the fingers' position servo
        takes half of it per finger: models/hand.xml)."""
        if self._fingers is None:
            raise ValueError("no hand is mounted (ArmPhysics(hand=True) mounts one)")
        arms = np.atleast_1d(np.asarray(arms, dtype=np.intp))
        half = np.broadcast_to(np.asarray(width, dtype=float) / 2.0, arms.shape)
        self._finger_ctrl.scatter(half[:, None], arms)

    def finger_width(self) -> np.ndarray:
        """(n,) measured opening width [m]: the two finger joints summed."""
        if self._fingers is None:
            raise ValueError("no hand is mounted")
        return self._fingers.gather().sum(axis=1)

    @property
    def time(self) -> float:
        """Simulated time [s] (every robot's world steps in lockstep)."""
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
        gains: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> None:
        """Advance the world by one 1 ms cycle.

        Args:
            q_ref, dq_ref: (n, 7) float64 joint reference of the internal joint impedance
                servo; ``dq_ref=None`` holds at rest (zero reference velocity). Every
                array here is (n, 7) float64 (the servo's C text takes no broadcast).
            tau_external: (n, 7) commanded torque *without gravity*, applied where
                ``external`` says; gravity is added by the actuators.
            external: None or False (no arm under external torque), True (every
                arm), or an (n,) bool mask.
            cartesian: the arms (its ``mask``) whose internal servo is the Cartesian
                impedance (sim/cartesian_servo.py) holding K on a pose; their
                ``q_ref`` is the nullspace's joint target.
            compensation: (n, 7) a torque the drives add in every mode (the weight
                of a load configured with SetLoad, which MuJoCo does not know of).
            gains: (K, D), (n, 7) each: the joint servo's stiffness and damping this
                cycle instead of :meth:`set_stiffness`'s (the controller's idle hold
                keeps the gains it was captured with).
        """
        kp, kd = (self.kp, self.kd) if gains is None else gains
        steps = self._planned_steps()
        finger_force = None if self._own_models else self.finger_force
        if external is not None and external is not True and external is not False:
            if not np.count_nonzero(external):
                external = None  # a mask of no arm: no arm under external torque
        if cartesian is None and (external is None or external is False):
            # The internal joint impedance servo, its torque into every arm's ctrl rows and
            # the step: one C call (sim/_stepping.c servo_run: the servo's one text)
            if self.truth is not None:
                self.truth.before_step()
            steps.servo_run(finger_force, q_ref, dq_ref, kp, kd, compensation)
            self._refresh()
            return
        # Every arm's joint servo into its ctrl rows, then the arms under the Cartesian
        # servo or an external torque their own (sim/_stepping.c torque and own: the
        # composition's one text, Coriolis and compensation as the joint servo's).
        if external is not True:  # (every arm under external torque: no joint servo's)
            steps.torque(q_ref, dq_ref, kp, kd, compensation)
        servo_tau = servo_arms = under = None
        if cartesian is not None:
            servo_tau, servo_arms = self._cartesian_servo(cartesian, q_ref), cartesian.mask
        if external is not None and external is not False:
            under = self._all_arms if external is True else external
        steps.own(
            servo_tau, servo_arms, tau_external if under is not None else None, under, compensation
        )
        if self.truth is not None:
            self.truth.before_step()
        # mj_step2 then mj_step1 of every arm's world; on one shared model with a hand its
        # finger limit set to each arm's first (every arm's own model, a reality draw's,
        # holds its own)
        steps.run(finger_force)
        self._refresh()

    def _planned_steps(self):
        """The C plan of a cycle's physics, made where what it holds changed."""
        if self._steps is None:
            self._steps = self._plan_steps()
        return self._steps

    def _plan_steps(self):
        """The C plan of a cycle's physics (sim/_stepping.c) over :attr:`models` and
        :attr:`datas`, and the shared model's finger limit where there is one to set."""
        functions = (
            function_address("mj_step2"),
            function_address("mj_step1"),
            function_address("mju_setLogHandler"),
        )
        if not all(functions):
            raise ImportError(
                "franka_sim_gym needs the libmujoco the mujoco package ships "
                f"(mj_step2, mj_step1, mju_setLogHandler): found {functions}"
            )
        shared = self.finger_force is not None and not self._own_models
        steps = STEPPING.Steps(
            functions,
            tuple(self.models),
            tuple(self.datas),
            self.model.actuator_forcerange if shared else None,
            self._finger_act if shared else -1,
            self._applied_force if shared else None,
        )
        steps.servo(self._servo_q, self._servo_dq, self.coriolis, tuple(self._ctrl.views))
        return steps

    def _cartesian_servo(self, target: CartesianTarget, q_ref: np.ndarray) -> np.ndarray:
        """(n, 7) the Cartesian impedance servo's torque (without Coriolis) of every arm."""
        flange_p, flange_R = self.flange_pose()
        k = target.flange_to_k
        rotation = flange_R @ k[:, :3, :3]
        position = flange_p + np.einsum("nij,nj->ni", flange_R, k[:, :3, 3])
        J = self.jacobian(position)
        damping = damping_for(target.stiffness, self._cartesian_inertia)
        q, dq = self._servo_q, self._servo_dq
        return impedance_torque(
            J, position, rotation, target, damping, q, dq, q_ref, self._nullspace_damping
        )

    # -- kinematics ----------------------------------------------------------------------------

    def flange_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """Flange (link8) position (n, 3) and rotation (n, 3, 3) in each arm's base frame
        (copies; arm bases are not rotated)."""
        return self._flange_pos.out.copy(), self._flange_mat.out.reshape(self.n, 3, 3).copy()
