"""Shared by the Cartesian client-filter tests (tests/envs/test_cartesian_*.py,
test_client_kernel.py): the FR3
limits libfranka rate-limits to, pose builders, and libfranka's own outputs on fixed
inputs."""

from __future__ import annotations

import numpy as np

from franka_sim_gym.fci.tables import FR3
from franka_sim_gym.sim.rotations import rotation_exp

DT = 1e-3
#: kMaxTranslational* / kMaxRotational* (include/franka/rate_limiting.h): limit - 1e-3.
V, A, J = FR3.v_trans_max, FR3.a_trans_max, FR3.j_trans_max
V_ROT, A_ROT, J_ROT = FR3.v_rot_max, FR3.a_rot_max, FR3.j_rot_max
LIMITS = (V, A, J, V_ROT, A_ROT, J_ROT)
#: kFactorCartesianRotationPoseInterface: the pose overload scales the rotational limits.
POSE_FACTOR = 0.99
#: Differencing a float64 stream at 1 kHz twice costs ~1e-11 relative.
RTOL = 1e-8


def unit_vector(rng, size=3):
    """A random unit vector."""
    u = rng.normal(size=size)
    return u / np.linalg.norm(u)


def homogeneous(R=None, t=(0.0, 0.0, 0.0)):
    """The 4 x 4 transform of rotation R (identity when None) and translation t."""
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    T[:3, 3] = t
    return T


def random_pose(rng):
    """A random transform."""
    return homogeneous(rotation_exp(rng.normal(size=3)), rng.normal(size=3))


def rotation_about(axis, angle):
    """The rotation by ``angle`` about ``axis``."""
    return rotation_exp(np.asarray(axis, dtype=float) * angle)


def row_norms(x):
    """Euclidean norms along the last axis."""
    return np.linalg.norm(x, axis=-1)


def derivatives(x):
    """A stream (steps, ...) and its first and second backward differences over DT."""
    v = x
    a = np.diff(v, axis=0) / DT
    return v, a, np.diff(a, axis=0) / DT


def assert_rotation(R, atol=1e-12):
    """R is a proper rotation (orthonormal, det 1) within ``atol``."""
    R = np.asarray(R)
    np.testing.assert_allclose(
        R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape), atol=atol
    )
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=atol)


# Expected values: libfranka 0.21.2's src/rate_limiting.cpp and src/lowpass_filter.cpp built
# with Eigen 3.4.0 (g++ -O2) and called on the same inputs (wire arrays converted back).


def pose_from_rotvec(rotvec, t):
    """The transform of rotation vector ``rotvec`` and translation t."""
    return homogeneous(rotation_exp(np.array(rotvec, dtype=float)), t)


#: (T_c, T_last, twist, dtwist, expected): libfranka's limitRate on poses.
LIBFRANKA_POSE_LIMITER_CASES = [
    (
        pose_from_rotvec([0.3, -0.2, 0.1], [0.4, 0.1, 0.5]),
        pose_from_rotvec([0.31, -0.19, 0.12], [0.401, 0.099, 0.5005]),
        [0.5, -0.2, 0.1, 0.3, 0.2, -0.4],
        [3.0, 1.0, -2.0, 5.0, -4.0, 1.0],
        [[0.9751320474685167, -0.14574068037303958, -0.16696449947297792, 0.40149964093766416],
         [0.087539453573915, 0.9453929385007624, -0.3139570606004492, 0.09880367965119143],
         [0.2036033744018967, 0.2915336102704066, 0.9346410113058723, 0.5005966635267619],
         [0.0, 0.0, 0.0, 1.0]],
    ),
    (  # a 2.9 rad difference: the quaternion's largest-diagonal branch
        pose_from_rotvec([2.0, -1.0, 0.5], [0.0, 0.0, 0.0]),
        pose_from_rotvec([-2.0, 1.5, 0.1], [0.1, 0.0, 0.0]),
        [0.0] * 6,
        [0.0] * 6,
        [[0.3493156539013705, -0.8875968976556621, 0.30025043082650543, 0.099995500001],
         [-0.8398877155992565, -0.15453769058843903, 0.5202948465755299, 0.0],
         [-0.41541208350855696, -0.43392378300761075, -0.7994641651853092, 0.0],
         [0.0, 0.0, 0.0, 1.0]],
    ),
]  # fmt: skip


#: (T_c, T_ref, cutoff, expected): libfranka's cartesianLowpassFilter (also the C
#: kernel's test).
LIBFRANKA_LOWPASS_CASES = [
    (
        pose_from_rotvec([0.3, -0.2, 0.1], [1, 2, 3]),
        pose_from_rotvec([0.2, 0.1, -0.3], [0, 0, 1]),
        100.0,
        [[0.9892603520923969, 0.14233830515481044, -0.03322292376782669, 0.3858695450950375],
         [-0.1461552922368075, 0.9608073166901957, -0.23555876282948898, 0.771739090190075],
         [-0.0016082068275449397, 0.2378846507873976, 0.9712920809882873, 1.771739090190075],
         [0.0, 0.0, 0.0, 1.0]],
    ),
    (  # the quaternion sign flip
        pose_from_rotvec([0.0, 0.0, np.radians(-100.0)], [0, 0, 0]),
        pose_from_rotvec([0.0, 0.0, np.radians(100.0)], [0, 0, 0]),
        30.0,
        [[-0.5789399948819778, -0.8153701504997939, 0.0, 0.0],
         [0.8153701504997939, -0.5789399948819778, 0.0, 0.0],
         [0.0, 0.0, 1.0, 0.0],
         [0.0, 0.0, 0.0, 1.0]],
    ),
    (  # both near a half turn: negative traces
        pose_from_rotvec([2.9, 0.3, -0.2], [0.5, 0.5, 0.5]),
        pose_from_rotvec([-0.4, 2.8, 0.9], [0.4, 0.6, 0.5]),
        10.0,
        [[-0.8899231892450603, -0.45608685308377445, 0.004636775608154287, 0.40591173974417494],
         [-0.3631180334367878, 0.7145996777932448, 0.5979068441578426, 0.5940882602558251],
         [-0.27601088934478774, 0.5304074687840759, -0.8015521854634102, 0.5],
         [0.0, 0.0, 0.0, 1.0]],
    ),
]  # fmt: skip
