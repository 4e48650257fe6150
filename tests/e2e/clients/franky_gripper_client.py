"""franky Gripper scenarios (franky-control 2.0.0), each run in its own process.

`python franky_gripper_client.py SCENARIO HOST` prints one JSON line as its
last line. franky and pylibfranka cannot share a process (their pybind11 types
collide), hence this second script beside gripper_client.py. franky's
``*_async`` calls return a future without holding the GIL, which is what lets
one connection send Stop while a Move is outstanding.
"""

from __future__ import annotations

import time

import franky
import scenario_main  # tests/e2e/clients/scenario_main.py: the shared entry point


def state_dict(gripper: franky.Gripper) -> dict:
    return {
        "width": gripper.width,
        "max_width": gripper.max_width,
        "is_grasped": gripper.is_grasped,
    }


def scenario_homing_move(host: str) -> dict:
    gripper = franky.Gripper(host)
    homing = gripper.homing()
    after_homing = gripper.width
    start = time.monotonic()
    move = gripper.move(0.04, 0.05)
    seconds = time.monotonic() - start
    return {
        "homing": homing,
        "width_after_homing": after_homing,
        "move": move,
        "move_seconds": seconds,
        "opened": gripper.open(0.1),
        **state_dict(gripper),
    }


def scenario_stop_mid_move(host: str) -> dict:
    """Close from 8 cm towards 0 at 2 cm/s; stop() on the same connection after 0.3 s."""
    gripper = franky.Gripper(host)
    gripper.homing()
    start_width = gripper.width
    future = gripper.move_async(0.0, 0.02)
    time.sleep(0.3)
    stop = gripper.stop()
    try:
        move: object = future.get()
    except Exception as exc:  # the interrupted command's answer
        move = f"{type(exc).__name__}: {exc}"
    width_at_stop = gripper.width
    time.sleep(0.5)
    return {
        "start_width": start_width,
        "stop": stop,
        "move": move,
        "width_at_stop": width_at_stop,
        **state_dict(gripper),
    }


def scenario_grasp(host: str) -> dict:
    """grasp(0.04) at 5 cm/s from fully open (franky passes libfranka's 5 mm epsilons)."""
    gripper = franky.Gripper(host)
    gripper.move(0.08, 0.1)
    ok = gripper.grasp(0.04, 0.05, 20.0, epsilon_inner=0.005, epsilon_outer=0.005)
    return {"ok": ok, **state_dict(gripper)}


def scenario_out_of_stroke(host: str) -> dict:
    """A width beyond the stroke raises through franky too; the connection keeps working."""
    gripper = franky.Gripper(host)
    try:
        gripper.move(0.1, 0.1)
        error = None
    except Exception as exc:
        error = f"{type(exc).__name__}: {exc}"
    return {"error": error, "homing_after": gripper.homing(), **state_dict(gripper)}


if __name__ == "__main__":
    scenario_main.run(globals())
