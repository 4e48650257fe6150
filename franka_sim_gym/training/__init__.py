"""Training on franka-sim-gym: what a learning framework needs beyond the Gymnasium ids.

Install with the ``train`` extra (``pip install 'franka-sim-gym[train]'``: a pinned
stable-baselines3, torch, matplotlib, tqdm, tensorboard). docs/training.md tells the
default run and its figures.

* ``franka_sim_gym.training.sb3_vec_env.FrankaFCISB3VecEnv`` — an SB3 ``VecEnv`` over
  the native batched env (N arms in one MuJoCo world);
* ``franka_sim_gym.training.sb3_her.ReflexChargedHerReplayBuffer`` — SB3's HER replay
  buffer keeping each transition's reflex charge, so that a relabelled reflex is no
  success;
* ``franka_sim_gym.training.evaluation.evaluate`` — success and reflex rates of any
  policy with a ``predict`` method (gymnasium and numpy only).

The modules are imported one by one (this file imports none of them), so that the
evaluation works without stable-baselines3. Nothing in ``fci``, ``sim``, ``envs`` or
``server`` imports this package.
"""
