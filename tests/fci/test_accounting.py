"""The batched cycle accounting (fci/accounting.py) against its rule, cycle by cycle.

control_command_success_rate is the fraction of the last 100 cycles of the running motion
that were answered (while the window fills, of the cycles it holds); lost_run counts the
unanswered cycles since the last answered one (docs/fci-behaviour.md "The cycle
contract"); the close of a cycle counts the robots at the 20-cycle bound. Long streaks
of answered cycles take the accounting's steady path (every robot answered for a whole
window), losses and restarts leave it.
"""

from __future__ import annotations

from hypothesis import example, given, settings
from hypothesis import strategies as st

from franka_sim_gym.fci.accounting import CycleAccounting
from franka_sim_gym.fci.tables import MAX_LOST_CYCLES, SUCCESS_RATE_WINDOW

#: (cycles, robot 0 answers, robot 1 answers, robot 1's motion restarts first)
_STRETCH = st.tuples(st.integers(1, 250), st.booleans(), st.booleans(), st.booleans())


@settings(max_examples=60, deadline=None)
@given(stretches=st.lists(_STRETCH, min_size=1, max_size=8))
@example(stretches=[(250, True, True, False), (3, False, True, False), (120, True, True, True)])
@example(stretches=[(230, True, True, False), (40, True, True, True), (5, True, False, False)])
@example(stretches=[(5, True, True, False), (25, False, True, False), (3, True, False, True)])
def test_success_rate_and_lost_run_follow_the_last_window_of_answers(stretches):
    n = 2
    acc = CycleAccounting(n)
    history = [[], []]
    for i in range(n):
        acc.start_motion(i, 0)
        acc.started[i] = True
    for cycles, *answers, restart in stretches:
        if restart:
            acc.start_motion(1, 0)
            acc.started[1] = True
            history[1] = []
        for _ in range(cycles):
            for i in range(n):
                acc.answered[i] = answers[i]
                history[i].append(answers[i])
            at_bound = acc.close_cycle()
            assert at_bound == sum(int(acc.lost_run[i]) >= MAX_LOST_CYCLES for i in range(n))
            for i in range(n):
                window = history[i][-SUCCESS_RATE_WINDOW:]
                assert acc.success_rate()[i] == sum(window) / len(window)
                last_answer = max((k for k, a in enumerate(history[i]) if a), default=-1)
                assert acc.lost_run[i] == len(history[i]) - 1 - last_answer
                assert acc.motion_summary(i) == (
                    len(history[i]),
                    history[i].count(False),
                    _longest_false_run(history[i]),
                )
                assert not acc.answered[i]


def _longest_false_run(answers: list[bool]) -> int:
    best = run = 0
    for a in answers:
        run = 0 if a else run + 1
        best = max(best, run)
    return best
