"""training/ensemble.py: the members' actions combined, as the mean or with the most
upward member's vertical velocity; bad input refused by name."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.training.ensemble import VERTICAL, Ensemble, member_seed
from tests.scripted_policies import Fixed

MEMBERS = [Fixed([0.3, -0.2, -0.6]), Fixed([0.1, 0.0, -0.1]), Fixed([0.2, 0.5, 0.1], np.float64)]
OBS = {"observation": np.zeros((2, 4), dtype=np.float32)}


def test_the_mean_of_the_members_actions():
    action, state = Ensemble(MEMBERS).predict(OBS)
    # in the first member's dtype, though the third acts in float64
    assert state is None and action.dtype == np.float32 and action.shape == (2, 3)
    np.testing.assert_allclose(action, [[0.2, 0.1, -0.2]] * 2, atol=1e-7)


def test_upward_takes_the_most_upward_member_s_vertical_velocity_and_the_mean_elsewhere():
    assert VERTICAL == 2  # a Cartesian velocity's z (docs/env.md, "Actions")
    action, _ = Ensemble(MEMBERS, combine="upward").predict(OBS)
    np.testing.assert_allclose(action, [[0.2, 0.1, 0.1]] * 2, atol=1e-7)


def test_one_observation_gets_one_combined_action():
    one = {"observation": np.zeros(4, dtype=np.float32)}
    action, _ = Ensemble(MEMBERS, combine="upward").predict(one)
    assert action.shape == (3,)
    np.testing.assert_allclose(action, [0.2, 0.1, 0.1], atol=1e-7)


def test_bad_ensembles_are_refused_by_name():
    with pytest.raises(ValueError, match="an ensemble needs at least one member"):
        Ensemble([])
    with pytest.raises(
        ValueError, match=r"unknown combine 'max': expected one of \('mean', 'upward'\)"
    ):
        Ensemble(MEMBERS, combine="max")
    with pytest.raises(ValueError, match="member index -1 is negative"):
        member_seed(0, -1)
