"""The table every arm stands on, and scene fragments (sim/scene.py, sim/world.py)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from franka_sim_gym.sim.arm import ArmPhysics
from franka_sim_gym.sim.scene import SCENES, TABLE
from franka_sim_gym.sim.world import HOME_Q

#: A pose whose flange points down 18 cm above the table (joint 2 forward, elbow bent).
OVER_THE_TABLE = np.array([0.0, 0.6, 0.0, -1.9, 0.0, 2.5, np.pi / 4])


def table_contacts(physics: ArmPhysics) -> tuple[float, float, set[int]]:
    """(normal force [N], deepest penetration [m], geoms touching) of the table's
    active contacts."""
    m, d = physics.model, physics.data
    table = m.geom(TABLE).id
    force, depth, geoms = 0.0, 0.0, set()
    wrench = np.zeros(6)
    for c in range(d.ncon):
        con = d.contact[c]
        if table not in (con.geom1, con.geom2) or con.efc_address < 0:
            continue
        mujoco.mj_contactForce(m, d, c, wrench)
        force += wrench[0]
        depth = max(depth, -con.dist)
        geoms.add(int(con.geom2 if con.geom1 == table else con.geom1))
    return force, depth, geoms


def press(physics: ArmPhysics, newtons: float):
    """Lower the arm onto the table with joint 2 and press until ``newtons``: the table's
    contacts then, and after 1 s of holding that servo target."""
    physics.reset_arms([0], OVER_THE_TABLE[None])
    target = OVER_THE_TABLE.copy()
    for _ in range(4000):
        pressed = table_contacts(physics)
        if pressed[0] >= newtons:
            break
        target[1] += 0.0001  # 0.1 rad/s: a slow descent, then a slow build-up of force
        physics.step(target[None], None)
    else:
        raise AssertionError(f"never pressed {newtons} N")
    for _ in range(1000):  # hold: the contact must settle, not ring
        physics.step(target[None], None)
    return pressed, table_contacts(physics)


def test_the_arm_presses_on_the_table_under_a_millimetre_at_50_newtons():
    physics = ArmPhysics(1)
    (force, depth, _), (held, held_depth, geoms) = press(physics, 50.0)
    assert force >= 50.0 and depth < 1e-3
    # Stable at the 1 ms step: the held arm rests on the table, not ringing on it, and
    # sinks less than 50 um (rigid like a table: MuJoCo's default contact sinks
    # ~0.15 mm at this force).
    assert held > 10.0 and held_depth < 5e-5
    assert np.abs(physics.dq).max() < 1e-3
    # What touches is the arm's own collision geometry.
    assert {int(physics.layout.geom_arm[g]) for g in geoms} == {0}


def test_the_hand_touches_the_table_and_the_base_never_does():
    physics = ArmPhysics(1, hand=True)
    _, (_, _, geoms) = press(physics, 30.0)
    hand = physics.layout.hand_body[0]
    hand_bodies = {hand, *np.flatnonzero(physics.model.body_parentid == hand).tolist()}
    assert any(int(physics.model.geom_bodyid[g]) in hand_bodies for g in geoms)
    # link0 is welded to the world like the table: no contact between them, ever.
    link0 = physics.layout.link_body[0, 0]
    d = physics.data
    bodies = physics.model.geom_bodyid[d.contact.geom[: d.ncon]]
    assert not np.any(bodies == link0)


@pytest.mark.parametrize("name", sorted(SCENES))
def test_each_arm_gets_its_own_copy_of_a_shipped_scene_at_rest_on_its_table(name):
    physics = ArmPhysics(3, scene=name)
    layout = physics.layout
    assert layout.scene_qpos_adr, "every shipped scene has an object to place"

    def positions(joint, adr):
        return np.array([d.qpos[adr[0] : adr[0] + 3] for d in physics.datas])

    start = {j: positions(j, a) for j, a in layout.scene_qpos_adr.items()}
    physics.datas[1].qpos[layout.scene_qpos_adr[next(iter(start))][1]] += 0.05  # arm 1's own
    physics.forward(np.array([1]))
    for _ in range(300):
        physics.step(physics.q.copy(), None)
    for joint, adr in layout.scene_qpos_adr.items():
        pos = positions(joint, adr)
        # One copy per arm in its own world (its MjData), resting where it was put; the
        # arms that were not disturbed agree bit for bit.
        np.testing.assert_allclose(pos[[0, 2]], start[joint][[0, 2]], atol=1e-4)
        assert np.array_equal(pos[0], pos[2]), joint
    moved = next(iter(start))
    assert not np.array_equal(positions(moved, layout.scene_qpos_adr[moved])[1], start[moved][1])


def test_a_block_rests_on_the_table_within_a_tenth_of_a_millimetre():
    physics = ArmPhysics(1, scene="block")
    adr = physics.layout.scene_qpos_adr["block"][0]
    for _ in range(300):
        physics.step(physics.q.copy(), None)
    assert abs(physics.data.qpos[adr + 2] - 0.02) < 1e-4  # half of the 4 cm cube


def test_a_scene_is_any_mjcf_fragment_given_by_path(tmp_path):
    path = tmp_path / "ball.xml"
    path.write_text(
        '<mujoco><worldbody><body name="ball" pos="0.4 0 0.5"><freejoint name="ball"/>'
        '<geom type="sphere" size="0.03" mass="0.2"/></body></worldbody></mujoco>'
    )
    physics = ArmPhysics(2, scene=path)
    adr = physics.layout.scene_qpos_adr["ball"]
    for _ in range(600):  # it falls onto the table and stops there
        physics.step(physics.q.copy(), None)
    heights = [d.qpos[a + 2] for d, a in zip(physics.datas, adr, strict=True)]
    np.testing.assert_allclose(heights, [0.03, 0.03], atol=2e-4)


def test_an_unknown_scene_or_a_broken_file_is_a_value_error_naming_it(tmp_path):
    with pytest.raises(ValueError, match="'nowhere.xml' is not a shipped scene"):
        ArmPhysics(1, scene="nowhere.xml")
    broken = tmp_path / "broken.xml"
    broken.write_text("<mujoco><worldbody><body></mujoco>")
    with pytest.raises(ValueError, match="broken.xml"):
        ArmPhysics(1, scene=broken)


def test_a_reset_restarts_the_arms_objects_and_fingers_without_warm_start():
    # An arm of the vector env runs on to the end of the step after its episode ended,
    # a single env stops: what the solver remembers of that (MuJoCo's qacc_warmstart)
    # must not reach the next episode.
    physics = ArmPhysics(2, hand=True, scene="block")
    lay = physics.layout
    block = lay.scene_dof_adr["block"][:, None] + np.arange(6)
    for d in physics.datas:
        d.qacc_warmstart[:] = 1.0
    physics.reset_arms(np.array([1]), HOME_Q[None])
    warm = physics.datas[1].qacc_warmstart
    assert np.all(warm[block[1]] == 0) and np.all(warm[lay.finger_dof_adr[1]] == 0)
    assert np.all(warm[lay.dof_adr[1]] == 0)
    assert np.all(physics.datas[0].qacc_warmstart == 1)  # arm 0's world untouched
