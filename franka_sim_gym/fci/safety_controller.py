"""The safety controller on the measured state (errors 2, 3, 4) and the communication
bound (25), judged every cycle of a motion after physics stepped.

docs/fci-behaviour.md "joint_velocity_violation (3)", "cartesian_velocity_violation (4)",
"self_collision_avoidance_violation (2)" and "Enabling the violation" (25). Not in any
generator's precedence chain: every control mode, 4 outranks 3, 2 is independent of
both. The rules are 3 and 4's one C text, run every cycle through
``limits.PlannedSafety`` (the same text as ``limits.check_safety``), with
``limits.describe_safety`` for the log line; the self-collision distances come from the
simulation (``sim.self_collision``).
"""

from __future__ import annotations

import numpy as np

from ..sim.arm import ArmPhysics
from ..sim.self_collision import close_link_pairs, closest_link_pair
from . import limits
from .accounting import CycleAccounting
from .config import ControllerConfig
from .engine import MotionLimitEngine
from .errors import ERROR_NAMES, Error
from .modes import Modes
from .tables import MAX_LOST_CYCLES


class SafetyController:
    """Watches the measured state of n robots; violations go to the engine."""

    def __init__(
        self,
        physics: ArmPhysics,
        O_T_EE: np.ndarray,
        modes: Modes,
        accounting: CycleAccounting,
        config: ControllerConfig,
        engine: MotionLimitEngine,
    ) -> None:
        self.physics = physics
        #: (n, 16) the measured pose as published (read)
        self.O_T_EE = O_T_EE
        self.modes = modes
        self.accounting = accounting
        self.config = config
        self.table = config.table
        self.engine = engine
        #: the measured EE position of the previous cycle (for the EE speed)
        self.ee_prev = np.zeros((physics.n, 3))
        self._planned = None  # errors 3 and 4 on these arrays, planned at the first check
        self._planned_margin = None
        self._ee = O_T_EE[:, 12:15]  # the measured EE position (a view of the pose)

    def remember_ee(self) -> None:
        """Keep the measured EE position before physics steps (the speed's other end)."""
        np.copyto(self.ee_prev, self._ee)

    def check(self) -> None:
        """Errors 3, 4 and 2 of the robots in motion (call after the step's state is written)."""
        physics, table = self.physics, self.table
        margin = self.config.measured_velocity_margin
        dq, q, ee = physics.dq, physics.q, self._ee
        # The measured EE speed at F_T_EE: the rule differences the measured O_T_EE
        # position over the 1 ms cycle (equal to J(q) dq to first order).
        planned = self._planned
        if planned is None or self._planned_margin != margin:  # the margin is the config's
            planned = self._planned = limits.PlannedSafety(dq, q, ee, self.ee_prev, table, margin)
            self._planned_margin = margin
        count = planned.run(self.modes.in_motion)
        if not count and not physics.any_link_contact():
            return  # the usual cycle: nothing over a limit, no link near another
        error, bad = planned.error, planned.bad
        distance = self.config.self_collision_distance
        close = close_link_pairs(physics, distance)
        if self.modes.n_motion < self.modes.n:
            close &= self.modes.in_motion
        if not count and not close.any():
            return
        bad = bad | close
        enforce = self.config.enforce_motion_limits
        for i in np.flatnonzero(bad).tolist():
            bits = []
            if error[i] >= 0:
                e = int(error[i])
                d = limits.describe_safety(i, dq, q, ee, self.ee_prev, table, margin)
                self.engine.report(i, e, d.message() if d else ERROR_NAMES[e], enforce)
                bits.append(e)
            if close[i]:
                e = int(Error.self_collision_avoidance_violation)
                pair = closest_link_pair(physics.model, physics.datas[i], physics.layout)
                where = f"link{pair[1]} / link{pair[2]} at {pair[0] * 1000:.1f} mm" if pair else ""
                self.engine.report(i, e, f"{where}, limit {distance * 1000:.0f} mm", enforce)
                bits.append(e)
            if enforce:
                self.engine.abort(i, bits)

    def communication_constraints(self) -> None:
        """docs/fci-behaviour.md "Enabling the violation": 20 consecutive lost cycles latch 25
        (opt-in)."""
        lost_run = self.accounting.lost_run
        over = (lost_run >= MAX_LOST_CYCLES) & self.modes.in_motion
        enforce = self.config.enforce_comm_constraints
        e = int(Error.communication_constraints_violation)
        for i in np.flatnonzero(over).tolist():
            run = int(lost_run[i])
            message = f"{run} consecutive lost cycles, limit {MAX_LOST_CYCLES}"
            self.engine.report(i, e, message, enforce)
            if enforce:
                self.engine.abort(i, [e])
