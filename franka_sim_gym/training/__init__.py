"""Training on franka-sim-gym: what a learning framework needs beyond the Gymnasium ids.

Install with the ``train`` extra (``pip install 'franka-sim-gym[train]'``: a pinned
stable-baselines3, torch, matplotlib, tqdm, tensorboard). docs/training.md tells the
default run and its figures.

* ``franka_sim_gym.training.sb3_vec_env.FrankaFCISB3VecEnv`` — an SB3 ``VecEnv`` over
  the native batched env (N arms, each its own MuJoCo world);
* ``franka_sim_gym.training.sb3_her.ReflexChargedHerReplayBuffer`` — SB3's HER replay
  buffer keeping each transition's reflex charge, so that a relabelled reflex is no
  success;
* ``franka_sim_gym.training.evaluation.evaluate`` — success and reflex rates of any
  policy with a ``predict`` method (gymnasium and numpy only);
* ``franka_sim_gym.training.datasets.record`` — any policy's episodes as a Minari
  dataset that replays bit for bit (the ``datasets`` extra);
* ``franka_sim_gym.training.sb3_demos`` — SAC + HER learning from such a dataset: batches
  half demonstrations (``DemoMixedHerReplayBuffer``), a behaviour-cloning term and a
  behaviour-cloning baseline (docs/demonstrations.md).

The modules are imported one by one (this file imports none of them), so that the
evaluation works without stable-baselines3. Nothing in ``fci``, ``sim``, ``envs`` or
``server`` imports this package.
"""

from __future__ import annotations

from pathlib import Path

#: The rl-zoo3 hyperparameter files shipped with the package, one per algorithm.
HYPERPARAMS = Path(__file__).resolve().parent / "hyperparams"


def hyperparams_file(algo: str = "sac") -> Path:
    """The shipped rl-zoo3 file of ``algo`` (rl-zoo3's ``-conf``; docs/training.md):
    ``python -m franka_sim_gym.training sac`` prints its path."""
    path = HYPERPARAMS / f"{algo}.yml"
    if not path.is_file():
        shipped = sorted(p.stem for p in HYPERPARAMS.glob("*.yml"))
        raise ValueError(f"no shipped rl-zoo3 file for {algo!r}: there is one for {shipped}")
    return path
