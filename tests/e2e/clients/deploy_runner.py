"""examples/deploy_pylibfranka.py with a scripted policy:
`python deploy_runner.py HOST EPISODES [ENV_KWARGS_JSON]`.

The policies have a trained policy's interface (SB3's ``predict``); the one run is
chosen by the env arguments' ``action_interface`` (``POLICIES``):

* joint position (the default): a proportional controller in Cartesian space, mapped
  to joints by the damped least-squares inverse of the flange Jacobian (MuJoCo's, of
  the simulator's own FR3 model; O_T_EE is the flange with libfranka's default end
  effector);
* Cartesian velocity (tests/scripted_policies.py, TowardTheGoal): the Cartesian
  error over 0.1 m, clipped to [-1, 1] (a 3-dof
  translational twist, 0.3 m/s per unit action);
* Cartesian pose: TowardTheGoal with POSE_STEPS (30 % of the error a step, at most
  1.5 cm: a 3-dof translational target near the reference).

Prints the deploy result as its last line (JSON). Run in a child process: libfranka
has no reply timeout.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import mujoco
import numpy as np

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT / "examples"))
sys.path.insert(0, str(ROOT))

from deploy_pylibfranka import deploy  # noqa: E402

from franka_sim_gym.envs.commands import ActionScale  # noqa: E402
from franka_sim_gym.sim.arm import ArmPhysics  # noqa: E402
from tests.scripted_policies import POSE_STEPS, TowardTheGoal  # noqa: E402


class ProportionalReach:
    """``predict(obs) -> (action, None)``: a joint step that removes ``gain`` of the
    Cartesian error, in units of the env's unit action (ActionScale.position), at most
    ``limit`` per joint."""

    def __init__(self, gain: float = 0.5, limit: float = 0.3) -> None:
        self.gain = gain
        # Half actions at most: at full saturation near a shrinking velocity envelope
        # libfranka's own rate limiter can exceed the jerk bound (docs/env.md).
        self.limit = limit
        self.physics = ArmPhysics(n_arms=1)
        layout = self.physics.layout
        self.site = int(layout.flange_site[0])
        self.qpos, self.dofs = layout.qpos_adr[0], layout.dof_adr[0]
        self.jacp = np.zeros((3, self.physics.model.nv))

    def predict(self, obs: dict, deterministic: bool = True):
        model, data = self.physics.model, self.physics.data
        data.qpos[self.qpos] = obs["observation"][:7]
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_jacSite(model, data, self.jacp, None, self.site)
        jac = self.jacp[:, self.dofs]
        error = obs["desired_goal"].astype(np.float64) - obs["achieved_goal"]
        step = jac.T @ np.linalg.solve(jac @ jac.T + 1e-3 * np.eye(3), self.gain * error)
        action = np.clip(step / ActionScale().position, -self.limit, self.limit)
        return action.astype(np.float32), None


#: The scripted policy of each action interface.
POLICIES = {
    "joint_position": ProportionalReach,
    "cartesian_velocity": TowardTheGoal,
    "cartesian_pose": lambda: TowardTheGoal(**POSE_STEPS),
}


def main() -> None:
    host, episodes = sys.argv[1], int(sys.argv[2])
    kwargs = json.loads(sys.argv[3]) if len(sys.argv) > 3 else {}
    policy = POLICIES[kwargs.get("action_interface", "joint_position")]()
    result = deploy(host, policy, episodes, seed=0, env_kwargs=kwargs)
    print(json.dumps(result))


if __name__ == "__main__":
    main()
