"""stable-baselines3's SAC with a cheaper gradient step: the same arithmetic, bit for bit.

    from franka_sim_gym.envs.sb3_sac import LeanSAC
    model = LeanSAC("MultiInputPolicy", env, ...)   # every argument of SAC

Why: at the sizes a reach policy uses (two 128-unit layers, batches of 256) an SB3 SAC
gradient step is mostly calls, not arithmetic: each of its ~600 torch operations costs a
few microseconds of dispatch, and ``examples/train_sb3.py`` takes one step per sample.
``LeanSAC.train`` does the step of ``SAC.train`` with fewer of them:

* the observation features are built once per batch and shared by the actor, the
  critic and the target critic (SB3 builds them five times). This needs SB3's own
  flattening extractors without parameters (the default ``FlattenExtractor``, and
  ``CombinedExtractor`` over vectors), for which every copy is the same tensor;
* the critic's parameters are frozen while the actor's loss goes through it: SB3
  computes their gradients there and then discards them (the critic's optimizer
  zeroes them before its next use);
* the target networks' Polyak update is one ``_foreach`` multiply and one add over all
  tensors, the operations of SB3's ``polyak_update`` in its order;
* the losses are logged from tensors collected over the steps, not with one
  ``.item()`` per loss and step;
* torch.distributions' argument validation is off during the step (it checks that the
  policy's mean is finite and its std positive at every sample; the losses' values do
  not depend on it).

Nothing else changes: the same replay samples, random draws and floating-point
operations in the same order, so the parameters after training are SB3's exactly
(``tests/training/test_sb3_sac.py`` compares them). Models save and load as SB3 SAC models
(``SAC.load`` reads them). Configurations outside the above (gSDE, a target update
interval other than 1, batch-norm statistics, other feature extractors) take SB3's
own ``SAC.train``.
"""

from __future__ import annotations

import numpy as np
import torch as th
import torch.nn.functional as F
from stable_baselines3 import SAC
from stable_baselines3.common.torch_layers import CombinedExtractor, FlattenExtractor
from stable_baselines3.sac.policies import LOG_STD_MAX, LOG_STD_MIN


def _plain_extractor(module: th.nn.Module) -> bool:
    """SB3's own flattening extractors without parameters: each call on a batch returns
    the same tensor (a subclass, or one with parameters, may not)."""
    return (
        type(module) in (FlattenExtractor, CombinedExtractor)
        and next(module.parameters(), None) is None
    )


class LeanSAC(SAC):
    """SB3's ``SAC`` whose ``train`` takes the same gradient steps with fewer torch calls.

    Takes every argument of ``SAC``. See the module's docstring for what is shared,
    frozen and fused, and when it falls back to ``SAC.train``.
    """

    def lean_step_applies(self) -> bool:
        """Whether ``train`` takes the lean step (else SB3's own ``SAC.train``)."""
        extractors = (
            self.actor.features_extractor,
            self.critic.features_extractor,
            self.critic_target.features_extractor,
        )
        return (
            not self.use_sde
            and self.target_update_interval == 1
            and not self.batch_norm_stats
            and all(_plain_extractor(e) for e in extractors)
            and len({type(e) for e in extractors}) == 1
        )

    def train(self, gradient_steps: int, batch_size: int = 64) -> None:
        if not self.lean_step_applies():
            super().train(gradient_steps, batch_size)
            return
        validate = th.distributions.Distribution._validate_args
        th.distributions.Distribution.set_default_validate_args(False)
        try:
            self._lean_train(gradient_steps, batch_size)
        finally:
            th.distributions.Distribution.set_default_validate_args(validate)

    def _lean_train(self, gradient_steps: int, batch_size: int) -> None:
        self.policy.set_training_mode(True)
        optimizers = [self.actor.optimizer, self.critic.optimizer]
        if self.ent_coef_optimizer is not None:
            optimizers += [self.ent_coef_optimizer]
        self._update_learning_rate(optimizers)

        actor, critic, target = self.actor, self.critic, self.critic_target
        critic_params = list(critic.parameters())
        target_params = list(target.parameters())

        def features(obs):
            return actor.extract_features(obs, actor.features_extractor)

        def pi(feats):  # Actor.action_log_prob after its features
            latent = actor.latent_pi(feats)
            mean = actor.mu(latent)
            log_std = th.clamp(actor.log_std(latent), LOG_STD_MIN, LOG_STD_MAX)
            return actor.action_dist.log_prob_from_params(mean, log_std)

        def q(networks, feats, actions):  # ContinuousCritic.forward after its features
            x = th.cat([feats, actions], dim=1)
            return [net(x) for net in networks]

        ent_coef_losses, ent_coefs, actor_losses, critic_losses = [], [], [], []
        for _ in range(gradient_steps):
            data = self.replay_buffer.sample(batch_size, env=self._vec_normalize_env)
            # n-step replay buffers carry their own discounts (absent in older SB3)
            discounts = getattr(data, "discounts", None)
            discounts = self.gamma if discounts is None else discounts
            obs_features = features(data.observations)

            actions_pi, log_prob = pi(obs_features)
            log_prob = log_prob.reshape(-1, 1)

            if self.ent_coef_optimizer is not None and self.log_ent_coef is not None:
                ent_coef = th.exp(self.log_ent_coef.detach())  # (before the step below)
                ent_coef_loss = -(
                    self.log_ent_coef * (log_prob + self.target_entropy).detach()
                ).mean()
                ent_coef_losses.append(ent_coef_loss.detach())
                self.ent_coef_optimizer.zero_grad()
                ent_coef_loss.backward()
                self.ent_coef_optimizer.step()
            else:
                ent_coef = self.ent_coef_tensor
            ent_coefs.append(ent_coef)

            with th.no_grad():
                next_features = features(data.next_observations)
                next_actions, next_log_prob = pi(next_features)
                next_q = th.cat(q(target.q_networks, next_features, next_actions), dim=1)
                next_q, _ = th.min(next_q, dim=1, keepdim=True)
                next_q = next_q - ent_coef * next_log_prob.reshape(-1, 1)
                target_q = data.rewards + (1 - data.dones) * discounts * next_q

            current_q = q(critic.q_networks, obs_features, data.actions)
            critic_loss = 0.5 * sum(F.mse_loss(c, target_q) for c in current_q)
            critic_losses.append(critic_loss.detach())
            critic.optimizer.zero_grad()
            critic_loss.backward()
            critic.optimizer.step()

            # The actor's loss differentiates through the critic, not into it.
            for p in critic_params:
                p.requires_grad_(False)
            try:
                q_pi = th.cat(q(critic.q_networks, obs_features, actions_pi), dim=1)
            finally:
                for p in critic_params:
                    p.requires_grad_(True)
            min_q_pi, _ = th.min(q_pi, dim=1, keepdim=True)
            actor_loss = (ent_coef * log_prob - min_q_pi).mean()
            actor_losses.append(actor_loss.detach())
            actor.optimizer.zero_grad()
            actor_loss.backward()
            actor.optimizer.step()

            with th.no_grad():  # polyak_update's mul_ then add, over every tensor at once
                th._foreach_mul_(target_params, 1 - self.tau)
                th._foreach_add_(target_params, critic_params, alpha=self.tau)

        self._n_updates += gradient_steps
        # SB3 logs the mean of the losses as Python floats: the same numbers.
        self.logger.record("train/n_updates", self._n_updates, exclude="tensorboard")
        self.logger.record("train/ent_coef", np.mean(th.stack(ent_coefs).tolist()))
        self.logger.record("train/actor_loss", np.mean(th.stack(actor_losses).tolist()))
        self.logger.record("train/critic_loss", np.mean(th.stack(critic_losses).tolist()))
        if ent_coef_losses:
            self.logger.record("train/ent_coef_loss", np.mean(th.stack(ent_coef_losses).tolist()))
