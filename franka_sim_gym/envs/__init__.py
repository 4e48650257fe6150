"""Gymnasium environments driving the simulated FCI controller in-process.

``import franka_sim_gym`` registers them (entry points are strings: the robot is not
imported until an env is made). Per task of ``envs/tasks/TASKS``, one id per action
interface plus its default:

* Reach: ``FrankaFCI-v0`` (joint positions through libfranka's rate limiter),
  ``FrankaFCIJointPosition-v0``, ``FrankaFCIJointVelocity-v0``,
  ``FrankaFCICartesianPose-v0``, ``FrankaFCICartesianVelocity-v0``,
  ``FrankaFCITorque-v0``, ``FrankaFCIJointPositionAsync-v0``;
* Push, PickAndPlace, PegInsertion: ``FrankaFCIPush-v0`` (their ``default_interface``,
  Cartesian velocity) and ``FrankaFCIPushCartesianPose-v0``,
  ``FrankaFCIPushJointPosition-v0``, ... (their ``interfaces``).

Every constructor argument of ``franka_sim_gym.envs.fci_env.FrankaFCIEnv`` can be passed
to ``gym.make``; each id's spec carries its task's ``max_episode_steps``, which
``gym.make(id, max_episode_steps=N)`` overrides. Every id also has a native batched
vector env (N arms, each its own MuJoCo world):
``gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``
(``franka_sim_gym.envs.vector_env.FrankaFCIVectorEnv``).
"""

from __future__ import annotations

import gymnasium as gym

from .tasks import TASKS

ENTRY = "franka_sim_gym.envs.fci_env:FrankaFCIEnv"
VECTOR_ENTRY = "franka_sim_gym.envs.vector_env:FrankaFCIVectorEnv"
#: Reach's episode length (its ids' specs, and an env made without one); every task
#: names its own (``Task.max_episode_steps``).
EPISODE_STEPS = 50
#: Each action interface's part of an id.
INTERFACE_IDS = {
    "joint_position": "JointPosition",
    "joint_velocity": "JointVelocity",
    "cartesian_pose": "CartesianPose",
    "cartesian_velocity": "CartesianVelocity",
    "torque": "Torque",
    "joint_position_async": "JointPositionAsync",
}


def task_ids() -> dict[str, dict]:
    """Every id with its arguments, from ``TASKS``."""
    ids = {}
    for name, task in TASKS.items():
        prefix = f"FrankaFCI{task.id_name}"

        def arguments(interface: str, name=name, task=task) -> dict:
            extra = task.cartesian_kwargs if interface.startswith("cartesian") else {}
            return {"task": name, "action_interface": interface, **extra}

        ids[f"{prefix}-v0"] = arguments(task.default_interface)
        for interface in task.interfaces or tuple(INTERFACE_IDS):
            ids[f"{prefix}{INTERFACE_IDS[interface]}-v0"] = arguments(interface)
    return ids


#: Every registered id and its arguments.
IDS = task_ids()


def register_envs() -> None:
    """Register every id (idempotent)."""
    for env_id, kwargs in IDS.items():
        if env_id not in gym.registry:
            gym.register(
                id=env_id,
                entry_point=ENTRY,
                vector_entry_point=VECTOR_ENTRY,
                max_episode_steps=TASKS[kwargs["task"]].max_episode_steps,
                kwargs=kwargs,
            )


register_envs()
