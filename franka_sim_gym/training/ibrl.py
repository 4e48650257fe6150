"""SAC that keeps a fitted imitation policy in the loop: Imitation Bootstrapped RL.

    from franka_sim_gym.training.ibrl import ImitationBootstrappedSAC
    model = ImitationBootstrappedSAC("MultiInputPolicy", env, ...)
    model.imitation = clone            # anything with SB3's predict: train_bc.py's run
    model.learn(100_000)

SAC moved off a behaviour-cloned actor as soon as its critics' gradients reached it, on
Push from 0.5-0.8 success to 0.06 (docs/demonstrations.md, "SAC after the cloning"):
critics that have not yet learnt what the clone's actions are worth pull the actor
anywhere. Hu, Mirchandani and Sadigh (2023), "Imitation Bootstrapped Reinforcement
Learning", keep the imitation policy beside the actor instead of starting the actor
from it: at every state both propose an action and the critics choose.

- **Acting** (rollouts and ``predict``): the actor's action (sampled, or its mean when
  ``deterministic``) and the imitation policy's (deterministic); the one the critics
  value higher (the minimum of the twin critics) is taken, arm by arm.
- **Bootstrapping**: the target of a transition is its reward plus the discounted value
  of the better of the two proposals at the next state: the actor's (less SAC's
  entropy term) or the imitation policy's, each valued by the target critics' minimum.
  The critics thus learn the value of following the imitation policy from the first
  step, and the actor's gradient is SAC's own.

The imitation policy is fixed (never trained here) and not saved with the model:
``examples/train_sb3.py --imitation RUN`` records its run folder in
``train_config.json``, and ``examples/evaluate.py`` attaches it again on loading. Without
one (``imitation`` None) this is SAC. Its update is SAC's (tests/training/test_ibrl.py
checks one step bit for bit) for what train_sb3.py runs: a constant learning rate,
one-step returns, no gSDE (``--sde`` is refused with ``--imitation``); it logs the
actor and critic losses and the entropy weight, not SAC's update count.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch as th
from stable_baselines3 import SAC
from stable_baselines3.common.utils import polyak_update


def lowest(critic, observations, actions: th.Tensor) -> th.Tensor:
    """(n,) the minimum over SAC's twin critics (or their targets) of Q(s, a), for
    actions in the policy's scaled units: SAC's guard against overestimation."""
    return th.min(th.cat(critic(observations, actions), dim=1), dim=1).values


class ImitationBootstrappedSAC(SAC):
    """SB3's SAC with IBRL's acting and bootstrapping (module docstring); ``imitation``
    is set after construction (and after ``load``)."""

    imitation: Any = None

    def _excluded_save_params(self) -> list[str]:
        # the imitation policy is another run's (train_config.json names it)
        return [*super()._excluded_save_params(), "imitation"]

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = False,
    ) -> tuple[np.ndarray, Any]:
        """The better-valued of the actor's and the imitation policy's actions, per arm
        (the actor's alone without an imitation policy)."""
        actions, state = super().predict(observation, state, episode_start, deterministic)
        if self.imitation is None:
            return actions, state
        proposed, _ = self.imitation.predict(observation, deterministic=True)
        proposed = np.asarray(proposed, dtype=actions.dtype).reshape(actions.shape)
        obs, vectorized = self.policy.obs_to_tensor(observation)
        batch = actions.reshape(-1, *self.action_space.shape)
        candidates = (batch, proposed.reshape(batch.shape))
        with th.no_grad():
            own, imitated = (self._value(self.critic, obs, a) for a in candidates)
        take = (imitated > own).cpu().numpy().reshape(-1)
        chosen = np.where(take[:, None], candidates[1], candidates[0])
        return (chosen if vectorized else chosen[0]).astype(actions.dtype), state

    def _value(self, critic, obs, actions: np.ndarray) -> th.Tensor:
        """The twin critics' minimum for env-unit ``actions``."""
        scaled = th.as_tensor(self.policy.scale_action(actions), device=self.device)
        return lowest(critic, obs, scaled.float())

    def _imitated(self, observations: dict[str, th.Tensor]) -> th.Tensor:
        """The imitation policy's actions for a batch of tensor observations, scaled."""
        arrays = {k: v.cpu().numpy() for k, v in observations.items()}
        actions, _ = self.imitation.predict(arrays, deterministic=True)
        scaled = self.policy.scale_action(np.asarray(actions, dtype=np.float32))
        return th.as_tensor(scaled, dtype=th.float32, device=self.device)

    def next_value(self, observations: dict[str, th.Tensor], ent_coef: th.Tensor) -> th.Tensor:
        """(n,) what a transition into ``observations`` bootstraps from: the better of the
        actor's proposal (sampled; its target-critic value less ``ent_coef`` times its
        log-probability, as SAC's) and the imitation policy's (its target-critic value)."""
        actions, log_prob = self.actor.action_log_prob(observations)
        own = lowest(self.critic_target, observations, actions)
        own = own - ent_coef.reshape(()) * log_prob.reshape(-1)
        theirs = lowest(self.critic_target, observations, self._imitated(observations))
        return th.maximum(own, theirs)

    def train(self, gradient_steps: int, batch_size: int = 64) -> None:
        """SAC's update with IBRL's target (module docstring)."""
        if self.imitation is None:
            return super().train(gradient_steps, batch_size)
        self.policy.set_training_mode(True)
        losses: dict[str, list[float]] = {"actor": [], "critic": [], "ent_coef": []}
        for step in range(gradient_steps):
            data = self.replay_buffer.sample(batch_size, env=self.get_vec_normalize_env())
            actions_pi, log_prob = self.actor.action_log_prob(data.observations)
            log_prob = log_prob.reshape(-1, 1)
            if self.ent_coef_optimizer is not None:  # the temperature, as SAC tunes it
                ent_coef = th.exp(self.log_ent_coef.detach())
                ent_loss = -(self.log_ent_coef * (log_prob + self.target_entropy).detach())
                self.ent_coef_optimizer.zero_grad()
                ent_loss.mean().backward()
                self.ent_coef_optimizer.step()
            else:
                ent_coef = self.ent_coef_tensor
            with th.no_grad():
                best = self.next_value(data.next_observations, ent_coef).reshape(-1, 1)
                target = data.rewards + (1 - data.dones) * self.gamma * best
            current = self.critic(data.observations, data.actions)
            critic_loss = 0.5 * sum(th.nn.functional.mse_loss(q, target) for q in current)
            self.critic.optimizer.zero_grad()
            critic_loss.backward()
            self.critic.optimizer.step()
            q_actor = lowest(self.critic, data.observations, actions_pi).reshape(-1, 1)
            actor_loss = (ent_coef * log_prob - q_actor).mean()
            self.actor.optimizer.zero_grad()
            actor_loss.backward()
            self.actor.optimizer.step()
            if step % self.target_update_interval == 0:
                polyak_update(self.critic.parameters(), self.critic_target.parameters(), self.tau)
                polyak_update(self.batch_norm_stats, self.batch_norm_stats_target, 1.0)
            losses["actor"].append(actor_loss.item())
            losses["critic"].append(critic_loss.item())
            losses["ent_coef"].append(float(ent_coef.reshape(())))
        for name, values in losses.items():
            self.logger.record(f"train/{name}" + ("" if name == "ent_coef" else "_loss"),
                               float(np.mean(values)))  # fmt: skip
