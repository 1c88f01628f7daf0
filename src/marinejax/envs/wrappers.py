"""Training wrappers: Brax's vmap / episode wrappers with a FULL reset on done.

Brax's AutoResetWrapper restores the cached first state of each env slot, so targets, trajectories,
currents and randomized physics would never change between episodes. `FullResetWrapper` calls the
env's reset with a fresh key instead; `wrap_for_training` is the `wrap_env_fn` to give `ppo.train`.
`FixedEpisodes` marks an evaluation env whose every batched reset starts the same episodes.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable, Optional

import jax
import jax.numpy as jnp
from brax.envs.base import Env, State, Wrapper
from brax.envs.wrappers.training import EpisodeWrapper, VmapWrapper

from marinejax.envs.trace_cache import TraceCache
from marinejax.errors import UserError

# Keys of State.info that describe the transition that just happened, kept through a reset.
_TRANSITION_KEYS = ("truncation", "steps")


def where_done(done: jax.Array, new, old):
    """Per env: `new` where `done` (leading batch axes, bool or 0/1) else `old`, over matching pytrees.
    The one masked selection of an auto-reset (training wrapper and Gymnasium vector env)."""

    def pick(a, b):
        return jnp.where(jnp.reshape(done, done.shape + (1,) * (b.ndim - done.ndim)) > 0, a, b)

    return jax.tree.map(pick, new, old)


class FullResetWrapper(Wrapper):
    """Batched env: where an episode ended, start a new one with `reset` (new randomness)."""

    def reset(self, rng: jax.Array) -> State:
        state = self.env.reset(rng)
        state.info["reset_rng"] = jax.vmap(lambda k: jax.random.fold_in(k, 1))(rng) if rng.ndim > 1 else jax.random.fold_in(rng, 1)
        return state

    def step(self, state: State, action: jax.Array) -> State:
        if "steps" in state.info:
            state.info["steps"] = jnp.where(state.done, jnp.zeros_like(state.info["steps"]), state.info["steps"])
        keys = state.info["reset_rng"]
        split = jax.vmap(jax.random.split)(keys) if keys.ndim > 1 else jax.random.split(keys)
        next_keys, reset_keys = (split[:, 0], split[:, 1]) if keys.ndim > 1 else (split[0], split[1])
        state = state.replace(info={k: v for k, v in state.info.items() if k != "reset_rng"})
        stepped = self.env.step(state, action)
        fresh = self.env.reset(reset_keys)
        done = stepped.done
        info = dict(stepped.info)
        for k, v in fresh.info.items():
            if k not in _TRANSITION_KEYS and k in info:
                info[k] = where_done(done, v, info[k])
        info["reset_rng"] = next_keys
        return stepped.replace(
            pipeline_state=where_done(done, fresh.pipeline_state, stepped.pipeline_state),
            obs=where_done(done, fresh.obs, stepped.obs),
            info=info,
        )


class FixedEpisodes(Wrapper):
    """An env to give `ppo.train` as its `eval_env`: `wrap_for_training` makes its batched resets
    ignore the keys they are given and start the same episodes every time, drawn from `seed`. Brax
    draws new evaluation episodes at each training evaluation; on the same episodes the best of the
    evaluations compares policies, not the episodes' luck."""

    def __init__(self, env: Env, seed: int):
        super().__init__(env)
        self.episodes_seed = int(seed)


class _SameResetKeys(Wrapper):
    """Batched env whose reset replaces its (n, 2) keys by n keys drawn from a fixed seed."""

    def __init__(self, env: Env, seed: int):
        super().__init__(env)
        self._key = jax.random.fold_in(jax.random.PRNGKey(seed), 0x6576616C)

    def reset(self, rng: jax.Array) -> State:
        return self.env.reset(jax.random.split(self._key, rng.shape[0]))


def wrap_for_training(
    env: Env,
    episode_length: int = 1000,
    action_repeat: int = 1,
    randomization_fn: Optional[Callable] = None,
    trace_cache: str | Path | None = None,
) -> Wrapper:
    """Same signature as `brax.envs.training.wrap`, with `FullResetWrapper` instead of AutoReset:
    pass as `ppo.train(..., wrap_env_fn=wrap_for_training)` (an env in `FixedEpisodes` gets the same
    wrappers, its resets keyed by its seed). Randomization is per episode, drawn by
    the env's plant (`randomization.enabled`), so Brax's per-slot `randomization_fn` is refused.

    With `trace_cache` (a folder) the wrapped reset and step are kept there between processes
    (`envs/trace_cache.py`), so that a second run skips tracing them:
    `functools.partial(wrap_for_training, trace_cache=folder)`."""
    if randomization_fn is not None:
        raise UserError(
            "marinejax envs randomize their physics per episode: make the env with "
            "randomization={'enabled': True} instead of passing a Brax randomization_fn"
        )
    fixed = env.episodes_seed if isinstance(env, FixedEpisodes) else None
    env = VmapWrapper(env.env if fixed is not None else env)
    env = EpisodeWrapper(env, episode_length, action_repeat)
    env = FullResetWrapper(env)
    env = env if trace_cache is None else TraceCache(env, trace_cache)
    return env if fixed is None else _SameResetKeys(env, fixed)
