"""When the server's tick thread runs its next 1 ms cycle.

The robot's cycle is hard real time: every state leaves exactly 1 ms after the
last, and a client has the whole millisecond to answer it (the command must be
back before the next cycle, or that cycle is lost: docs/fci-behaviour.md "What the sim does with
a lost cycle"). A simulator on a shared, non-real-time host sometimes runs a
tick late. Catching up on the wall clock by running the missed ticks back to
back would leave the client no time to answer the states of the burst, and
count those cycles as lost against a client that did nothing wrong. So a late
state still gets a minimum answer window before the next cycle judges it, and
the schedule catches up over the following cycles instead, 1 ms minus that
window per cycle. The long-run rate stays 1000 states/s; only a lag longer than
``MAX_LAG_S`` is given up (the clock restarts: a slow host delays states, it
never skips physics).
"""

from __future__ import annotations

from ..fci.tables import DELTA_T as CYCLE_S  # the robot's cycle [s] (1 kHz), one definition

#: The shortest time [s] a state is given to be answered before the next cycle
#: receives commands. A Python readOnce/writeOnce client needs ~0.1-0.25 ms of work
#: between the two calls here (examples/deploy_pylibfranka.py measures a 116 us median,
#: 245 us p99), plus its wake-up; 0.6 ms covers both and still recovers a lag at
#: 0.4 ms per cycle.
MIN_ANSWER_WINDOW_S = 0.0006

#: A lag longer than this is not caught up: the clock restarts from now.
MAX_LAG_S = 0.005


def next_tick(scheduled: float, sent: float) -> tuple[float, float]:
    """(when to run the next tick, its slot on the 1 kHz schedule).

    Args:
        scheduled: the schedule slot of the tick that just ran.
        sent: when that tick's state left (the clock's now).
    """
    slot = scheduled + CYCLE_S
    if sent - slot > MAX_LAG_S:  # hopelessly behind: restart the clock
        return sent + CYCLE_S, sent + CYCLE_S
    return max(slot, sent + MIN_ANSWER_WINDOW_S), slot
