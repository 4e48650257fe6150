"""sim/_truth.c, the one text of the drives' friction law (sim/friction.py JointFriction)
and of the extra joint forces of a step (sim/truth.py ArmTruth.before_step): Gaz et al.'s
law as the paper writes it, each robot and joint at its own scale, and the drives' friction
minus the links' weight differences in every robot's own MjData."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.sim.arm import ArmPhysics
from franka_sim_gym.sim.friction import GAZ_A, GAZ_ALPHA, GAZ_PHI, RULES, JointFriction
from tests.fci.test_reality import gaz  # Gaz et al.'s law as the paper writes it


def test_the_friction_law_is_gaz_et_al_s_at_each_robots_own_scale():
    rng = np.random.default_rng(0)
    friction = JointFriction(3)
    scale = np.stack([np.ones(7), -np.ones(7), rng.uniform(0.5, 2.0, 7)])
    friction.set_scale(np.arange(3), scale)
    for _ in range(20):
        dq = rng.normal(0, 1.0, (3, 7))
        np.testing.assert_allclose(friction.torque(dq), scale * gaz(dq), rtol=0, atol=1e-14)
    assert not friction.torque(np.zeros((3, 7))).any()  # zero at rest
    far = friction.torque(np.full((3, 7), 50.0))[0]  # saturated: A less its value at dq = 0
    np.testing.assert_allclose(far, GAZ_A - GAZ_A / (1 + np.exp(-GAZ_ALPHA * GAZ_PHI)), atol=1e-12)


def test_a_step_applies_the_drives_friction_minus_the_links_weight_differences():
    physics = ArmPhysics(n_arms=2)
    truth = physics.enable_truth()
    truth.friction.set_scale([0, 1], np.array([[-1.0] * 7, [-0.5] * 7]))
    truth.weights.set([1], np.full((1, 7), 1.1), np.zeros((1, 7, 3)))
    physics.datas[0].qvel[:7] = 0.3
    physics.datas[1].qvel[:7] = -0.2
    physics.forward([0, 1])
    truth.before_step()
    for i, (scale, dq) in enumerate(((-1.0, 0.3), (-0.5, -0.2))):
        expected = scale * gaz(np.full(7, dq)) - truth.weights.torque()[i]
        np.testing.assert_allclose(physics.datas[i].qfrc_applied[:7], expected, atol=1e-14)
    assert not truth.weights.torque()[0].any() and truth.weights.torque()[1].any()


def test_the_c_text_names_a_bad_argument():
    seven = np.zeros((2, 7))
    with pytest.raises(ValueError, match="^gain: axis 0 has length 1, expected 2"):
        RULES.friction(seven, seven[:1], seven, seven, seven)
    with pytest.raises(ValueError, match="^xmat: axis 2 has length 3, expected 9"):
        RULES.link_weights(np.zeros((2, 7, 3)), *[np.zeros((2, 7, 3))] * 5, seven)
    with pytest.raises(TypeError, match=r"Forces\(\) takes 11 arguments \(7 given\)"):
        RULES.Forces(*[seven] * 7)
    # xmat, dmc, dm, tail, origins, axes
    weights = [np.zeros((2, 7, k)) for k in (9, 3, 1, 1, 3, 3)]
    with pytest.raises(ValueError, match=r"^targets\[1\]: expected 7 float64 values"):
        RULES.Forces(*[seven] * 4, *weights, (np.zeros(7), np.zeros(6)))
    with pytest.raises(ValueError, match="^out: axis 1 has length 6, expected 7"):
        RULES.Friction(*[seven] * 4, np.zeros((2, 6)))
