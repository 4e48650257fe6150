"""A reality draw's scene (sim/truth.py, envs/tasks/): the table's height, the objects' mass
and friction and a fixture's offset are the arm's own world's, not the task's nominal ones,
while the goals stay where the task put them."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

import franka_sim_gym  # noqa: F401  (registers the ids)

SCENE = {
    "scene": {
        "table_height": 0.004,
        "object_mass_scale": 1.5,
        "object_friction_scale": 0.6,
        "fixture_offset": [0.001, -0.0015],
    }
}


def test_push_puts_the_block_on_the_drawn_table_with_its_drawn_mass_and_friction():
    env = gym.make("FrankaFCIPush-v0", reality=SCENE).unwrapped
    ideal = gym.make("FrankaFCIPush-v0").unwrapped
    obs, _ = env.reset(seed=2)
    nominal, _ = ideal.reset(seed=2)
    physics = env.core.controller.physics
    truth = physics.truth
    block = truth.objects[0]
    assert physics.models[0].body_mass[block] == 1.5 * physics.model.body_mass[block]
    geoms = truth.object_geoms
    np.testing.assert_array_equal(
        physics.models[0].geom_friction[geoms, 0], 0.6 * physics.model.geom_friction[geoms, 0]
    )
    assert physics.models[0].geom_pos[truth.table, 2] == 0.004
    # the block rests on the raised table: 4 mm higher than the ideal one, same x, y
    for _ in range(5):
        obs, *_ = env.step(np.zeros(3, dtype=np.float32))
        nominal, *_ = ideal.step(np.zeros(3, dtype=np.float32))
    lift = obs["achieved_goal"] - nominal["achieved_goal"]
    np.testing.assert_allclose(lift, [0.0, 0.0, 0.004], atol=2e-4)
    np.testing.assert_array_equal(obs["desired_goal"], nominal["desired_goal"])


def test_peg_insertion_puts_the_fixture_off_the_goal_by_the_drawn_offset():
    env = gym.make("FrankaFCIPegInsertion-v0", reality=SCENE).unwrapped
    obs, _ = env.reset(seed=5)
    physics = env.core.controller.physics
    fixture = physics.layout.scene_body["fixture"][0]
    mocap = int(physics.model.body_mocapid[fixture])
    goal = env.core.goals[0]
    np.testing.assert_allclose(
        physics.datas[0].mocap_pos[mocap], goal + [0.001, -0.0015, 0.004], atol=1e-15
    )
    np.testing.assert_allclose(obs["desired_goal"], goal, atol=1e-7)  # where the task said
