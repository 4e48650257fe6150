"""Learning from demonstrations with stable-baselines3: a replay buffer whose batches
mix a Minari dataset's transitions with the online ones (RLPD's symmetric sampling).

    from franka_sim_gym.training.sb3_demos import DemoMixedHerReplayBuffer
    model = SAC("MultiInputPolicy", env, replay_buffer_class=DemoMixedHerReplayBuffer,
                replay_buffer_kwargs=dict(demos="franka/push-v0", demo_fraction=0.5,
                                          n_sampled_goal=4, goal_selection_strategy="future"))

Each batch of n draws ``round(demo_fraction * n)`` transitions from the demonstrations
and the rest from what the learner collected (Ball et al., 2023, "Efficient Online
Reinforcement Learning with Offline Data": half and half). Until the learner has a
finished episode of its own the whole batch is demonstrations, so learning can start at
the first step. Both halves go through HER (``future`` goals, relabelled with the env's
``compute_reward``) and keep the reflex charge: the demonstrations' charges come from
the ``reflex_penalty`` the dataset recorded (franka_sim_gym.training.datasets), so a
demonstration that ended in a reflex stays charged when relabelled, as an online one
does (franka_sim_gym.training.sb3_her).

``behaviour_cloning`` pre-trains a policy's actor on a dataset (mean squared error of
its deterministic action), the plain baseline of what demonstrations alone give.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np
import torch as th
from stable_baselines3.common.type_aliases import DictReplayBufferSamples

from franka_sim_gym.training.datasets import DEMONSTRATOR_ACTION
from franka_sim_gym.training.sb3_her import ReflexChargedHerReplayBuffer


def load(demos: Any):
    """A ``minari.MinariDataset`` from an id (or the dataset itself)."""
    if isinstance(demos, str):
        import minari

        return minari.load_dataset(demos)
    return demos


def load_all(demos: Any) -> list:
    """``MinariDataset``s from an id, a dataset, or a sequence of either (DAgger's
    rounds aggregated with the demonstrations they started from)."""
    if isinstance(demos, Sequence) and not isinstance(demos, str):
        if not demos:
            raise ValueError("no dataset given: demos is an empty sequence")
        return [load(d) for d in demos]
    return [load(demos)]


def check_spaces(dataset, observation_space, action_space) -> None:
    """A ``ValueError`` when the dataset's spaces are not the learner's env's."""
    if dataset.observation_space != observation_space or dataset.action_space != action_space:
        raise ValueError(
            f"dataset {dataset.id!r} was recorded on {dataset.env_spec.id} with arguments "
            f"{dataset.env_spec.kwargs}: observations {shapes(dataset.observation_space)}, "
            f"actions {dataset.action_space.shape}; the env has observations "
            f"{shapes(observation_space)}, actions {action_space.shape} (bounds are compared "
            "too): train on the dataset's id and arguments"
        )


def shapes(space) -> dict:
    return {key: sub.shape for key, sub in space.spaces.items()}


def fill(buffer: ReflexChargedHerReplayBuffer, dataset) -> None:
    """Add every episode of ``dataset`` to ``buffer`` (one env), as SB3 adds a step:
    ``done`` at the episode's end, a time limit as ``TimeLimit.truncated``, the reflex
    charge from the recorded ``reflex_penalty``."""
    for episode in dataset.iterate_episodes():
        obs = episode.observations
        steps = len(episode)
        penalty = episode.infos["reflex_penalty"]
        for t in range(steps):
            terminated = bool(episode.terminations[t])
            done = terminated or bool(episode.truncations[t]) or t == steps - 1
            buffer.add(
                {key: value[t][None] for key, value in obs.items()},
                {key: value[t + 1][None] for key, value in obs.items()},
                episode.actions[t][None],
                np.array([episode.rewards[t]]),
                np.array([done]),
                [
                    {
                        "reflex_penalty": float(penalty[t + 1]),
                        "TimeLimit.truncated": done and not terminated,
                    }
                ],
            )


class DemoMixedHerReplayBuffer(ReflexChargedHerReplayBuffer):
    """``ReflexChargedHerReplayBuffer`` whose batches are part demonstrations.

    Args:
        demos: a Minari dataset id (or a loaded ``MinariDataset``) recorded on the env's
            id with the env's arguments (franka_sim_gym.training.datasets.record).
        demo_fraction: the share of each batch drawn from the demonstrations (0.5:
            RLPD's symmetric sampling); the whole batch until the learner has finished
            an episode.
        **kwargs: every argument of ``ReflexChargedHerReplayBuffer``; the
            demonstrations' buffer is relabelled the same way.
    """

    def __init__(
        self,
        buffer_size: int,
        observation_space,
        action_space,
        env=None,
        demos: Any = None,
        demo_fraction: float = 0.5,
        **kwargs,
    ) -> None:
        if demos is None:
            raise ValueError("DemoMixedHerReplayBuffer needs demos: a Minari dataset id")
        if not 0.0 <= demo_fraction <= 1.0:
            raise ValueError(f"demo_fraction must be in [0, 1], got {demo_fraction}")
        super().__init__(buffer_size, observation_space, action_space, env=env, **kwargs)
        dataset = load(demos)
        check_spaces(dataset, observation_space, action_space)
        self.demo_fraction = float(demo_fraction)
        own = {k: v for k, v in kwargs.items() if k not in ("n_envs", "optimize_memory_usage")}
        # One slot more than the transitions: the buffer never wraps.
        self.demos = ReflexChargedHerReplayBuffer(
            dataset.total_steps + 1, observation_space, action_space, env=env, n_envs=1, **own
        )
        fill(self.demos, dataset)

    def set_env(self, env) -> None:
        super().set_env(env)
        if self.demos.env is None:
            self.demos.set_env(env)

    def demo_count(self, batch_size: int) -> int:
        """How many of a batch of ``batch_size`` come from the demonstrations."""
        if not (self.ep_length > 0).any():  # no finished online episode yet
            return batch_size
        return int(round(self.demo_fraction * batch_size))

    def sample(self, batch_size: int, env=None) -> DictReplayBufferSamples:
        """``demo_count(batch_size)`` demonstration transitions, then online ones."""
        n_demo = self.demo_count(batch_size)
        parts = []
        if n_demo > 0:
            parts.append(self.demos.sample(n_demo, env))
        if n_demo < batch_size:
            parts.append(super().sample(batch_size - n_demo, env))
        if len(parts) == 1:
            return parts[0]
        return DictReplayBufferSamples(
            observations={
                k: th.cat([p.observations[k] for p in parts]) for k in parts[0].observations
            },
            actions=th.cat([p.actions for p in parts]),
            next_observations={
                k: th.cat([p.next_observations[k] for p in parts]) for k in parts[0].observations
            },
            dones=th.cat([p.dones for p in parts]),
            rewards=th.cat([p.rewards for p in parts]),
        )


def demo_arrays(demos: Any) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Every (observation, action) pair of ``demos`` (a dataset, or a sequence of them:
    ``load_all``): the observations a policy acted on (an episode's last observation has
    no action) and the actions: the recorded ones, or a labelled dataset's
    ``demonstrator_action`` (what the demonstrator chose there; a noisy action or a
    learner's was executed)."""
    obs: dict[str, list] = {}
    actions = []
    episodes = (e for dataset in load_all(demos) for e in dataset.iterate_episodes())
    for episode in episodes:
        for key, value in episode.observations.items():
            obs.setdefault(key, []).append(value[:-1])
        # a noise-injected demonstration: the demonstrator's action, not the executed one
        labels = episode.infos.get(DEMONSTRATOR_ACTION)
        actions.append(episode.actions if labels is None else labels[1:])
    return {k: np.concatenate(v) for k, v in obs.items()}, np.concatenate(actions)


def behaviour_cloning(
    policy,
    demos: Any,
    steps: int,
    batch_size: int = 256,
    learning_rate: float = 1e-3,
    seed: int = 0,
    log_every: int = 0,
    normalize=None,
    exploration_std: float | None = None,
    on_step: Callable[[int], None] | None = None,
    prepare: Callable[[dict, np.ndarray], tuple[dict, np.ndarray]] | None = None,
) -> list[float]:
    """Fit an SB3 actor-critic policy's actor to a dataset's actions: ``steps`` Adam
    steps on the mean squared error between its deterministic action and the recorded
    one, on batches drawn uniformly from every recorded step. Returns the losses.

    ``demos``: a dataset or its id, or a sequence of them, fitted as one (``load_all``).

    ``on_step(k)``, when given, is called after the k-th step (k = 1 ... steps), in the
    policy's training mode (e.g. to keep a copy of the actor: examples/train_bc.py's
    learning curve).

    ``policy`` is ``model.policy`` of an SB3 SAC / TD3 (anything with ``actor`` and
    ``obs_to_tensor``); its observation preprocessing is the model's own, after
    ``normalize`` (e.g. a ``VecNormalize``'s ``normalize_obs``) when given.

    ``prepare(obs, actions)``, when given, turns the recorded observations and actions
    into the ones the policy is fitted on, before anything else (the line's frame:
    ``line_frame.to_line_frame``).

    ``exploration_std`` (SAC): also fit the actor's log standard deviation (before the
    tanh squashing) to the log of this. An untrained SAC actor explores with a standard
    deviation of about 1 before the squashing, i.e. nearly uniform actions: the
    episodes a cloned policy collects then are not the policy's, and the first critic
    learns from noise. Cloning it to the demonstrations' own noise keeps the first
    episodes near what was cloned (docs/demonstrations.md, "SAC after the clone")."""
    datasets = load_all(demos)
    for dataset in datasets:
        check_spaces(dataset, policy.observation_space, policy.action_space)
    obs, actions = demo_arrays(datasets)
    if prepare is not None:
        obs, actions = prepare(obs, actions)
    if normalize is not None:
        obs = normalize(obs)
    target = th.as_tensor(policy.scale_action(actions), dtype=th.float32)
    actor = policy.actor
    optimizer = th.optim.Adam(actor.parameters(), lr=learning_rate)
    rng = np.random.default_rng(seed)
    losses = []
    policy.set_training_mode(True)
    for step in range(steps):
        rows = rng.integers(0, len(target), batch_size)
        batch, _ = policy.obs_to_tensor({k: v[rows] for k, v in obs.items()})
        loss = th.nn.functional.mse_loss(actor(batch, deterministic=True), target[rows])
        if exploration_std is not None:
            _, log_std, _ = actor.get_action_dist_params(batch)
            loss = loss + th.nn.functional.mse_loss(
                log_std, th.full_like(log_std, float(np.log(exploration_std)))
            )
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        losses.append(loss.item())
        if log_every and (step + 1) % log_every == 0:
            print(f"bc step {step + 1}: loss {np.mean(losses[-log_every:]):.5f}", flush=True)
        if on_step is not None:
            on_step(step + 1)
    policy.set_training_mode(False)
    return losses


class BehaviourCloningAdam(th.optim.Adam):
    """Adam for an SB3 actor that adds a behaviour-cloning term to every actor step.

    SB3's SAC calls ``actor.optimizer.step()`` after backpropagating its actor loss;
    this optimizer first adds ``weight`` times the gradient of the mean squared error
    between the actor's deterministic action and the demonstrated one, on a batch of
    ``batch_size`` recorded steps (their own goals: a relabelled goal is not what the
    demonstrator acted for). Nair et al. (2018), "Overcoming Exploration in
    Reinforcement Learning with Demonstrations", add this term to DDPG + HER.

    ``warmup``: for its first ``warmup`` steps SAC's own actor gradient is dropped and
    the actor takes the behaviour-cloning gradient only, so that the cloned actor is
    moved by SAC only once the critics have learnt something (they start at random,
    and their first gradients undo the cloning). Dropped, not scaled down: Adam divides
    each step by the gradient's running magnitude, so a gradient scaled by a factor
    moves the parameters almost as far as the whole one.
    """

    def __init__(
        self,
        params: Iterable[th.nn.Parameter],
        actor: th.nn.Module,
        obs: dict[str, np.ndarray],
        actions: np.ndarray,
        weight: float,
        batch_size: int = 256,
        normalize: Callable[[dict], dict] | None = None,
        seed: int = 0,
        warmup: int = 0,
        **adam_kwargs: Any,
    ) -> None:
        super().__init__(params, **adam_kwargs)
        self.actor, self.obs, self.weight = actor, obs, float(weight)
        self.warmup, self.steps = int(warmup), 0
        self.target = th.as_tensor(actions, dtype=th.float32)
        self.batch_size, self.normalize = batch_size, normalize
        self.rng = np.random.default_rng(seed)
        self.last_loss = float("nan")

    def step(self, closure=None):
        self.steps += 1
        if self.steps <= self.warmup:  # SAC's own gradient dropped: cloning only
            for group in self.param_groups:
                for parameter in group["params"]:
                    if parameter.grad is not None:
                        parameter.grad.zero_()
        if self.weight > 0:
            rows = self.rng.integers(0, len(self.target), self.batch_size)
            obs = {k: v[rows] for k, v in self.obs.items()}
            if self.normalize is not None:
                obs = self.normalize(obs)
            batch = {k: th.as_tensor(v, dtype=th.float32) for k, v in obs.items()}
            loss = self.weight * th.nn.functional.mse_loss(
                self.actor(batch, deterministic=True), self.target[rows]
            )
            loss.backward()
            self.last_loss = loss.item()
        return super().step(closure)


def add_behaviour_cloning(
    model: Any,
    demos: Any,
    weight: float,
    normalize: Callable[[dict], dict] | None = None,
    seed: int = 0,
    warmup: int = 0,
) -> BehaviourCloningAdam:
    """Give ``model`` (an SB3 SAC) an actor optimizer with a behaviour-cloning term
    (``BehaviourCloningAdam``; the first ``warmup`` actor steps clone only),
    keeping its learning rate and Adam settings."""
    datasets = load_all(demos)
    for dataset in datasets:
        check_spaces(dataset, model.observation_space, model.action_space)
    obs, actions = demo_arrays(datasets)
    old = model.actor.optimizer
    group = old.param_groups[0]
    model.actor.optimizer = BehaviourCloningAdam(
        model.actor.parameters(),
        model.actor,
        obs,
        model.policy.scale_action(actions),
        weight,
        batch_size=model.batch_size,
        normalize=normalize,
        seed=seed,
        warmup=warmup,
        lr=group["lr"],
        betas=group["betas"],
        eps=group["eps"],
        foreach=group.get("foreach"),
    )
    return model.actor.optimizer


def seed_normalization(venv, demos: Any) -> None:
    """Update a ``VecNormalize``'s observation statistics with every recorded
    observation of ``demos``, so that the first batches are normalised sensibly."""
    obs, _ = demo_arrays(demos)
    for key, values in obs.items():
        venv.obs_rms[key].update(values)
