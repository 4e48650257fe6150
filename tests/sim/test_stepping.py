"""A cycle's physics of every arm, one C call (sim/_stepping.c, ArmPhysics.step).

What the plan must do: each arm's world stepped as MuJoCo's own mj_step2 then mj_step1
step it (the same library, so the same bits as the bindings' calls), a shared model's
finger limit set to each arm's own before its world steps, a MuJoCo error raised as
an exception naming the arm (the bindings raise mujoco.FatalError) with MuJoCo's error
hook given back, and bad arguments refused by name.
"""

from __future__ import annotations

import ctypes

import mujoco
import numpy as np
import pytest

from franka_sim_gym.sim.arm import STEPPING, ArmPhysics
from franka_sim_gym.sim.libmujoco import function_address, library

FUNCTIONS = (
    function_address("mj_step2"),
    function_address("mj_step1"),
    function_address("mju_setLogHandler"),
)


def _log_handler() -> int | None:
    """The address of MuJoCo's installed log handler (read by swapping it out and back)."""
    swap = library().mju_setLogHandler
    swap.restype, swap.argtypes = ctypes.c_void_p, [ctypes.c_void_p]
    current = swap(None)
    swap(current)
    return current


def _squeezing(n: int = 3) -> ArmPhysics:
    """n arms with hands, fingers commanded shut from open (their servo saturates)."""
    physics = ArmPhysics(n_arms=n, hand=True)
    physics.set_finger_width(np.arange(n), np.zeros(n))
    return physics


def _finger_force(physics: ArmPhysics) -> np.ndarray:
    """(n,) the fingers' actuator force of every arm's world after its last step."""
    act = physics._finger_act
    return np.array([d.actuator_force[act] for d in physics.datas])


def test_each_arm_squeezes_at_its_own_finger_limit_on_one_shared_model():
    alone = _squeezing(1)
    default = float(alone.finger_force[0])  # the limit the shared model starts with
    alone.step(alone.q.copy(), None)
    physics = _squeezing()
    physics.set_finger_force([0, 1, 2], [10.0, default, 15.0])
    hook = _log_handler()
    physics.step(physics.q.copy(), None)
    # The shared model's range is set to each arm's limit before its world steps: the
    # servo, saturated in its first cycle (open to shut asks ~40 N), pushes with exactly
    # that limit, arm by arm; arm 1, back at the model's first limit after arm 0's, as a
    # lone arm does.
    force = _finger_force(physics)
    np.testing.assert_array_equal(force[[0, 2]], [-10.0, -15.0])
    assert force[1] == _finger_force(alone)[0] < -15.0
    # ... and holds the last arm's when the cycle ends (what forward compares against).
    assert physics.model.actuator_forcerange[physics._finger_act, 1] == 15.0
    # MuJoCo's log handler is as the cycle found it
    assert _log_handler() == hook


def test_the_steps_give_the_bindings_bits():
    physics, twin = _squeezing(), _squeezing()
    for p in (physics, twin):
        p.set_finger_force([0, 1, 2], [20.0, 70.0, 20.0])
    q = physics.q + 0.05
    act = twin._finger_act
    for _ in range(20):
        physics.step(q, None)
        # the same cycle through the bindings, arm by arm
        for a, b in zip(physics.datas, twin.datas, strict=True):
            b.ctrl[:] = a.ctrl  # the servo's torque of this cycle
        for force, data in zip(twin.finger_force.tolist(), twin.datas, strict=True):
            twin.model.actuator_forcerange[act] = (-force, force)
            mujoco.mj_step2(twin.model, data)
            mujoco.mj_step1(twin.model, data)
        for a, b in zip(physics.datas, twin.datas, strict=True):
            for field in ("qpos", "qvel", "qfrc_bias", "xpos", "qfrc_actuator"):  # mj_step1's last
                assert getattr(a, field).tobytes() == getattr(b, field).tobytes(), field


def _chain(memory: str = "") -> mujoco.MjModel:
    """A 60-link chain; with a small ``memory`` its step overflows MuJoCo's stack."""
    links = "".join(
        f"<body pos='0 0 {0.1 * i}'><joint type='hinge'/><geom size='.05'/>" for i in range(60)
    )
    size = f"<size memory='{memory}'/>" if memory else ""
    return mujoco.MjModel.from_xml_string(
        f"<mujoco>{size}<worldbody>{links}{'</body>' * 60}</worldbody></mujoco>"
    )


def test_a_mujoco_error_in_a_step_is_an_exception_naming_the_arm():
    good, bad = _chain(), _chain("8K")
    datas = (mujoco.MjData(good), mujoco.MjData(bad))
    steps = STEPPING.Steps(FUNCTIONS, (good, bad), datas, None, -1, None)
    hook = _log_handler()
    with pytest.raises(RuntimeError, match=r"MuJoCo error in arm 1's step: mj_stackAlloc"):
        steps.run(None)
    assert datas[0].time == good.opt.timestep  # the arm before it stepped
    # MuJoCo's log handler is given back (a later error elsewhere must not jump here)
    assert _log_handler() == hook
    with pytest.raises(mujoco.FatalError):
        mujoco.mj_step1(bad, datas[1])


def test_bad_arguments_are_refused_by_name():
    model = _chain()
    data = mujoco.MjData(model)
    forcerange, applied = np.zeros((2, 2)), np.zeros(1)
    cases = [
        ((FUNCTIONS[:2], (model,), (data,), None, -1, None), TypeError, "functions"),
        ((FUNCTIONS, [model], (data,), None, -1, None), TypeError, "tuples"),
        ((FUNCTIONS, (model, model), (data,), None, -1, None), ValueError, "models: 2"),
        ((FUNCTIONS, (model,), (model,), None, -1, None), TypeError, r"datas\[0\]"),
        ((FUNCTIONS, ("x",), (data,), None, -1, None), TypeError, r"models\[0\]"),
        ((FUNCTIONS, (model,), (data,), forcerange, 2, applied), ValueError, "act: 2"),
        ((FUNCTIONS, (model,), (data,), np.zeros((2, 3)), 0, applied), ValueError, "forcerange"),
        ((FUNCTIONS, (model,), (data,), forcerange, 0, np.zeros(2)), ValueError, "applied"),
        (((0, 0, 0), (model,), (data,), None, -1, None), ValueError, "non-null"),
    ]
    for args, error, text in cases:
        with pytest.raises(error, match=text):
            STEPPING.Steps(*args)
    steps = STEPPING.Steps(FUNCTIONS, (model,), (data,), forcerange, 0, applied)
    with pytest.raises(ValueError, match="finger_force"):
        steps.run(np.zeros(3))


@pytest.mark.parametrize("at_rest", [False, True])
@pytest.mark.parametrize("compensated", [False, True])
def test_the_joint_servo_writes_its_law_into_every_arms_ctrl_rows(at_rest, compensated):
    physics = ArmPhysics(n_arms=2)
    rng = np.random.default_rng(5)
    for _ in range(3):  # moving, so that dq and the Coriolis terms are not zero
        physics.step(physics.q + 0.01, None)
    q, dq, coriolis = physics.q.copy(), physics.dq.copy(), physics.coriolis.copy()
    q_ref = q + rng.normal(scale=0.01, size=q.shape)
    dq_ref = None if at_rest else rng.normal(scale=0.1, size=q.shape)
    kp, kd = rng.uniform(100, 3000, q.shape), rng.uniform(1, 50, q.shape)
    extra = rng.normal(size=q.shape) if compensated else None
    physics.step(q_ref, dq_ref, compensation=extra, gains=(kp, kd))
    tau = (q_ref - q) * kp
    tau = tau - kd * dq if at_rest else tau + (dq_ref - dq) * kd
    tau = tau + coriolis
    if compensated:
        tau = tau + extra
    for i, data in enumerate(physics.datas):
        assert data.ctrl[physics.layout.actuator_ids[i]].tobytes() == tau[i].tobytes()


def test_the_servo_needs_its_arrays_and_refuses_bad_ones_by_name():
    model = _chain()
    data = mujoco.MjData(model)
    steps = STEPPING.Steps(FUNCTIONS, (model,), (data,), None, -1, None)
    seven = np.zeros((1, 7))
    with pytest.raises(RuntimeError, match="servo first"):
        steps.servo_run(None, seven, None, seven, seven, None)
    with pytest.raises(TypeError, match="ctrl: expected a tuple of 1"):
        steps.servo(seven, seven, seven, (np.zeros(7), np.zeros(7)))
    with pytest.raises(ValueError, match=r"ctrl\[0\]: expected 7"):
        steps.servo(seven, seven, seven, (np.zeros(6),))
    with pytest.raises(ValueError, match="coriolis"):
        steps.servo(seven, seven, np.zeros((1, 6)), (np.zeros(7),))
    ctrl = np.zeros(7)
    steps.servo(seven, seven, seven, (ctrl,))
    with pytest.raises(ValueError, match="kd"):
        steps.servo_run(None, seven, None, seven, np.zeros((2, 7)), None)
    with pytest.raises(ValueError, match="compensation"):
        steps.servo_run(None, seven, None, seven, seven, np.zeros(7))
    assert data.time == 0.0  # nothing stepped


def test_an_arm_under_external_torque_gets_it_and_the_others_the_joint_servo():
    physics = ArmPhysics(n_arms=2)
    physics.step(physics.q + 0.01, None)
    q, dq, coriolis = physics.q.copy(), physics.dq.copy(), physics.coriolis.copy()
    q_ref, extra = q + 0.002, np.full((2, 7), 0.25)
    tau_external = np.arange(14.0).reshape(2, 7)
    physics.step(q_ref, None, tau_external, np.array([True, False]), compensation=extra)
    ctrl = [d.ctrl[physics.layout.actuator_ids[i]] for i, d in enumerate(physics.datas)]
    # arm 0: the commanded torque (gravity is the actuators'), plus the compensation
    assert ctrl[0].tobytes() == (tau_external[0] + extra[0]).tobytes()
    joint = (q_ref - q) * physics.kp - physics.kd * dq + coriolis + extra
    assert ctrl[1].tobytes() == joint[1].tobytes()


def test_the_cartesian_servos_arms_get_its_torque_with_coriolis_and_compensation():
    """Three arms in one step: arm 0 under the Cartesian impedance servo (its torque plus
    the joint servo's Coriolis and the compensation), arm 1 under an external torque
    (the client's plus the compensation: no Coriolis), arm 2 under the joint servo; an
    arm in both masks is the external torque's."""
    from franka_sim_gym.sim.cartesian_servo import CartesianTarget

    physics = ArmPhysics(n_arms=3)
    for _ in range(3):  # moving: Coriolis is not zero
        physics.step(physics.q + 0.01, None)
    q, dq, coriolis = physics.q.copy(), physics.dq.copy(), physics.coriolis.copy()
    p, R = physics.flange_pose()
    target = CartesianTarget(
        np.array([True, True, False]), p + [0.0, 0.0, 0.01], R, np.tile(np.eye(4), (3, 1, 1)),
        np.tile([2000.0, 2000.0, 2000.0, 100.0, 100.0, 100.0], (3, 1)),
    )  # fmt: skip
    q_ref, extra = q + 0.002, np.full((3, 7), 0.25)
    servo_tau = physics._cartesian_servo(target, q_ref)  # what the step computes from here
    assert np.abs(coriolis[0]).max() > 1e-6 and np.abs(servo_tau[0]).max() > 0.1
    tau_external = np.arange(21.0).reshape(3, 7)
    under = np.array([False, True, False])
    physics.step(q_ref, None, tau_external, under, cartesian=target, compensation=extra)
    ctrl = [d.ctrl[physics.layout.actuator_ids[i]] for i, d in enumerate(physics.datas)]
    assert ctrl[0].tobytes() == (servo_tau[0] + coriolis[0] + extra[0]).tobytes()
    assert ctrl[1].tobytes() == (tau_external[1] + extra[1]).tobytes()
    joint = (q_ref - q) * physics.kp - physics.kd * dq + coriolis + extra
    assert ctrl[2].tobytes() == joint[2].tobytes()


def test_own_refuses_a_torque_without_its_arms_by_name():
    physics = ArmPhysics(n_arms=2)
    steps = physics._planned_steps()
    seven = np.zeros((2, 7))
    with pytest.raises(ValueError, match="a torque and its arms come together"):
        steps.own(seven, None, None, None, None)
    with pytest.raises(ValueError, match="external_arms"):
        steps.own(None, None, seven, np.zeros(3, bool), None)
    with pytest.raises(ValueError, match="servo_tau"):
        steps.own(np.zeros((2, 6)), np.ones(2, bool), None, None, None)


def test_a_forward_of_one_arms_world_sets_the_shared_finger_limit_to_that_arms():
    physics = _squeezing(2)
    physics.set_finger_force([0, 1], [12.0, 33.0])
    act = physics._finger_act
    physics.forward([1])
    np.testing.assert_array_equal(physics.model.actuator_forcerange[act], [-33.0, 33.0])
    physics.forward([0])
    np.testing.assert_array_equal(physics.model.actuator_forcerange[act], [-12.0, 12.0])
    with pytest.raises(ValueError, match="arm 2 is not one of the 2"):
        physics._planned_steps().limit(2, physics.finger_force)
