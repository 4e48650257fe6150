"""What publishing a state copies (fci/_publish.c, StateWriter.copy_for_publish and
publish): the wire's float32 values are the float64 shadow as numpy casts it (round to
nearest; beyond float32's range an infinity; NaN kept), every robot's next message id,
the success rate where given; the desired and commanded pose and elbow are the measured
ones, and q_d is the measured q only between motions (docs/fci-behaviour.md "RobotState
fields")."""

from __future__ import annotations

import numpy as np
import pytest

from franka_sim_gym.fci.state import _PUBLISH, StateWriter
from franka_sim_gym.fci.wire import ROBOT_STATE_DTYPE, ROBOT_STATE_SIZE

FIELDS = ROBOT_STATE_DTYPE.fields
LAYOUT = (
    ROBOT_STATE_SIZE,
    8,
    FIELDS["message_id"][1],
    FIELDS["control_command_success_rate"][1],
)


def test_the_wire_is_the_shadow_as_numpy_casts_it_and_each_state_a_new_id():
    writer = StateWriter(3)
    rng = np.random.default_rng(7)
    shadow = writer.shadow
    shadow[...] = rng.normal(scale=10.0, size=shadow.shape)
    shadow[0, :5] = [np.nan, np.inf, -np.inf, 1e39, 1e-46]  # out of range, subnormal, ...
    shadow[1, 3] = 1.0 + 2.0**-24 + 2.0**-40  # just above a tie: rounds up
    rate = np.array([1.0, 0.5, 0.97])
    writer.publish(rate)
    raw = writer.states.view(np.uint8).reshape(3, ROBOT_STATE_SIZE)
    wire = raw[:, 8 : 8 + 4 * shadow.shape[1]].copy().view("<f4")
    with np.errstate(over="ignore"):  # numpy warns where it casts 1e39 (the C text does not)
        expected = shadow.astype("<f4")
    assert wire.tobytes() == expected.tobytes()
    assert writer.states["message_id"].tolist() == [1, 1, 1] == writer.message_id.tolist()
    np.testing.assert_array_equal(
        writer.states["control_command_success_rate"], rate.astype(np.float32)
    )
    writer.publish(None)  # no rate: the last one stays
    assert writer.states["message_id"].tolist() == [2, 2, 2]
    np.testing.assert_array_equal(
        writer.states["control_command_success_rate"], rate.astype(np.float32)
    )
    # the named fields read what was cast
    assert writer.states["q"][2].tobytes() == writer.q[2].astype("<f4").tobytes()


def test_a_shadow_of_any_width_is_cast_whole_and_nothing_beyond_it():
    w = StateWriter(2)
    w.shadow[...] = np.arange(w.shadow.size, dtype=float).reshape(w.shadow.shape) + 0.25
    width = 317  # not a multiple of the cast's blocks of 8
    plan = _PUBLISH.Publishing(
        w.O_T_EE, w.O_T_EE_d, w.O_T_EE_c, w.elbow, w.elbow_d, w.elbow_c, w.q_d,
        w.shadow[:, :width], w.states, w.message_id, LAYOUT,
    )  # fmt: skip
    plan.publish(None)
    wire = w.states.view(np.uint8).reshape(2, ROBOT_STATE_SIZE)[:, 8 : 8 + 4 * 320]
    floats = wire.copy().view("<f4")
    np.testing.assert_array_equal(floats[:, :width], w.shadow[:, :width].astype("<f4"))
    np.testing.assert_array_equal(floats[:, width:], 0.0)  # beyond it: untouched


def test_the_desired_pose_and_elbow_are_the_measured_ones_and_q_d_only_between_motions():
    writer = StateWriter(2)
    rng = np.random.default_rng(3)
    writer.O_T_EE[...] = rng.normal(size=(2, 16))
    writer.elbow[...] = [[0.3, -1.0], [-0.2, 1.0]]
    writer.q_d[...] = 5.0  # a motion's reference
    q = rng.normal(size=(2, 7))
    writer.copy_for_publish(q, np.array([True, False]))
    for field in (writer.O_T_EE_d, writer.O_T_EE_c):
        np.testing.assert_array_equal(field, writer.O_T_EE)
    for field in (writer.elbow_d, writer.elbow_c):
        np.testing.assert_array_equal(field, writer.elbow)
    np.testing.assert_array_equal(writer.q_d[0], 5.0)  # in motion: its reference kept
    np.testing.assert_array_equal(writer.q_d[1], q[1])  # between motions: the measured q


def test_bad_arrays_are_refused_by_name():
    w = StateWriter(2)
    head = (w.O_T_EE, w.O_T_EE_d, w.O_T_EE_c, w.elbow, w.elbow_d, w.elbow_c, w.q_d)
    ok = (*head, w.shadow, w.states, w.message_id, LAYOUT)
    cases = [
        ((*head[:6], np.zeros((2, 6)), *ok[7:]), ValueError, "q_d"),
        ((*head, w.shadow[:, ::2], *ok[8:]), ValueError, "shadow"),
        ((*head, w.shadow, w.states[:1], *ok[9:]), ValueError, "states: 1377 bytes"),
        ((*ok[:9], w.message_id.astype(np.int32), LAYOUT), ValueError, "message_id"),
        ((*ok[:10], (ROBOT_STATE_SIZE, 100, 0, 1373)), ValueError, "do not fit"),
        ((*ok[:10], LAYOUT[:3]), TypeError, "layout"),
    ]
    for args, error, text in cases:
        with pytest.raises(error, match=text):
            _PUBLISH.Publishing(*args)
    plan = _PUBLISH.Publishing(*ok)
    with pytest.raises(ValueError, match="keeps_q_d"):
        plan.copies(np.zeros((2, 7)), np.zeros(3, bool))
    before = w.q_d.copy()
    with pytest.raises(ValueError, match="q: axis 1 has length 6, expected 7"):
        plan.copies(np.zeros((2, 6)), np.zeros(2, bool))
    assert np.array_equal(w.q_d, before)  # nothing copied
    with pytest.raises(ValueError, match="success_rate"):
        plan.publish(np.zeros(3))
    assert w.states["message_id"].tolist() == [0, 0]  # nothing was published


def test_the_measured_pose_is_the_flanges_and_the_elbow_joint_3_and_the_sign_of_joint_4():
    writer = StateWriter(3)
    rng = np.random.default_rng(11)
    position = rng.normal(size=(3, 3))
    rotation = rng.normal(size=(3, 3, 3))
    q = rng.normal(size=(3, 7))
    q[:, 3] = [0.0, -0.0, -2.1]  # sign(0) is +1, a negative zero's -1 (copysign)
    writer._publishing.pose(position, rotation, q)
    pose = writer.O_T_EE.reshape(3, 4, 4)  # the column-major wire read row-major: R^T
    np.testing.assert_array_equal(pose[:, 3, :3], position)
    np.testing.assert_array_equal(pose[:, :3, :3], rotation)
    np.testing.assert_array_equal(pose[:, 3, 3], 1.0)  # the constant entry untouched
    np.testing.assert_array_equal(writer.elbow[:, 0], q[:, 2])
    assert writer.elbow[:, 1].tolist() == [1.0, -1.0, -1.0]
    with pytest.raises(ValueError, match="rotation"):
        writer._publishing.pose(position, rotation[:, :2], q)
