"""pylibfranka Gripper scenarios, each run in its own process by the socket tests.

`python gripper_client.py SCENARIO HOST` prints one JSON line (the scenario's
result) as its last line; an exception becomes {"exception_type", "exception"}.
"""

from __future__ import annotations

import os
import time

import pylibfranka as fr
import scenario_main  # tests/e2e/clients/scenario_main.py: the shared entry point


def state_dict(gripper: fr.Gripper) -> dict:
    state = gripper.read_once()
    return {
        "width": state.width,
        "max_width": state.max_width,
        "is_grasped": state.is_grasped,
        "temperature": state.temperature,
    }


def timed(call) -> tuple[object, float]:
    start = time.monotonic()
    result = call()
    return result, time.monotonic() - start


def scenario_homing(host: str) -> dict:
    gripper = fr.Gripper(host)
    ok, seconds = timed(gripper.homing)
    return {
        "ok": ok,
        "seconds": seconds,
        "version": gripper.server_version(),
        **state_dict(gripper),
    }


def scenario_homing_from_closed(host: str) -> dict:
    """Close to 2 cm, then homing: it must open the fingers again."""
    gripper = fr.Gripper(host)
    moved = gripper.move(0.02, 0.1)
    closed = gripper.read_once().width
    ok, seconds = timed(gripper.homing)
    return {"moved": moved, "closed": closed, "ok": ok, "seconds": seconds, **state_dict(gripper)}


def scenario_open_close(host: str) -> dict:
    """Close to 1 cm and open again, CYCLES times at 5 cm/s (the arm may move meanwhile)."""
    gripper = fr.Gripper(host)
    results, widths = [], []
    for _ in range(int(os.environ.get("CYCLES", "2"))):
        for width in (0.01, 0.08):
            results.append(gripper.move(width, 0.05))
            widths.append(gripper.read_once().width)
    return {"results": results, "widths": widths}


def scenario_move(host: str) -> dict:
    """Open fully, then move to 4 cm at 2 cm/s: 2 s if the speed is honoured."""
    gripper = fr.Gripper(host)
    gripper.move(0.08, 0.1)
    ok, seconds = timed(lambda: gripper.move(0.04, 0.02))
    return {"ok": ok, "seconds": seconds, **state_dict(gripper)}


def scenario_grasp(host: str) -> dict:
    """grasp(0.04) at 5 cm/s from fully open."""
    gripper = fr.Gripper(host)
    gripper.move(0.08, 0.1)
    ok, seconds = timed(lambda: gripper.grasp(0.04, 0.05, 20.0))
    return {"ok": ok, "seconds": seconds, **state_dict(gripper)}


def scenario_grasp_zero(host: str) -> dict:
    gripper = fr.Gripper(host)
    ok = gripper.grasp(0.0, 0.1, 20.0)
    return {"ok": ok, **state_dict(gripper)}


def scenario_out_of_stroke(host: str) -> dict:
    """A width beyond the stroke raises; the connection keeps working afterwards."""
    gripper = fr.Gripper(host)
    errors = []
    for call in (lambda: gripper.move(0.1, 0.1), lambda: gripper.grasp(-0.01, 0.1, 20.0)):
        try:
            call()
            errors.append(None)
        except Exception as exc:
            errors.append(f"{type(exc).__name__}: {exc}")
    return {"errors": errors, "homing_after": gripper.homing(), **state_dict(gripper)}


def scenario_hold(host: str) -> dict:
    """Hold one connection, reading the state, until told on stdin; then 10 states more
    and a move (scenario_main.hold_until_told)."""
    gripper = fr.Gripper(host)
    held = scenario_main.hold_until_told(
        lambda: round(gripper.read_once().time.to_sec() * 1000), more=10
    )
    ok = gripper.move(0.05, 0.1)
    return {**held, "move_after": ok, **state_dict(gripper)}


def scenario_connect_only(host: str) -> dict:
    try:
        gripper = fr.Gripper(host)
        return {"error": None, **state_dict(gripper)}
    except Exception as exc:
        return {"error": f"{type(exc).__name__}: {exc}"}


if __name__ == "__main__":
    scenario_main.run(globals())
