"""Controllers behind one interface, and the one closed-loop rollout of an env.

A `Controller` is a pair of pure functions: `init(key) -> carry` and
`act(carry, observation, info) -> (action, carry)`; the carry holds whatever the controller keeps
between steps (nothing for a trained policy, a key for random actions, a step count for a scripted
sequence, integrator states for a classical controller). `info` is the env state's `info` (time,
task, ...), which classical controllers may read; a policy uses only the observation.

`rollout(env, controller, keys)` runs one episode per key (reset, then `steps` control steps, no
automatic reset) in one jitted, vmapped call and returns the final states and what `record(state)`
picks from the state after every step. Evaluation, benchmarks and tests all use it.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Callable

import jax
import jax.numpy as jnp
from brax.envs.base import Env, State

from marinejax.errors import UserError


@dataclasses.dataclass(frozen=True)
class Controller:
    """init(key) -> carry; act(carry, observation, info) -> (action, carry). Pure and jit/vmap-able;
    actions in the env's action space ([-1, 1] per component)."""

    init: Callable[[jax.Array], Any]
    act: Callable[[Any, jax.Array, dict], tuple[jax.Array, Any]]


def policy_controller(policy: Callable[[jax.Array], jax.Array]) -> Controller:
    """A memoryless policy, observation → action (e.g. a trained PPO policy's deterministic action)."""
    return Controller(init=lambda key: (), act=lambda carry, obs, info: (policy(obs), carry))


def random_controller(action_size: int) -> Controller:
    """Independent uniform actions in [-1, 1], drawn from the key given to `init`."""

    def act(key, obs, info):
        key, sub = jax.random.split(key)
        return jax.random.uniform(sub, (action_size,), minval=-1.0, maxval=1.0), key

    return Controller(init=lambda key: key, act=act)


def sequence_controller(actions: jax.Array) -> Controller:
    """Open loop: `actions` (T, action_size), one per control step (the last one is held after T)."""
    actions = jnp.asarray(actions)
    if actions.ndim != 2:
        raise UserError(f"sequence_controller takes actions of shape (steps, action_size), got {actions.shape}")

    def act(step, obs, info):
        return actions[jnp.minimum(step, actions.shape[0] - 1)], step + 1

    return Controller(init=lambda key: jnp.zeros((), jnp.int32), act=act)


def _no_record(state: State) -> tuple:
    return ()


def run_steps(env: Env, controller: Controller, state: State, carry: Any, steps: int,
              record: Callable[[State], Any] = _no_record) -> tuple[State, Any, Any]:
    """`steps` closed-loop steps from `state` (one env, not batched): returns (final state, final
    carry, record(state) after every step stacked along a leading time axis)."""

    def body(loop, _):
        s, c = loop
        action, c = controller.act(c, s.obs, s.info)
        s = env.step(s, action)
        return (s, c), record(s)

    (state, carry), recorded = jax.lax.scan(body, (state, carry), None, length=steps)
    return state, carry, recorded


def rollout(env: Env, controller: Controller, keys: jax.Array, steps: int | None = None,
            record: Callable[[State], Any] = _no_record) -> tuple[State, Any]:
    """One episode per key (keys (E, 2)): env.reset(key), controller.init(fold_in(key, 1)), then
    `steps` steps (default: the env's episode_length), no automatic reset. Jitted and vmapped over
    the keys; returns (final states, record(state) after every step, shape (E, T, ...))."""
    steps = int(steps if steps is not None else env.config.episode_length)

    def episode(key):
        state = env.reset(key)
        final, _, recorded = run_steps(env, controller, state, controller.init(jax.random.fold_in(key, 1)), steps, record)
        return final, recorded

    return jax.jit(jax.vmap(episode))(keys)
