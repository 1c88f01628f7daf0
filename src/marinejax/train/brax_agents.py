"""What the Brax algorithm modules (`ppo`, `sac`) share: saving a checkpoint with the network
config that rebuilds it, and the deterministic policy of saved params."""

from __future__ import annotations

from pathlib import Path
from typing import Callable


def save_checkpoint(checkpoint_module, factory: Callable, path: Path, step: int, params, env, normalize_observations: bool,
                    config_file: str) -> None:
    """`path/<step:012d>` through Brax's `checkpoint_module` (agents.ppo.checkpoint or
    agents.sac.checkpoint), its network config in `config_file`; with several processes, the same
    layout written by this process alone (`_save_alone`)."""
    import jax

    net_config = checkpoint_module.network_config(observation_size=env.observation_size, action_size=env.action_size,
                                                  normalize_observations=normalize_observations, network_factory=factory)
    if jax.process_count() == 1:
        checkpoint_module.save(path, step, params, net_config)
    else:
        _save_alone(Path(path) / f"{step:012d}", params, net_config, config_file)


def _save_alone(directory: Path, params, net_config, config_file: str) -> None:
    """What Brax's checkpoint save writes, written by this process only: Brax saves from process 0
    alone, and orbax's save as Brax calls it waits for every process. The arrays go as NumPy's
    (orbax refuses process-local jax arrays among several processes), Brax's UInt64 count as the
    {hi, lo} its load rebuilds it from (UInt64 turns NumPy back into jax arrays)."""
    import jax
    import numpy as np
    import orbax.checkpoint as ocp
    from brax.training.types import UInt64
    from flax.training import orbax_utils
    from ml_collections import config_dict

    params = jax.tree.map(lambda x: {"hi": np.asarray(x.hi), "lo": np.asarray(x.lo)} if isinstance(x, UInt64) else np.asarray(x),
                          params, is_leaf=lambda x: isinstance(x, UInt64))
    directory.mkdir(parents=True, exist_ok=True)
    alone = ocp.options.MultiprocessingOptions(primary_host=jax.process_index(), active_processes={jax.process_index()})
    checkpointer = ocp.Checkpointer(ocp.PyTreeCheckpointHandler(multiprocessing_options=alone), multiprocessing_options=alone)
    checkpointer.save(directory, params, force=True, save_args=orbax_utils.save_args_from_target(params))
    config = net_config.to_dict()  # functions (activation, initializers) by their registered names, as Brax writes them
    config["network_factory_kwargs"] = {k: v.__name__ if callable(v) else v for k, v in config["network_factory_kwargs"].items()}
    (directory / config_file).write_text(config_dict.ConfigDict(config).to_json_best_effort())


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
