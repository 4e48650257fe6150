"""training/governor.py: a Cartesian velocity's motion toward the base capped as joint 4
nears its stop, everything else passed through; bad settings refused by name."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.fci.tables import FR3
from franka_sim_gym.training.governor import FLOOR, JOINT_4, SLOW_FROM, STOP_AT, ElbowGovernor
from tests.scripted_policies import Fixed


def observations(q4) -> dict:
    obs = np.zeros((len(q4), 20), dtype=np.float32)
    obs[:, JOINT_4] = q4
    return {"observation": obs}


def test_motion_toward_the_base_is_capped_as_joint_4_nears_its_stop():
    assert STOP_AT < SLOW_FROM and FR3.q_lower[JOINT_4] < STOP_AT  # the stop is beyond
    q4 = [-2.0, SLOW_FROM, (SLOW_FROM + STOP_AT) / 2, STOP_AT, -3.0]
    governor = ElbowGovernor(Fixed([-0.8, 0.3, -0.5]), floor=0.0)
    governed, _ = governor.predict(observations(q4))
    # the whole range until SLOW_FROM, half way half the range, none from STOP_AT on
    np.testing.assert_allclose(governed[:, 0], [-0.8, -0.8, -0.5, 0.0, 0.0], atol=1e-6)
    np.testing.assert_array_equal(governed[:, 1:], np.float32([[0.3, -0.5]] * 5))  # the rest
    assert governed.dtype == np.float32
    # away from the base: untouched however folded the elbow
    away, _ = ElbowGovernor(Fixed([0.6, 0.0, 0.0])).predict(observations([-3.0]))
    np.testing.assert_array_equal(away, np.float32([[0.6, 0.0, 0.0]]))
    # the default floor keeps some motion toward the base (0.2: 0.06 m/s), half way
    # between it and the whole range half way between the angles
    assert FLOOR == 0.2
    slow, _ = ElbowGovernor(Fixed([-0.8, 0, 0])).predict(observations(q4))
    np.testing.assert_allclose(slow[:, 0], [-0.8, -0.8, -0.6, -0.2, -0.2], atol=1e-6)


def test_one_observation_gets_one_governed_action():
    one = observations([-3.0])["observation"][0]
    action, _ = ElbowGovernor(Fixed([-0.8, 0.3, -0.5])).predict({"observation": one})
    assert action.shape == (3,)
    np.testing.assert_allclose(action, [-FLOOR, 0.3, -0.5], atol=1e-6)


def test_bad_governors_are_refused_by_name():
    with pytest.raises(ValueError, match=r"stop_at \(-2.5\) must be below slow_from \(-2.6\)"):
        ElbowGovernor(Fixed([0, 0, 0]), stop_at=-2.5)
    with pytest.raises(ValueError, match=r"floor must be in \[0, 1\] \(action units\), got 1.5"):
        ElbowGovernor(Fixed([0, 0, 0]), floor=1.5)
