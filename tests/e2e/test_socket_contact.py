"""End to end against the table: real clients meet the FR3's collision detection.

`serve --enforce-motion-limits` (collision reflexes abort like every other reflex);
pylibfranka descends onto the table under SetCollisionBehavior's thresholds, franky
runs the reaction pattern of its own examples. The pylibfranka descents, presses and the
example's motions run in lockstep (`--lockstep`: the same cycles and physics, at the
client's pace instead of the wall clock's, 3-4 times faster here; their
`--enforce-comm-constraints` is the example's setting, and in lockstep it fires only
after answers 900 ms late); the wall-clock server has its own tests
(test_socket_realtime.py, test_socket_pylibfranka.py, franky's here).
"""

from __future__ import annotations

import pytest

pytestmark = pytest.mark.socket

#: the pylibfranka scenarios' server: in lockstep, no gripper server beside it. Each
#: state waits up to 900 ms for its answer, still inside libfranka's 1 s: with the
#: default 50 ms, a fresh clone's suite run beside other work saw the contact flag first
#: in the state just before the collision's, as when the descent's cycles go on without
#: a late client's answers; these tests read every state between 10 and 20 N.
LOCKSTEP = ("--lockstep", "--lockstep-timeout", "900", "--no-gripper")


@pytest.mark.parametrize("upper", [20.0, 60.0])
def test_a_descent_onto_the_table_ends_in_a_collision_reflex_near_the_threshold(
    serve, client, upper
):
    server = serve(*LOCKSTEP, "--enforce-motion-limits")
    r = client("contact", "descend", server.host, env={"FORCE": f"10,{upper}"}, timeout=90)
    assert "exception" not in r, r
    assert r["error"] is not None and "motion aborted by reflex" in r["error"], r
    assert "cartesian_reflex" in r["error"] or "joint_reflex" in r["error"], r
    # The contact flag came first (lower threshold 10 N), then the collision at the upper.
    assert r["first_contact"] is not None and r["first_contact"][0] < r["t_end"]
    # The last state the client saw before the reflex: just under the threshold (the
    # next one crossed it and carried the abort).
    assert 0.8 * upper < -r["F_z_min"] <= upper
    # The flange stopped at the table: within 5 mm of where contact began, 18 cm below
    # where it started at most.
    assert abs(r["z_end"] - r["first_contact"][1]) < 5e-3
    assert r["robot_mode"] == "Reflex"
    assert "cartesian_reflex" in r["current_errors"] or "joint_reflex" in r["current_errors"]
    assert r["cartesian_collision"][2] == 1.0  # latched on z ...
    assert r["mode_recovered"] == "Idle"  # ... until AutomaticErrorRecovery
    assert r["cartesian_collision_recovered"] == [0.0] * 6
    assert "external wrench at K" in server.log()  # logged, naming what crossed


def test_at_rest_in_free_space_nothing_is_sensed(serve, client):
    server = serve()
    r = client("contact", "rest", server.host)
    assert r["worst_tau"] < 0.05
    assert r["worst_force"] < 0.5
    assert r["flags"] == 0.0


def test_frankys_force_reaction_fires_at_the_table(serve, client):
    # Lockstep: what is tested is where the reaction fires, not the client's timing; a
    # loaded machine that stalls the client would otherwise lose cycles and trip a
    # discontinuity before the table is reached (docs/socket.md "Lockstep").
    server = serve("--enforce-motion-limits", "--lockstep")
    r = client("franky_contact", "reaction", server.host, timeout=120)
    assert "exception" not in r, r
    assert r["error"] is None, r
    assert r["fired"], "the reaction never fired"
    force_z, z_fired = r["fired"][0]
    assert force_z < -5.0
    assert r["z_start"] - z_fired < 0.2  # at the table, not 30 cm down
    assert r["z_end"] > z_fired  # ... and the retreat moved it up
    assert r["robot_mode"] == "Idle"


@pytest.mark.parametrize("stiffness", [500.0, 1500.0])
def test_under_cartesian_impedance_a_pose_2_cm_into_the_table_presses_stiffness_times_2_cm(
    serve, client, stiffness
):
    server = serve(*LOCKSTEP, "--enforce-motion-limits")
    r = client(
        "contact", "impedance_press", server.host, env={"STIFFNESS": str(stiffness)}, timeout=90
    )
    assert "exception" not in r, r
    assert r["error"] is None, r
    assert r["z"] > r["z_commanded"] + 0.015  # held at the table, 2 cm above the command
    assert -r["F_z"] == pytest.approx(stiffness * 0.02, rel=0.25)


@pytest.mark.parametrize(("load", "rises"), [(1.0, True), (0.0, False)])
def test_a_configured_load_that_is_not_there_lifts_the_arm_under_zero_torque(
    serve, client, load, rises
):
    server = serve()
    r = client("contact", "zero_torque", server.host, env={"LOAD": str(load)})
    assert r.get("error") is None, r
    if rises:
        assert r["rise"] > 5e-3
    else:
        assert abs(r["rise"]) < 2e-3


def test_pylibfranka_cartesian_velocity_examples_motion_in_free_space_senses_nothing(serve, client):
    """pylibfranka's cartesian_velocity_example.py's calls and motion (its joint moves in
    free space) under the example's 20 N thresholds: it completes, no flag rises, the
    estimate stays far below the default lower thresholds (12 to 20 Nm, 20 to 25 N)."""
    server = serve(*LOCKSTEP, "--enforce-motion-limits", "--enforce-comm-constraints")
    r = client("example_motion", "free", server.host, timeout=120)
    assert "exception" not in r, r
    assert r["error"] is None, r
    assert r["robot_mode"] == "Idle"
    assert r["flags"] == 0.0
    assert max(r["tau_peak"]) < 0.1, r["tau_peak"]
    assert max(r["force_peak"]) < 0.5, r["force_peak"]


def test_pylibfranka_cartesian_velocity_examples_own_goal_meets_the_table(serve, client):
    """The example's own q_goal (joint 2 at +pi/4, where libfranka's C++ examples have
    -pi/4) puts the flange 2.6 cm above the table plane: the joint move collides with the
    table and ends in cartesian_reflex at the table; every state before the impact read
    no external force."""
    server = serve(*LOCKSTEP, "--enforce-motion-limits", "--enforce-comm-constraints")
    r = client("example_motion", "example_goal", server.host, timeout=120)
    assert "exception" not in r, r
    assert r["stage"] == "joint", r
    assert r["error"] is not None and "cartesian_reflex" in r["error"], r
    assert r["z"] < 0.07, r  # the flange stopped 7 cm above the table plane at most
    assert max(r["force_peak"]) < 0.5, r["force_peak"]  # free space until the impact
    assert r["robot_mode"] == "Reflex"
