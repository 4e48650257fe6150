"""The FR3 model: kinematics, dynamics, served URDF, collision set, world layout.

Reference numbers are docs/fr3-model.md §6 (libfranka's own model of the served
URDF) and docs/limits.md §4.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import mujoco
import numpy as np
import pytest

from franka_sim_gym.sim.world import (
    FR3_XML,
    HOME_Q,
    SELF_COLLISION_DISTANCE,
    URDF_PATH,
    build_world,
    report_band_params,
)

# docs/fr3-model.md §6
FLANGE_HOME_POS = np.array([0.306891, 0.0, 0.590282])
FLANGE_HOME_ROT = np.array(
    [[0.707107, -0.707107, 0.0], [-0.707107, -0.707107, 0.0], [0.0, 0.0, -1.0]]
)
FLANGE_ZERO_POS = np.array([0.088, 0.0, 0.926])
FLANGE_ZERO_ROT = np.diag([1.0, -1.0, -1.0])
GRAVITY_HOME = np.array([0.0, -1.7090, -0.6395, 18.9582, 0.7919, 1.5879, 0.0])
GRAVITY_ZERO = np.array([0.0, -3.5239, 0.0, -3.4425, 0.0, 1.6336, 0.0])
MASS_HOME = np.array(
    [
        [0.4985, -0.0115, 0.4333, -0.0103, 0.0270, -0.0023, 0.0004],
        [-0.0115, 1.5254, -0.0128, -0.6426, -0.0024, -0.0425, -0.0023],
        [0.4333, -0.0128, 0.9233, -0.0187, 0.0153, -0.0030, 0.0008],
        [-0.0103, -0.6426, -0.0187, 0.8340, 0.0157, 0.0873, 0.0007],
        [0.0270, -0.0024, 0.0153, 0.0157, 0.0275, 0.0020, -0.0001],
        [-0.0023, -0.0425, -0.0030, 0.0873, 0.0020, 0.0305, 0.0002],
        [0.0004, -0.0023, 0.0008, 0.0007, -0.0001, 0.0002, 0.0001],
    ]
)
# docs/limits.md §4: (v_max, v_off, a_dec, q_min, q_max, effort) per joint
URDF_JOINT_PARAMS = [
    (2.62, 0.30, 6.0, -2.7501, 2.7501, 87),
    (2.62, 0.20, 2.585, -1.7918, 1.7918, 87),
    (2.62, 0.20, 3.50, -2.9065, 2.9065, 87),
    (2.62, 0.30, 4.00, -3.0481, -0.1458, 87),
    (5.26, 0.35, 17.0, -2.8101, 2.8101, 12),
    (4.18, 0.35, 5.5, 0.54092, 4.5205, 12),
    (5.26, 0.35, 17.0, -3.0196, 3.0196, 12),
]


def _forward(model: mujoco.MjModel, q: np.ndarray, arm: int = 0, layout=None) -> mujoco.MjData:
    data = mujoco.MjData(model)
    if layout is None:
        data.qpos[:7] = q
    else:
        mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
        data.qpos[layout.qpos_adr[arm]] = q
    mujoco.mj_forward(model, data)
    return data


def _full_mass(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    mass = np.zeros((model.nv, model.nv))
    try:
        mujoco.mj_fullM(model, data, mass)  # MuJoCo >= 3.10
    except TypeError:
        mujoco.mj_fullM(model, mass, data.qM)
    return mass


@pytest.fixture(scope="module")
def arm_model() -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_path(str(FR3_XML))


@pytest.fixture(scope="module")
def urdf() -> ET.Element:
    return ET.parse(URDF_PATH).getroot()


# --- kinematics -------------------------------------------------------------


@pytest.mark.parametrize("arm", [0, 2])
def test_flange_pose_at_home_matches_libfranka(arm):
    model, layout = build_world(n_arms=3)
    data = _forward(model, HOME_Q, arm, layout)
    site = layout.flange_site[arm]
    pos = data.site_xpos[site] - layout.base_pos[arm]
    np.testing.assert_allclose(pos, FLANGE_HOME_POS, atol=1e-4)
    np.testing.assert_allclose(data.site_xmat[site].reshape(3, 3), FLANGE_HOME_ROT, atol=1e-5)


def test_flange_pose_at_zero_matches_libfranka(arm_model):
    data = _forward(arm_model, np.zeros(7))
    site = arm_model.site("flange").id
    np.testing.assert_allclose(data.site_xpos[site], FLANGE_ZERO_POS, atol=1e-4)
    np.testing.assert_allclose(data.site_xmat[site].reshape(3, 3), FLANGE_ZERO_ROT, atol=1e-5)


def test_arm_bases_sit_at_spacing_along_x():
    model, layout = build_world(n_arms=3, spacing=1.5)
    data = _forward(model, HOME_Q, 0, layout)
    expected = np.array([[1.5 * i, 0.0, 0.0] for i in range(3)])
    np.testing.assert_allclose(layout.base_pos, expected)
    np.testing.assert_allclose(data.xpos[layout.link_body[:, 0]], expected)


# --- dynamics ---------------------------------------------------------------


@pytest.mark.parametrize(
    ("q", "expected"), [(HOME_Q, GRAVITY_HOME), (np.zeros(7), GRAVITY_ZERO)], ids=["home", "zero"]
)
def test_gravity_torques_match_libfranka(arm_model, q, expected):
    data = _forward(arm_model, q)
    tol = np.maximum(0.02 * np.abs(expected), np.where(np.abs(expected) < 0.05, 0.02, 0.0))
    assert np.all(np.abs(data.qfrc_gravcomp - expected) <= tol), data.qfrc_gravcomp


def test_gravity_compensation_is_delivered_through_the_actuators(arm_model):
    data = _forward(arm_model, HOME_Q)  # ctrl = 0
    np.testing.assert_allclose(data.qfrc_actuator, data.qfrc_gravcomp, atol=1e-12)
    np.testing.assert_allclose(data.qfrc_actuator, data.qfrc_bias, atol=1e-9)  # at rest
    assert np.abs(data.qfrc_passive).max() < 1e-12


def test_mass_matrix_at_home_matches_libfranka_plus_armature(arm_model):
    data = _forward(arm_model, HOME_Q)
    mass = _full_mass(arm_model, data) - np.diag(arm_model.dof_armature)
    # 2 % on the diagonal, but never tighter than the table's last printed
    # digit (M77 = 0.000119 is printed as 0.0001).
    diag_ref = np.diag(MASS_HOME)
    assert np.all(np.abs(np.diag(mass) - diag_ref) <= np.maximum(0.02 * diag_ref, 5e-5))
    off = ~np.eye(7, dtype=bool)
    assert np.abs(mass - MASS_HOME)[off].max() <= 0.01
    np.testing.assert_allclose(arm_model.dof_armature, [0.195] * 4 + [0.074] * 3)


def test_link_masses_are_the_served_urdf_inertials(arm_model, urdf):
    masses = {
        link.get("name"): float(link.find("inertial/mass").get("value"))
        for link in urdf.iter("link")
        if link.find("inertial") is not None
    }
    for k in range(8):
        assert arm_model.body(f"link{k}").mass[0] == pytest.approx(masses[f"link{k}"], abs=1e-10)
    moving = sum(arm_model.body(f"link{k}").mass[0] for k in range(1, 8))
    assert moving == pytest.approx(15.4948, abs=1e-4)


def test_idle_arm_holds_still_with_zero_torque():
    """Calm idle: gravity compensation alone holds HOME_Q (Menagerie's fr3 chatters)."""
    model, layout = build_world(n_arms=1)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    peak = 0.0
    for _ in range(2000):  # 2 s
        mujoco.mj_step(model, data)
        peak = max(peak, np.abs(data.qvel[layout.dof_adr[0]]).max())
    assert peak < 1e-3
    assert np.abs(data.qpos[layout.qpos_adr[0]] - HOME_Q).max() < 1e-3


# --- served URDF ------------------------------------------------------------


def test_urdf_names_the_robot_fr3_without_hand_or_meshes(urdf):
    assert urdf.tag == "robot" and urdf.get("name") == "fr3"
    links = [link.get("name") for link in urdf.iter("link")]
    assert {"base", *(f"link{k}" for k in range(9))} <= set(links)
    assert "link8" in links
    assert not list(urdf.iter("mesh"))
    assert not any("finger" in name or "hand" in name for name in links)


def test_urdf_revolute_joints_carry_the_limits_libfranka_reads(urdf):
    revolute = [j for j in urdf.findall("joint") if j.get("type") == "revolute"]
    assert [j.get("name") for j in revolute] == [f"joint{k}" for k in range(1, 8)]
    for joint, (v_max, v_off, a_dec, q_min, q_max, effort) in zip(
        revolute, URDF_JOINT_PARAMS, strict=True
    ):
        limit = joint.find("limit")
        assert float(limit.get("velocity")) == v_max
        assert float(limit.get("lower")) == q_min
        assert float(limit.get("upper")) == q_max
        assert float(limit.get("effort")) == effort
        pbvl = joint.find("position_based_velocity_limits")
        assert float(pbvl.get("velocity_offset")) == v_off
        assert float(pbvl.get("deceleration_limit")) == a_dec
        assert joint.find("safety_controller") is not None
        assert joint.find("dynamics") is not None


def test_urdf_has_no_other_joint_libfranka_would_take_for_joint_k(urdf):
    # libfranka takes any direct <joint> child whose name contains joint<k>.
    for joint in urdf.findall("joint"):
        name = joint.get("name")
        if name in {f"joint{k}" for k in range(1, 8)}:
            continue
        assert not any(f"joint{k}" in name for k in range(1, 8)), name
    movable = [j for j in urdf.findall("joint") if j.get("type") != "fixed"]
    assert len(movable) == 7


def _rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    cr, sr, cp, sp, cy, sy = (f(a) for a in (roll, pitch, yaw) for f in (math.cos, math.sin))
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _urdf_fk(urdf: ET.Element, q: np.ndarray, tip: str = "link8") -> np.ndarray:
    """T_base->tip from the URDF's own origins: Trans(xyz) Rz Ry Rx Rot_z(q)."""
    by_child = {j.find("child").get("link"): j for j in urdf.findall("joint")}
    chain = []
    link = tip
    while link in by_child:
        chain.append(by_child[link])
        link = by_child[link].find("parent").get("link")
    pose = np.eye(4)
    for joint in reversed(chain):
        origin = joint.find("origin")
        step = np.eye(4)
        step[:3, :3] = _rpy_matrix(*map(float, origin.get("rpy").split()))
        step[:3, 3] = list(map(float, origin.get("xyz").split()))
        if joint.get("type") == "revolute":
            k = int(joint.get("name")[-1]) - 1
            step[:3, :3] = step[:3, :3] @ _rpy_matrix(0.0, 0.0, q[k])
        pose = pose @ step
    return pose


def test_urdf_kinematics_equal_the_mjcf_flange(arm_model, urdf):
    rng = np.random.default_rng(7)
    lo, hi = arm_model.jnt_range[:, 0], arm_model.jnt_range[:, 1]
    site = arm_model.site("flange").id
    for q in [HOME_Q, *rng.uniform(lo, hi, size=(5, 7))]:
        data = _forward(arm_model, q)
        pose = _urdf_fk(urdf, q)
        np.testing.assert_allclose(data.site_xpos[site], pose[:3, 3], rtol=0, atol=1e-9)
        np.testing.assert_allclose(data.site_xmat[site].reshape(3, 3), pose[:3, :3], atol=1e-9)


def test_mjcf_joint_ranges_equal_the_urdf_limits(arm_model, urdf):
    for k in range(1, 8):
        joint = urdf.find(f"joint[@name='joint{k}']")
        limit = joint.find("limit")
        expected = [float(limit.get("lower")), float(limit.get("upper"))]
        assert list(arm_model.joint(f"joint{k}").range) == expected
        assert arm_model.jnt_limited[arm_model.joint(f"joint{k}").id]


# --- collision set ----------------------------------------------------------


def _contact_names(model: mujoco.MjModel, data: mujoco.MjData) -> list[tuple[str, str]]:
    return [(model.geom(c.geom1).name, model.geom(c.geom2).name) for c in data.contact[: data.ncon]]


def test_no_arm_geoms_within_the_report_band_at_home(arm_model):
    data = _forward(arm_model, HOME_Q)
    assert data.ncon == 0, _contact_names(arm_model, data)


def test_no_contacts_at_home_in_a_world_including_the_table():
    model, layout = build_world(n_arms=2)
    data = _forward(model, HOME_Q, 0, layout)
    assert data.ncon == 0, _contact_names(model, data)
    assert model.geom("table").id >= 0


def test_hand_is_clear_of_links_0_to_4_at_home():
    model, layout = build_world(n_arms=1, hand=True)
    data = _forward(model, HOME_Q, 0, layout)
    for c in data.contact[: data.ncon]:
        links = {layout.geom_link[c.geom1], layout.geom_link[c.geom2]}
        hand_involved = -1 in links
        assert not (hand_involved and links & {0, 1, 2, 3, 4}), _contact_names(model, data)


def test_report_band_flags_close_links_without_any_force():
    """Joint 4 folded, joint 5 twisted: link5 comes within 50 mm of link1, untouched."""
    model, layout = build_world(n_arms=1)
    q = HOME_Q.copy()
    q[1], q[3], q[4] = 0.0, -3.04, -1.6
    data = _forward(model, q, 0, layout)
    close = [
        c
        for c in data.contact[: data.ncon]
        if {layout.geom_link[c.geom1], layout.geom_link[c.geom2]} == {1, 5}
    ]
    assert close, _contact_names(model, data)
    for c in close:
        assert 0.0 < c.dist < SELF_COLLISION_DISTANCE
        assert c.efc_address == -1  # reported, no constraint row, no force
    assert data.nefc == 0


def test_report_band_params_give_a_50mm_band_under_each_mujoco_rule():
    assert report_band_params((4, 0)) == (0.0, 0.025)  # summed; detect < margin + gap
    assert report_band_params((3, 6)) == (0.025, 0.025)  # summed; force < margin - gap
    assert report_band_params((3, 3)) == (0.05, 0.05)  # maximum; force < margin - gap


# --- world layout -----------------------------------------------------------


@pytest.mark.parametrize(("n", "hand"), [(1, False), (4, False), (2, True)])
def test_layout_arrays_have_documented_shapes_and_point_at_the_right_names(n, hand):
    model, layout = build_world(n_arms=n, hand=hand)
    assert layout.n == n and layout.hand == hand
    assert layout.qpos_adr.shape == layout.dof_adr.shape == layout.actuator_ids.shape == (n, 7)
    assert layout.flange_site.shape == (n,)
    assert layout.base_pos.shape == (n, 3)
    assert layout.link_body.shape == (n, 8)
    assert layout.geom_arm.shape == layout.geom_link.shape == (model.ngeom,)
    for i in range(n):
        for k in range(7):
            joint = model.joint(f"arm{i}/joint{k + 1}")
            assert layout.qpos_adr[i, k] == joint.qposadr[0]
            assert layout.dof_adr[i, k] == joint.dofadr[0]
            assert model.actuator(int(layout.actuator_ids[i, k])).name == f"arm{i}/joint{k + 1}"
        assert model.site(int(layout.flange_site[i])).name == f"arm{i}/flange"
        for k in range(8):
            assert model.body(int(layout.link_body[i, k])).name == f"arm{i}/link{k}"
    for g in range(model.ngeom):
        body = model.geom_bodyid[g]
        name = model.body(body).name
        if layout.geom_arm[g] >= 0:
            assert name == f"arm{layout.geom_arm[g]}/link{layout.geom_link[g]}"
        else:
            assert layout.geom_link[g] == -1 and "/link" not in name
    assert layout.geom_arm[model.geom("table").id] == -1
    if hand:
        assert layout.finger_qpos_adr.shape == layout.finger_dof_adr.shape == (n, 2)
        assert layout.finger_actuator.shape == layout.tcp_site.shape == (n,)
        for i in range(n):
            for k, joint in enumerate(("finger_joint1", "finger_joint2")):
                assert layout.finger_qpos_adr[i, k] == model.joint(f"arm{i}/{joint}").qposadr[0]
            assert model.actuator(int(layout.finger_actuator[i])).name == f"arm{i}/fingers"
            assert model.site(int(layout.tcp_site[i])).name == f"arm{i}/tcp"
    else:
        assert layout.finger_qpos_adr is None and layout.finger_actuator is None
        assert layout.finger_dof_adr is None and layout.tcp_site is None


def test_home_keyframe_puts_every_arm_at_home_with_open_fingers():
    model, layout = build_world(n_arms=3, hand=True)
    key = model.key("home").id
    for i in range(3):
        np.testing.assert_array_equal(model.key_qpos[key][layout.qpos_adr[i]], HOME_Q)
        np.testing.assert_array_equal(model.key_qpos[key][layout.finger_qpos_adr[i]], 0.04)
        assert model.key_ctrl[key][layout.finger_actuator[i]] == 0.04
    assert not np.any(model.key_ctrl[key][layout.actuator_ids])


def test_hand_tcp_points_down_at_home():
    model, layout = build_world(n_arms=1, hand=True)
    data = _forward(model, HOME_Q, 0, layout)
    site = layout.tcp_site[0]
    np.testing.assert_allclose(data.site_xpos[site], [0.306891, 0.0, 0.486882], atol=1e-4)
    np.testing.assert_allclose(
        data.site_xmat[site].reshape(3, 3), np.diag([1.0, -1.0, -1.0]), atol=1e-5
    )


def test_world_keeps_1ms_implicitfast_and_builds_64_arms():
    model, layout = build_world(n_arms=64)
    assert model.opt.timestep == 0.001
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    assert layout.qpos_adr.shape == (64, 7)
    assert len(set(layout.qpos_adr.ravel())) == 64 * 7


def test_home_q_is_read_only():
    with pytest.raises(ValueError):
        HOME_Q[0] = 1.0
