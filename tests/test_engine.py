"""The engine's fused fast path decides exactly as the rule functions do."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from franka_sim_gym.fci import limits

from .fci_helpers import IMP, JP, LoopClient, make_controller

CTRL = make_controller()
LoopClient(CTRL).start(JP, IMP)
ENGINE = CTRL.engine
TABLE = CTRL.table


@settings(max_examples=300, deadline=None)
@given(
    joint=st.integers(0, 6),
    q_offset=st.floats(-3.2, 3.2),
    velocity=st.floats(-3.0, 3.0),
    acceleration=st.floats(-12.0, 12.0),
    jerk=st.floats(-6000.0, 6000.0),
)
def test_fast_path_agrees_with_check_joint_position(joint, q_offset, velocity, acceleration, jerk):
    dt = 1e-3
    ref = CTRL.reference
    ref.q[0] = np.clip(TABLE.q_lower + (TABLE.q_upper - TABLE.q_lower) / 2 + 0.0, -3, 4)
    ref.q[0, joint] = np.clip(q_offset, TABLE.q_lower[joint] - 0.05, TABLE.q_upper[joint] + 0.05)
    ref.dq[0] = 0.0
    ref.ddq[0] = 0.0
    ref.dq[0, joint] = velocity - acceleration * dt
    ref.ddq[0, joint] = acceleration - jerk * dt
    ENGINE.invalidate_envelope()
    q_c = ref.q.copy()
    q_c[0, joint] += velocity * dt
    fast = ENGINE._positions_inside_limits(q_c)
    rule = limits.check_joint_position(
        q_c, ref.q, ref.dq, ref.ddq, False, ref.q, 1, TABLE, 0.1
    ).error
    assert fast == (rule[0] == limits.NO_ERROR)


@settings(max_examples=100, deadline=None)
@given(answers=st.lists(st.booleans(), min_size=1, max_size=260))
def test_one_robot_accounting_matches_the_batched_arithmetic(answers):
    from franka_sim_gym.fci.accounting import CycleAccounting

    one, two = CycleAccounting(1), CycleAccounting(2)  # n = 2 takes the array path
    for acc in (one, two):
        acc.start_motion(0, 0)
        acc.started[0] = True
    for answered in answers:
        one.answered[0] = two.answered[0] = answered
        one.close_cycle(1)
        two.close_cycle(1)
        assert one.success_rate()[0] == two.success_rate()[0]
        assert one.lost_run[0] == two.lost_run[0]
        assert one.longest_lost_run[0] == two.longest_lost_run[0]
        assert one.lost_total[0] == two.lost_total[0]
