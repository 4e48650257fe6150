"""LeanSAC (envs/sb3_sac.py): SB3's SAC gradient step with fewer torch calls, the same bits."""

from __future__ import annotations

import numpy as np
import pytest

sb3 = pytest.importorskip("stable_baselines3")
import torch as th  # noqa: E402
from stable_baselines3 import SAC  # noqa: E402
from stable_baselines3.common.torch_layers import CombinedExtractor  # noqa: E402

from franka_sim_gym.envs.sb3_her import ReflexChargedHerReplayBuffer  # noqa: E402
from franka_sim_gym.envs.sb3_sac import LeanSAC  # noqa: E402
from franka_sim_gym.envs.sb3_vec_env import FrankaFCISB3VecEnv  # noqa: E402


def trained(algo, steps: int = 160, callback=None, **kwargs) -> SAC:
    """``algo`` trained like examples/train_sb3.py's default, small: HER on the batched
    env, one gradient step per sample, learning from step 40 (the collection then
    follows the policy, so any difference in training shows in the samples too)."""
    env = FrankaFCISB3VecEnv(
        4, action_interface="cartesian_velocity", cartesian_dof=3, policy_hz=25, max_episode_steps=8
    )
    options = dict(
        replay_buffer_class=ReflexChargedHerReplayBuffer,
        replay_buffer_kwargs=dict(n_sampled_goal=4, goal_selection_strategy="future"),
        learning_starts=40,
        buffer_size=steps + 8,
        batch_size=32,
        gradient_steps=4,
        learning_rate=1e-3,
        tau=0.05,
        gamma=0.95,
        ent_coef="auto_0.02",
        policy_kwargs=dict(net_arch=[32, 32], optimizer_kwargs=dict(foreach=True)),
        seed=5,
    )
    model = algo("MultiInputPolicy", env, **{**options, **kwargs})
    model.learn(total_timesteps=steps, callback=callback)
    return model


def state(model: SAC) -> dict[str, th.Tensor]:
    """Every learnt number: the policy (actor, critic, target critic), the entropy
    weight and the optimizers' moments."""
    out = {f"policy.{k}": v for k, v in model.policy.state_dict().items()}
    if model.log_ent_coef is not None:
        out["log_ent_coef"] = model.log_ent_coef.detach()
    optimizers = {"actor": model.actor.optimizer, "critic": model.critic.optimizer}
    if model.ent_coef_optimizer is not None:
        optimizers["ent_coef"] = model.ent_coef_optimizer
    for name, optimizer in optimizers.items():
        for i, moments in optimizer.state_dict()["state"].items():
            for k, v in moments.items():
                out[f"{name}.{i}.{k}"] = th.as_tensor(v)
    return out


def assert_same_bits(a: SAC, b: SAC) -> None:
    sa, sb = state(a), state(b)
    assert sa.keys() == sb.keys()
    differ = [k for k in sa if not th.equal(sa[k], sb[k])]
    assert not differ, f"differ from SB3's SAC: {differ}"


@pytest.mark.parametrize("ent_coef", ["auto_0.02", 0.05])
def test_lean_training_is_sb3s_bit_for_bit(ent_coef):
    sb3_model = trained(SAC, ent_coef=ent_coef)
    lean = trained(LeanSAC, ent_coef=ent_coef)
    assert lean.lean_step_applies()
    assert lean._n_updates == sb3_model._n_updates == 120  # (160 - 40) samples, one step each
    assert_same_bits(lean, sb3_model)
    # the logged means are SB3's numbers too
    for key in ("train/ent_coef", "train/actor_loss", "train/critic_loss", "train/ent_coef_loss"):
        assert lean.logger.name_to_value.get(key) == sb3_model.logger.name_to_value.get(key), key


def test_the_step_leaves_torch_as_it_found_it():
    """The critic is frozen only within the actor's loss, and torch.distributions'
    validation is back to what it was."""
    before = th.distributions.Distribution._validate_args
    model = trained(LeanSAC, steps=60)
    assert th.distributions.Distribution._validate_args == before
    assert all(p.requires_grad for p in model.critic.parameters())
    assert all(p.requires_grad for p in model.actor.parameters())


class TaggedExtractor(CombinedExtractor):
    """A user's extractor: LeanSAC cannot know that its calls agree."""


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(use_sde=True),
        dict(target_update_interval=2),
        dict(policy_kwargs=dict(net_arch=[32, 32], features_extractor_class=TaggedExtractor)),
    ],
)
def test_other_configurations_take_sb3s_own_step(kwargs):
    lean = trained(LeanSAC, steps=60, **kwargs)
    assert not lean.lean_step_applies()
    assert_same_bits(lean, trained(SAC, steps=60, **kwargs))


def test_a_lean_model_loads_as_an_sb3_sac(tmp_path):
    lean = trained(LeanSAC, steps=60)
    lean.save(tmp_path / "model.zip")
    loaded = SAC.load(tmp_path / "model.zip", env=lean.env)
    obs = lean.env.reset()
    a, _ = lean.predict(obs, deterministic=True)
    b, _ = loaded.predict(obs, deterministic=True)
    assert np.array_equal(a, b)
