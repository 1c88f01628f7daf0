"""Registered RL tasks: station keeping and circle, helix and lemniscate tracking, per vehicle.

    env = marinejax.make("BlueROV2Heavy-StationKeeping", current={"mode": "constant"})
    state = jax.jit(env.reset)(jax.random.PRNGKey(0))
"""

from marinejax.envs.base import EnvConfig, MarineEnv, ResetConfig, RewardConfig
from marinejax.envs.current import CurrentConfig
from marinejax.envs.randomization import RandomizationConfig, brax_randomization_fn
from marinejax.envs.registry import get_default_config, list_envs, make, register_with_brax
from marinejax.envs.wrappers import wrap_for_training

register_with_brax()

__all__ = [
    "CurrentConfig",
    "EnvConfig",
    "MarineEnv",
    "RandomizationConfig",
    "ResetConfig",
    "RewardConfig",
    "brax_randomization_fn",
    "get_default_config",
    "list_envs",
    "make",
    "wrap_for_training",
]
