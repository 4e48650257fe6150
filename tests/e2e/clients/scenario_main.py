"""The entry point every client script shares: `python X_client.py SCENARIO HOST`.

Runs ``scenario_<SCENARIO>(HOST)`` from the calling script and prints its result
as one JSON line, the last line of stdout; an exception becomes
``{"exception_type", "exception"}`` (the tests read the type and the text a
libfranka client sees).
"""

from __future__ import annotations

import json
import sys


def run(scenarios: dict) -> None:
    """Run the scenario named on the command line from ``scenarios`` (a module's globals)."""
    name, host = sys.argv[1], sys.argv[2]
    try:
        result = scenarios[f"scenario_{name}"](host)
    except Exception as exc:  # the test reads the exception type and text
        result = {"exception_type": type(exc).__name__, "exception": str(exc)}
    print(json.dumps(result), flush=True)
