"""The entry point every client script shares: `python X_client.py SCENARIO HOST`.

Runs ``scenario_<SCENARIO>(HOST)`` from the calling script and prints its result
as one JSON line, the last line of stdout; an exception becomes
``{"exception_type", "exception"}`` (the tests read the type and the text a
libfranka client sees).
"""

from __future__ import annotations

import json
import select
import sys
from collections.abc import Callable


def run(scenarios: dict) -> None:
    """Run the scenario named on the command line from ``scenarios`` (a module's globals)."""
    name, host = sys.argv[1], sys.argv[2]
    try:
        result = scenarios[f"scenario_{name}"](host)
    except Exception as exc:  # the test reads the exception type and text
        result = {"exception_type": type(exc).__name__, "exception": str(exc)}
    print(json.dumps(result), flush=True)


#: What a holding scenario prints once its connection is up (hold_until_told).
HOLDING = "holding"


def hold_until_told(read_id: Callable[[], int], more: int) -> dict:
    """Read states with ``read_id()`` (a state's message id) until a line arrives on
    stdin, then ``more`` states: the 'first client' of a second-client test, which
    tells it when the second has been turned away. Prints HOLDING once a state came.

    Returns the message ids: the first read, the last read before the line, and those
    read after it (the stream goes on after the refusal: judged in the robot's count).
    """
    first = read_id()
    print(HOLDING, flush=True)
    reads, last = 1, first
    while not select.select([sys.stdin], [], [], 0)[0]:
        last = read_id()
        reads += 1
    after = [read_id() for _ in range(more)]
    return {"reads": reads, "first_id": first, "told_id": last, "after_ids": after}
