"""PPO (Brax's `brax.training.agents.ppo`): its settings, networks, training call, checkpoints and
deterministic policy. Every algorithm module (`ppo`, `sac`) has the same names:

  Config                     frozen dataclass of the algorithm's settings (num_timesteps, num_envs, seed, ...)
  NETWORK_CONFIG             file name of the network config inside a checkpoint directory
  network_factory(config, observation_size)
  run(env, config, **common) Brax's train function with our settings (`runner.train` passes `common`)
  save(path, step, params, env, config) / load(path)
  policy(config, env, params) deterministic policy fn observation → action in [−1, 1]
"""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path
from typing import Any, Callable, Mapping

from marinejax.errors import UserError
from marinejax.train.brax_agents import deterministic_policy, save_checkpoint

NETWORK_CONFIG = "ppo_network_config.json"
# Brax's learning-rate schedules: "none" (constant `learning_rate`) or "adaptive_kl" (after every
# update epoch the rate is divided by 1.5 where the policy's mean KL divergence exceeded 2 ×
# `desired_kl` and multiplied by 1.5 where it fell under half of it, within 1e-5–1e-2; the schedule
# of rsl_rl's legged-robot PPO).
LEARNING_RATE_SCHEDULES = ("none", "adaptive_kl")


@dataclasses.dataclass(frozen=True)
class Config:
    """Arguments of `brax.training.agents.ppo.train` (see its docstring), plus network sizes."""

    num_timesteps: int = 3_000_000
    num_envs: int = 256
    unroll_length: int = 20
    batch_size: int = 256
    num_minibatches: int = 8
    num_updates_per_batch: int = 4
    learning_rate: float = 3e-4  # the initial rate with "adaptive_kl"
    learning_rate_schedule: str = "none"  # LEARNING_RATE_SCHEDULES
    desired_kl: float = 0.01  # the KL divergence "adaptive_kl" aims at, per update
    entropy_cost: float = 1e-3
    discounting: float = 0.97
    gae_lambda: float = 0.95
    clipping_epsilon: float = 0.2
    reward_scaling: float = 1.0
    max_grad_norm: float = 1.0
    normalize_observations: bool = True
    init_noise_std: float = 1.0  # initial exploration noise of the policy (pre-tanh std)
    policy_hidden: tuple[int, ...] = dataclasses.field(default=(64, 64), metadata={"variable_length": True})
    value_hidden: tuple[int, ...] = dataclasses.field(default=(64, 64), metadata={"variable_length": True})
    num_evals: int = 20
    num_eval_envs: int = 64
    seed: int = 0

    def __post_init__(self):
        for name in ("num_timesteps", "num_envs", "unroll_length", "batch_size", "num_minibatches",
                     "num_updates_per_batch", "num_evals", "num_eval_envs"):
            if getattr(self, name) < 1:
                raise UserError(f"ppo '{name}' must be >= 1, got {getattr(self, name)}")
        if (self.batch_size * self.num_minibatches) % self.num_envs:
            raise UserError(
                f"ppo batch_size * num_minibatches ({self.batch_size} * {self.num_minibatches}) must be a "
                f"multiple of num_envs ({self.num_envs})"
            )
        for name in ("learning_rate", "discounting", "gae_lambda", "clipping_epsilon", "reward_scaling"):
            if not getattr(self, name) > 0:
                raise UserError(f"ppo '{name}' must be > 0, got {getattr(self, name)}")
        if self.learning_rate_schedule not in LEARNING_RATE_SCHEDULES:
            raise UserError(f"ppo 'learning_rate_schedule' must be one of {list(LEARNING_RATE_SCHEDULES)}, "
                            f"got {self.learning_rate_schedule!r}")
        if not self.desired_kl > 0:
            raise UserError(f"ppo 'desired_kl' must be > 0, got {self.desired_kl}")
        if not (self.discounting < 1 and self.gae_lambda <= 1):
            raise UserError(f"ppo 'discounting' must be < 1 and 'gae_lambda' <= 1, got {self.discounting}, {self.gae_lambda}")

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "Config":
        """The config as config.json records it (lists for the tuples)."""
        return cls(**{**data, "policy_hidden": tuple(data["policy_hidden"]), "value_hidden": tuple(data["value_hidden"])})


def network_factory(config: Config, observation_size: int | Mapping | None = None) -> Callable:
    """Brax's PPO networks with our sizes; for a dict observation size (`privileged_observation`)
    the policy reads "state" and the critic "privileged_state"."""
    from brax.training.agents.ppo import networks as ppo_networks

    keys = {"policy_obs_key": "state", "value_obs_key": "privileged_state"} if isinstance(observation_size, Mapping) else {}
    return functools.partial(
        ppo_networks.make_ppo_networks,
        policy_hidden_layer_sizes=tuple(config.policy_hidden),
        value_hidden_layer_sizes=tuple(config.value_hidden),
        init_noise_std=config.init_noise_std,
        **keys,
    )


def run(env, config: Config, *, num_timesteps: int, seed: int, wrap_env_fn, progress_fn, save_fn, restore: Path | None,
        devices: int, checkpoint_dir: Path) -> None:
    """Brax PPO on `env`; `save_fn(step, params)` after every evaluation (step counted from this call's start)."""
    from brax.training.agents.ppo import train as ppo_train

    ppo_train.train(
        environment=env,
        num_timesteps=num_timesteps,
        episode_length=env.config.episode_length,
        wrap_env_fn=wrap_env_fn,
        num_envs=config.num_envs,
        unroll_length=config.unroll_length,
        batch_size=config.batch_size,
        num_minibatches=config.num_minibatches,
        num_updates_per_batch=config.num_updates_per_batch,
        learning_rate=config.learning_rate,
        learning_rate_schedule=config.learning_rate_schedule.upper(),
        desired_kl=config.desired_kl,
        entropy_cost=config.entropy_cost,
        discounting=config.discounting,
        gae_lambda=config.gae_lambda,
        clipping_epsilon=config.clipping_epsilon,
        reward_scaling=config.reward_scaling,
        max_grad_norm=config.max_grad_norm,
        normalize_observations=config.normalize_observations,
        network_factory=network_factory(config, env.observation_size),
        num_evals=config.num_evals,
        num_eval_envs=config.num_eval_envs,
        deterministic_eval=True,
        seed=seed,
        restore_checkpoint_path=str(restore) if restore else None,
        progress_fn=progress_fn,
        policy_params_fn=lambda step, make_policy, params: save_fn(step, params) if step > 0 else None,
        max_devices_per_host=devices,
    )


def save(path: Path, step: int, params, env, config: Config) -> None:
    """A Brax PPO checkpoint `path/<step:012d>` (normalizer, policy, value params + network config)."""
    from brax.training.agents.ppo import checkpoint

    save_checkpoint(checkpoint, network_factory(config, env.observation_size), path, step, params, env, config.normalize_observations,
                    NETWORK_CONFIG)


def load(path: Path):
    """The params (normalizer, policy, value) of a checkpoint directory."""
    from brax.training.agents.ppo import checkpoint as ppo_checkpoint

    return ppo_checkpoint.load(path)


def policy(config: Config, env, params) -> Callable:
    """The deterministic policy (observation → action) of `params`."""
    from brax.training.agents.ppo import networks

    return deterministic_policy(networks, network_factory(config, env.observation_size), env, params, config.normalize_observations)
