"""The kinematic Franka Hand (franka_sim_gym.sim.gripper), stepped by hand.

Behaviours: docs/fci-behaviour.md "Gripper fidelity".
"""

from __future__ import annotations

import math

import pytest

from franka_sim_gym.sim.gripper import MAX_WIDTH, FrankaHand, Outcome

DT = 0.001


def run(hand: FrankaHand, seconds: float = 10.0) -> float:
    """Step until the running action finishes; return the time it took."""
    t = 0.0
    while hand.busy and t < seconds:
        hand.step(DT)
        t += DT
    return t


def test_max_width_is_the_8_cm_stroke_and_the_hand_starts_open():
    hand = FrankaHand()
    assert hand.max_width == MAX_WIDTH == 0.08
    assert hand.width == MAX_WIDTH


def test_move_follows_the_commanded_speed_not_snapped():
    hand = FrankaHand()
    hand.move(0.04, 0.02)
    hand.step(0.5)
    assert hand.width == pytest.approx(0.08 - 0.01)
    assert hand.busy and hand.outcome is None
    assert run(hand) == pytest.approx(1.5, abs=2 * DT)
    assert hand.width == pytest.approx(0.04)
    assert hand.take_finished()[-1][1] is Outcome.SUCCESS


def test_homing_opens_to_max_width():
    hand = FrankaHand(width=0.01)
    hand.homing()
    run(hand)
    assert hand.width == MAX_WIDTH and hand.outcome is Outcome.SUCCESS


@pytest.mark.parametrize("width", [-0.001, 0.0801, math.nan, math.inf])
def test_width_outside_the_stroke_is_rejected(width):
    hand = FrankaHand()
    with pytest.raises(ValueError):
        hand.move(width, 0.1)
    with pytest.raises(ValueError):
        hand.grasp(width, 0.1, 20.0)
    assert not hand.busy


def test_non_positive_speed_is_rejected():
    with pytest.raises(ValueError):
        FrankaHand().move(0.04, 0.0)


def test_grasp_of_thin_air_closes_to_zero_and_fails():
    hand = FrankaHand()
    hand.grasp(0.04, 0.1, 20.0)
    run(hand)
    assert hand.width == 0.0
    assert hand.outcome is Outcome.UNSUCCESSFUL and not hand.is_grasped


def test_grasp_of_zero_on_nothing_succeeds():
    hand = FrankaHand()
    hand.grasp(0.0, 0.1, 20.0)
    run(hand)
    assert hand.outcome is Outcome.SUCCESS and hand.is_grasped


def test_grasp_stalls_on_the_object_and_passes_the_epsilon_test():
    hand = FrankaHand(object_width=0.04)
    hand.grasp(0.04, 0.1, 20.0)
    hand.step(0.2)  # 0.08 - 0.02: still closing
    assert hand.width == pytest.approx(0.06) and not hand.is_grasped
    run(hand)
    assert hand.width == pytest.approx(0.04)
    assert hand.outcome is Outcome.SUCCESS and hand.is_grasped


@pytest.mark.parametrize(
    ("width", "eps_inner", "eps_outer", "grasped"),
    [
        (0.04, 0.005, 0.005, True),
        (0.046, 0.005, 0.005, False),  # d = 0.04 <= width - eps_inner
        (0.034, 0.005, 0.005, False),  # d = 0.04 >= width + eps_outer
        (0.046, 0.01, 0.0, True),
    ],
)
def test_epsilon_band_is_libfrankas_open_interval(width, eps_inner, eps_outer, grasped):
    hand = FrankaHand(object_width=0.04)
    hand.grasp(width, 0.1, 20.0, eps_inner, eps_outer)
    run(hand)
    assert hand.is_grasped is grasped
    assert hand.outcome is (Outcome.SUCCESS if grasped else Outcome.UNSUCCESSFUL)


def test_inward_move_stops_at_the_object():
    hand = FrankaHand(object_width=0.04)
    hand.move(0.01, 0.1)
    run(hand)
    assert hand.width == pytest.approx(0.04)
    assert hand.outcome is Outcome.UNSUCCESSFUL


def test_opening_is_never_blocked_by_the_object():
    hand = FrankaHand(object_width=0.04)
    hand.grasp(0.04, 0.1, 20.0)
    run(hand)
    hand.move(0.07, 0.1)
    run(hand)
    assert hand.width == pytest.approx(0.07) and hand.outcome is Outcome.SUCCESS
    assert not hand.is_grasped  # opening released it


def test_stop_halts_in_place_and_aborts_the_action():
    hand = FrankaHand()
    action = hand.move(0.0, 0.02)
    hand.step(1.0)
    hand.stop()
    assert hand.take_finished() == [(action, Outcome.ABORTED)]
    for _ in range(100):
        hand.step(0.01)
    assert hand.width == pytest.approx(0.06) and not hand.busy


def test_stop_after_a_grasp_keeps_holding():
    hand = FrankaHand(object_width=0.04)
    hand.grasp(0.04, 0.1, 20.0)
    run(hand)
    hand.stop()
    assert hand.is_grasped and hand.width == pytest.approx(0.04)


def test_a_new_command_preempts_the_running_one():
    hand = FrankaHand()
    first = hand.move(0.0, 0.01)
    hand.step(0.1)
    second = hand.homing()
    assert hand.take_finished() == [(first, Outcome.ABORTED)]
    run(hand)
    assert hand.take_finished() == [(second, Outcome.SUCCESS)]


def test_object_wider_than_the_stroke_is_rejected():
    with pytest.raises(ValueError):
        FrankaHand(object_width=0.09)
