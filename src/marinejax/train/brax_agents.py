"""What the Brax algorithm modules (`ppo`, `sac`) share: saving a checkpoint with the network
config that rebuilds it, and the deterministic policy of saved params."""

from __future__ import annotations

from pathlib import Path
from typing import Callable


def save_checkpoint(checkpoint_module, factory: Callable, path: Path, step: int, params, env, normalize_observations: bool) -> None:
    """`path/<step:012d>` through Brax's `checkpoint_module` (agents.ppo.checkpoint or agents.sac.checkpoint)."""
    net_config = checkpoint_module.network_config(observation_size=env.observation_size, action_size=env.action_size,
                                                  normalize_observations=normalize_observations, network_factory=factory)
    checkpoint_module.save(path, step, params, net_config)


def deterministic_policy(networks_module, factory: Callable, env, params, normalize_observations: bool) -> Callable:
    """observation → action of `params`, the networks built as Brax's train functions build them
    (Brax 0.14's checkpoint.load_policy cannot rebuild networks it saved itself)."""
    import jax
    from brax.training import types
    from brax.training.acme import running_statistics

    normalize = running_statistics.normalize if normalize_observations else types.identity_observation_preprocessor
    network = factory(env.observation_size, env.action_size, preprocess_observations_fn=normalize)
    inference = networks_module.make_inference_fn(network)(params, deterministic=True)
    return lambda obs: inference(obs, jax.random.PRNGKey(0))[0]
