"""A payload on the flange and the weight compensation of a configured load (sim side)."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.sim.arm import ArmPhysics
from franka_sim_gym.sim.dynamics import ArmDynamics, weight_torque

#: 1 kg, 5 cm out along the flange's z axis (the F_x_Cload of SetLoad).
MASS, COM = 1.0, np.array([0.0, 0.0, 0.05])


def float_for_a_second(physics: ArmPhysics, configured: bool) -> float:
    """Zero commanded torque for 1 s (gravity compensated by the drives, plus the
    configured load's weight when ``configured``); how far the flange rose [m]."""
    dyn = ArmDynamics(physics)
    start = physics.flange_pose()[0][0, 2]
    zero = np.zeros((1, 7))
    for _ in range(1000):
        compensation = None
        if configured:
            p, R = physics.flange_pose()
            J = dyn.jacobian(p + np.einsum("nij,j->ni", R, COM))
            compensation = weight_torque(J, np.array([MASS]), physics.model.opt.gravity)
        physics.step(physics.q, None, zero, True, compensation=compensation)
    return physics.flange_pose()[0][0, 2] - start


def test_a_payload_the_robot_is_told_of_floats():
    physics = ArmPhysics(1, payload=(MASS, *COM))
    assert abs(float_for_a_second(physics, configured=True)) < 2e-3


def test_a_payload_nobody_configured_sinks():
    physics = ArmPhysics(1, payload=(MASS, *COM))
    assert float_for_a_second(physics, configured=False) < -5e-3


def test_a_configured_load_that_is_absent_lifts_the_arm():
    physics = ArmPhysics(1)
    assert float_for_a_second(physics, configured=True) > 5e-3


def test_without_a_load_the_arm_floats():
    physics = ArmPhysics(1)
    assert abs(float_for_a_second(physics, configured=False)) < 2e-3


@pytest.mark.parametrize("payload", [(0.0, 0, 0, 0), (-1.0, 0, 0, 0), (1.0, np.nan, 0, 0)])
def test_a_payload_needs_a_positive_mass_and_a_finite_centre(payload):
    with pytest.raises(ValueError, match="payload"):
        ArmPhysics(1, payload=payload)


def test_the_joint_servo_does_not_hold_up_a_payload_nobody_configured():
    """The servo's Coriolis term is C dq only: the unconfigured payload's weight sags the
    held arm by K^-1 times its torque (2 kg: a millimetre or two), as on the robot."""
    physics = ArmPhysics(1, payload=(2.0, 0.0, 0.0, 0.05))
    q = physics.q.copy()
    z0 = physics.flange_pose()[0][0, 2]
    for _ in range(1000):
        physics.step(q, None)
    assert z0 - physics.flange_pose()[0][0, 2] > 5e-4
    assert np.abs(physics.payload_weight).max() > 5.0  # its weight torque, Nm
