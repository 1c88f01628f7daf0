"""SAC (Brax's `brax.training.agents.sac`): its settings, networks, training call, checkpoints and
deterministic policy, with the same names as `ppo` (see there).

Off-policy: `num_envs` envs step together, each step's transitions go to a replay buffer, and
`grad_updates_per_step` gradient steps of `batch_size` transitions follow. Brax SAC checkpoints hold
the policy and the observation statistics only, and Brax 0.14 cannot restore them into a training
(its restored parameters are not replicated over devices): a SAC run cannot be resumed.
"""

from __future__ import annotations

import dataclasses
import functools
import shutil
from pathlib import Path
from typing import Any, Callable, Mapping

from marinejax.errors import UserError
from marinejax.train.brax_agents import deterministic_policy, save_checkpoint
from marinejax.train.curves import BEST_ON

NETWORK_CONFIG = "sac_network_config.json"


@dataclasses.dataclass(frozen=True)
class Config:
    """Arguments of `brax.training.agents.sac.train` (see its docstring), plus network sizes (the
    policy and both critics have `hidden` layers; swish activations, as the PPO networks)."""

    num_timesteps: int = 1_000_000
    num_envs: int = 64
    batch_size: int = 256
    grad_updates_per_step: int = 8
    learning_rate: float = 1e-3
    discounting: float = 0.98
    reward_scaling: float = 1.0
    tau: float = 0.005  # target networks' soft-update rate
    min_replay_size: int = 8192  # transitions collected with the initial policy before learning starts
    max_replay_size: int = 1_000_000
    normalize_observations: bool = True
    hidden: tuple[int, ...] = dataclasses.field(default=(128, 128), metadata={"variable_length": True})
    num_evals: int = 10
    num_eval_envs: int = 64
    seed: int = 0
    cpu_devices: int = 1  # on a CPU-only host, the JAX devices its cores are split into (as PPO's)
    best_on: str = "window_error"  # what the best checkpoint is chosen on (as PPO's)

    def __post_init__(self):
        for name in ("num_timesteps", "num_envs", "batch_size", "grad_updates_per_step", "max_replay_size", "num_evals",
                     "num_eval_envs", "cpu_devices"):
            if getattr(self, name) < 1:
                raise UserError(f"sac '{name}' must be >= 1, got {getattr(self, name)}")
        for name in ("learning_rate", "discounting", "reward_scaling", "tau"):
            if not getattr(self, name) > 0:
                raise UserError(f"sac '{name}' must be > 0, got {getattr(self, name)}")
        if self.best_on not in BEST_ON:
            raise UserError(f"sac 'best_on' must be one of {list(BEST_ON)}, got {self.best_on!r}")
        if not (self.discounting < 1 and self.tau <= 1):
            raise UserError(f"sac 'discounting' must be < 1 and 'tau' <= 1, got {self.discounting}, {self.tau}")
        if not 0 <= self.min_replay_size < min(self.num_timesteps, self.max_replay_size):
            raise UserError(f"sac 'min_replay_size' must be >= 0 and below num_timesteps ({self.num_timesteps}) and "
                            f"max_replay_size ({self.max_replay_size}), got {self.min_replay_size}")

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> "Config":
        """The config as config.json records it (a list for the tuple)."""
        return cls(**{**data, "hidden": tuple(data["hidden"])})


def network_factory(config: Config, observation_size: int | Mapping | None = None) -> Callable:
    """Brax's SAC networks with our sizes."""
    from brax.training.agents.sac import networks as sac_networks
    from flax import linen

    if isinstance(observation_size, Mapping):
        raise UserError("SAC trains on the flat 'state' observation only; set privileged_observation=false")
    return functools.partial(sac_networks.make_sac_networks, hidden_layer_sizes=tuple(config.hidden), activation=linen.swish)


def run(env, config: Config, *, num_timesteps: int, seed: int, wrap_env_fn, progress_fn, save_fn, restore: Path | None,
        devices: int, checkpoint_dir: Path) -> None:
    """Brax SAC on `env`; `save_fn(step, params)` after every evaluation (step counted from this call's start)."""
    from brax.training.agents.sac import train as sac_train

    factory = network_factory(config, env.observation_size)
    # Brax SAC writes its checkpoints itself, numbered from this call's start: they are staged here
    # and handed to `save_fn`, which names them by the run's total step count.
    staging = Path(checkpoint_dir) / "incoming"

    def progress(step: int, metrics) -> None:
        staged = staging / f"{int(step):012d}"
        if step > 0 and staged.exists():
            save_fn(step, load(staged))
            shutil.rmtree(staged)
        progress_fn(step, metrics)

    try:
        sac_train.train(
            environment=env,
            num_timesteps=num_timesteps,
            episode_length=env.config.episode_length,
            wrap_env_fn=wrap_env_fn,
            num_envs=config.num_envs,
            num_eval_envs=config.num_eval_envs,
            learning_rate=config.learning_rate,
            discounting=config.discounting,
            seed=seed,
            batch_size=config.batch_size,
            num_evals=config.num_evals,
            normalize_observations=config.normalize_observations,
            max_devices_per_host=devices,
            reward_scaling=config.reward_scaling,
            tau=config.tau,
            min_replay_size=config.min_replay_size,
            max_replay_size=config.max_replay_size,
            grad_updates_per_step=config.grad_updates_per_step,
            deterministic_eval=True,
            network_factory=factory,
            progress_fn=progress,
            checkpoint_logdir=str(staging),
        )
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def save(path: Path, step: int, params, env, config: Config) -> None:
    """A Brax SAC checkpoint `path/<step:012d>` (normalizer and policy params + network config)."""
    from brax.training.agents.sac import checkpoint

    save_checkpoint(checkpoint, network_factory(config, env.observation_size), path, step, params, env, config.normalize_observations,
                    NETWORK_CONFIG)


def load(path: Path):
    """The params (normalizer, policy) of a checkpoint directory."""
    from brax.training.agents.sac import checkpoint as sac_checkpoint

    return sac_checkpoint.load(path)


def policy(config: Config, env, params) -> Callable:
    """The deterministic policy (observation → action) of `params`: tanh of the mean."""
    from brax.training.agents.sac import networks

    return deterministic_policy(networks, network_factory(config, env.observation_size), env, params, config.normalize_observations)
