"""Gymnasium environments driving the simulated FCI controller in-process.

``import franka_sim_gym`` registers them (entry points are strings: nothing
heavy is imported until an env is made):

* ``FrankaFCI-v0`` — reach, joint-position actions through libfranka's rate limiter;
* ``FrankaFCIJointPosition-v0``, ``FrankaFCIJointVelocity-v0``,
  ``FrankaFCICartesianPose-v0``, ``FrankaFCICartesianVelocity-v0``, ``FrankaFCITorque-v0``
  — one id per action interface (every constructor argument of
  ``franka_sim_gym.envs.fci_env.FrankaFCIEnv`` can be passed to ``gym.make``).

Every id also has a native batched vector env (N arms in one MuJoCo world):
``gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``
(``franka_sim_gym.envs.vector_env.FrankaFCIVectorEnv``).
"""

from __future__ import annotations

import gymnasium as gym

_ENTRY = "franka_sim_gym.envs.fci_env:FrankaFCIEnv"
_VECTOR_ENTRY = "franka_sim_gym.envs.vector_env:FrankaFCIVectorEnv"
IDS = {
    "FrankaFCI-v0": {"action_interface": "joint_position"},
    "FrankaFCIJointPosition-v0": {"action_interface": "joint_position"},
    "FrankaFCIJointVelocity-v0": {"action_interface": "joint_velocity"},
    "FrankaFCICartesianPose-v0": {"action_interface": "cartesian_pose"},
    "FrankaFCICartesianVelocity-v0": {"action_interface": "cartesian_velocity"},
    "FrankaFCITorque-v0": {"action_interface": "torque"},
}


def register_envs() -> None:
    """Register every id (idempotent)."""
    for env_id, kwargs in IDS.items():
        if env_id not in gym.registry:
            gym.register(
                id=env_id, entry_point=_ENTRY, vector_entry_point=_VECTOR_ENTRY, kwargs=kwargs
            )


register_envs()
