"""Gymnasium adapters: every registered env as a `gymnasium.Env` and as a batched `gymnasium.vector.VectorEnv`.

    import gymnasium, marinejax
    env = gymnasium.make("marinejax/BlueROV2Heavy-StationKeeping-v0", episode_length=400)
    envs = gymnasium.make_vec("marinejax/BlueROV2Heavy-StationKeeping-v0", num_envs=64)

`gymnasium.make("marinejax:marinejax/<env>-v0")` (module prefix) imports marinejax itself, for code
that cannot import it first (the ids are registered when marinejax is imported).

Keyword arguments other than `render_mode`, `render_width`, `render_height` (and `num_envs`,
`autoreset_mode` for the vector env) are config overrides for `marinejax.envs.make`; an unknown one
raises TypeError, as an unexpected keyword argument does (clients such as TorchRL's `GymEnv` and
SB3's `make_vec_env` try optional keywords and fall back on TypeError). Both adapters take and
return numpy arrays: observations float32, actions float32 in [-1, 1] (the env clips).

Rendering: `render_mode="rgb_array"` makes `render()` return the 'chase' camera's view, (480, 640, 3)
uint8 by default (`render_width`, `render_height`), with the target as a red sphere; the vector env
returns a tuple with one frame per env. MuJoCo renders offscreen; on a machine without a display
start Python with MUJOCO_GL=egl.

Episodes end as in Gymnasium: `terminated` when the Brax env reports done (the vehicle left the work
area, or the physics went non-finite), `truncated` after `config.episode_length` steps without
termination. The adapters truncate themselves, so the gymnasium ids carry no `max_episode_steps` and
`gymnasium.make` adds no TimeLimit wrapper.

Randomness. Every episode is drawn from one JAX key:
  * `reset(seed=s)`: key = jax.random.PRNGKey(s) (s is taken modulo 2**32, as JAX does);
  * `reset()` without a seed: s is drawn from the adapter's `np_random` (seeded by the last seeded
    reset), so seeding once and then resetting repeatedly is reproducible;
  * the vector env: `reset(seed=s)` gives env i the seed s + i (Gymnasium's convention), so its
    first episodes equal those of single envs reset with seeds s, s + 1, ...; a list gives one
    seed per env (None entries are drawn from `np_random`);
  * vector autoresets: the k-th automatic reset of env i (k = 1, 2, ...) since its last explicit
    reset uses key jax.random.fold_in(K_i, k), where K_i is the key of that explicit reset.
    A single env has no autoreset, so these episodes have no single-env counterpart with the same
    seed: compare vector and single envs only up to the first autoreset.

Autoreset of the vector env (`autoreset_mode`, also in `metadata` and as an attribute):
  * "next_step" (default, Gymnasium's NEXT_STEP): the step after env i reported terminated or
    truncated resets env i instead of stepping it (its action is ignored) and returns the new
    episode's first observation with reward 0, terminated False and truncated False;
  * "same_step" (SAME_STEP, what TorchRL expects): the step that ends an episode also resets the env
    and returns the new episode's first observation, with that step's reward, terminated and
    truncated; the last observation is in infos["final_obs"] and the last metrics in
    infos["final_info"], each with a boolean mask "_final_obs" / "_final_info".
All N envs advance in one jitted, vmapped call, autoresets included; state stays on the device.

Processes: JAX cannot run in a process forked after it started its threads. Gymnasium's
AsyncVectorEnv forks by default on Linux, so use `make_vec(..., vectorization_mode="async",
vector_kwargs={"context": "spawn"})` (or the default jitted vector env, which is faster); an env
created in a forked child raises a RuntimeError saying so instead of hanging.

Compiled functions are shared: all adapters built for the same env name and resolved config reuse
one Brax env and its jitted reset/step (a small LRU cache), so `gymnasium.make` twice,
`make_vec(..., vectorization_mode="sync")` or `check_env` compile each function once.
"""

from __future__ import annotations

import functools
import os
from typing import Any, NamedTuple, Sequence

import gymnasium
import jax
import jax.numpy as jnp
import numpy as np
from brax.envs.base import State
from gymnasium import spaces
from gymnasium.vector.utils import batch_space

from marinejax.config import UnknownConfigKey
from marinejax.envs.base import MarineEnv
from marinejax.envs.registry import list_envs, make
from marinejax.envs.wrappers import where_done
from marinejax.errors import UserError

__all__ = ["MarineJaxEnv", "MarineJaxVectorEnv", "gymnasium_id", "register_gymnasium_envs"]

NAMESPACE = "marinejax"
VERSION = 0
_SEED_BOUND = 2**31  # seeds drawn from np_random lie in [0, 2**31)
RENDER_MODES = ["rgb_array"]
AUTORESET_MODES = {"next_step": gymnasium.vector.AutoresetMode.NEXT_STEP,
                   "same_step": gymnasium.vector.AutoresetMode.SAME_STEP}
_IMPORT_PID = os.getpid()  # a different pid later means this process was forked after the import


def gymnasium_id(env_name: str) -> str:
    """The gymnasium id of marinejax env `env_name`, e.g. 'marinejax/BlueROV2Heavy-StationKeeping-v0'."""
    return f"{NAMESPACE}/{env_name}-v{VERSION}"


def register_gymnasium_envs() -> list[str]:
    """Register every marinejax env with gymnasium (idempotent); returns all marinejax ids.

    No `max_episode_steps`: the adapters truncate at `episode_length` themselves (an override like
    `gymnasium.make(id, episode_length=400)` therefore just works).
    """
    ids = []
    for name in list_envs():
        env_id = gymnasium_id(name)
        ids.append(env_id)
        if env_id in gymnasium.registry:
            continue
        gymnasium.register(
            id=env_id,
            entry_point="marinejax.envs.gym_adapter:MarineJaxEnv",
            vector_entry_point="marinejax.envs.gym_adapter:MarineJaxVectorEnv",
            kwargs={"env_name": name},
            max_episode_steps=None,
            nondeterministic=False,
        )
    return ids


# --- compiled functions, shared between adapters of the same env and config ----------------


def _seed_keys(seeds: Sequence[int]) -> jax.Array:
    """PRNG keys of `seeds`, (N, 2): row i equals jax.random.PRNGKey(seeds[i] mod 2**32)."""
    seeds = np.asarray([int(s) % 2**32 for s in seeds], dtype=np.uint32)
    return _vmapped_prng_key(seeds)


_vmapped_prng_key = jax.jit(jax.vmap(jax.random.PRNGKey))


class _Carry(NamedTuple):
    """Device-side state of the vector env (leading axis: env)."""

    state: State
    steps: jax.Array  # (N,) int32, control steps in the current episode
    needs_reset: jax.Array  # (N,) bool, the last step terminated or truncated: reset on the next
    episode: jax.Array  # (N,) int32, autoresets since the last explicit reset
    key: jax.Array  # (N, 2) key of the last explicit reset


class _Kernels:
    """One Brax env and its jitted single and batched functions."""

    def __init__(self, env: MarineEnv):
        self.env = env
        self.episode_length = int(env.config.episode_length)
        self.reset = jax.jit(env.reset)
        self.step = jax.jit(env.step)
        self.vreset = jax.jit(self._vreset)
        self.vstep = jax.jit(self._vstep)
        self.vstep_same = jax.jit(self._vstep_same)
        self.vmerge = jax.jit(where_done)
        self.target = jax.jit(env.target_position)
        self.pose = jax.jit(self._pose)
        self.vpose = jax.jit(jax.vmap(self._pose))

    def _pose(self, plant_state) -> tuple[jax.Array, jax.Array]:
        """World position (m) and quaternion of the vehicle: all a frame needs of the plant state."""
        vs = self.env.plant.vehicle_state(plant_state)
        return vs.position, vs.quaternion

    def _reset_where(self, mask: jax.Array, carry: _Carry, episode: jax.Array, state: State) -> State:
        """`state` with envs where `mask` replaced by fresh episodes (key fold_in(K_i, episode_i))."""

        def with_resets():
            fresh = jax.vmap(self.env.reset)(jax.vmap(jax.random.fold_in)(carry.key, episode))
            return where_done(mask, fresh, state)

        # Reset only when some env needs it (jnp.any is a scalar: a real branch, not a select).
        return jax.lax.cond(jnp.any(mask), with_resets, lambda: state)

    def _vreset(self, keys: jax.Array) -> _Carry:
        n = keys.shape[0]
        zeros = jnp.zeros(n, jnp.int32)
        return _Carry(jax.vmap(self.env.reset)(keys), zeros, jnp.zeros(n, bool), zeros, keys)

    def _vstep(self, carry: _Carry, action: jax.Array):
        """NEXT_STEP: envs that ended on the previous call reset now instead of stepping."""
        stepped = jax.vmap(self.env.step)(carry.state, action)
        resetting = carry.needs_reset
        episode = carry.episode + resetting.astype(jnp.int32)
        state = self._reset_where(resetting, carry, episode, stepped)
        reward = jnp.where(resetting, 0.0, state.reward)
        terminated = (state.done > 0) & ~resetting
        steps = jnp.where(resetting, 0, carry.steps + 1)
        truncated = (steps >= self.episode_length) & ~terminated
        carry = _Carry(state, steps, terminated | truncated, episode, carry.key)
        return carry, (state.obs, reward, terminated, truncated, state.metrics)

    def _vstep_same(self, carry: _Carry, action: jax.Array):
        """SAME_STEP: envs whose episode ends in this step reset in it; returns also the final
        observations and metrics and the mask of the envs that ended."""
        stepped = jax.vmap(self.env.step)(carry.state, action)
        terminated = stepped.done > 0
        truncated = (carry.steps + 1 >= self.episode_length) & ~terminated
        ended = terminated | truncated
        episode = carry.episode + ended.astype(jnp.int32)
        state = self._reset_where(ended, carry, episode, stepped)
        steps = jnp.where(ended, 0, carry.steps + 1)
        carry = _Carry(state, steps, jnp.zeros_like(ended), episode, carry.key)
        return carry, (state.obs, stepped.reward, terminated, truncated, state.metrics, stepped.obs, stepped.metrics, ended)


@functools.lru_cache(maxsize=16)
def _cached_kernels(env_name: str, config) -> _Kernels:
    return _Kernels(make(env_name, config=config))


def _kernels(env_name: str, overrides: dict[str, Any]) -> _Kernels:
    if os.getpid() != _IMPORT_PID:
        raise RuntimeError(
            "marinejax envs cannot run in a process forked after JAX started (it would hang): for Gymnasium's "
            "AsyncVectorEnv pass vector_kwargs={'context': 'spawn'}, or use the jitted vector env "
            "(gymnasium.make_vec(id, num_envs=N), the default vectorization mode)"
        )
    try:
        env = make(env_name, **overrides)  # validates the name and the overrides
    except UnknownConfigKey as err:
        # Python's own wording: clients such as TorchRL match "unexpected keyword argument '<name>'"
        raise TypeError(f"{env_name} got an unexpected keyword argument '{err.key}' ({err})") from err
    try:
        hash(env.config)
    except TypeError:  # an unhashable config field: no sharing
        return _Kernels(env)
    return _cached_kernels(env_name, env.config)


def _observation_space(size) -> spaces.Space:
    """A Box of the env's observation size, or a Dict of Boxes for a dict observation."""
    if isinstance(size, dict):
        return spaces.Dict({k: spaces.Box(-np.inf, np.inf, tuple(shape), np.float32) for k, shape in size.items()})
    return spaces.Box(-np.inf, np.inf, (size,), np.float32)


def _np_obs(obs):
    """An observation (array or dict of arrays) as float32 numpy."""
    return {k: np.array(v, dtype=np.float32) for k, v in obs.items()} if isinstance(obs, dict) else np.array(obs, dtype=np.float32)


def _check_render_mode(render_mode: str | None) -> None:
    if render_mode is not None and render_mode not in RENDER_MODES:
        raise UserError(f"render_mode={render_mode!r} is not supported; valid: None, {', '.join(map(repr, RENDER_MODES))}")


class _Frames:
    """Lazily created offscreen renderer of one env's vehicle (no OpenGL until the first frame)."""

    def __init__(self, kernels: _Kernels, width: int, height: int):
        if int(width) < 1 or int(height) < 1:
            raise UserError(f"render_width and render_height must be >= 1, got {width} x {height}")
        self.kernels, self.width, self.height = kernels, int(width), int(height)
        self.renderer = None

    def __call__(self, position: np.ndarray, quaternion: np.ndarray, info: dict) -> np.ndarray:
        """The frame of one env's vehicle pose (world position m, quaternion) and info."""
        if self.renderer is None:
            from marinejax.render import FrameRenderer

            vehicle = self.kernels.env.vehicle
            self.renderer = FrameRenderer(vehicle.mj_model, self.width, self.height, vehicle.sys.qpos_adr)
        target = np.asarray(self.kernels.target(info))
        return self.renderer.frame(position, quaternion, target)

    def close(self) -> None:
        if self.renderer is not None:
            self.renderer.close()
            self.renderer = None


def _float32_action(action: Any, shape: tuple[int, ...]) -> np.ndarray:
    array = np.asarray(action, dtype=np.float32)
    if array.shape != shape:
        raise UserError(f"action must have shape {shape} (float32 in [-1, 1]), got shape {array.shape}")
    return array


# --- single env ---------------------------------------------------------------------------


class MarineJaxEnv(gymnasium.Env):
    """A marinejax env as a `gymnasium.Env` (numpy in and out, one jitted call per step).

    `info` (reset and step) holds the env's metrics as python floats: position_error (m),
    heading_error_deg, reward/<term> (weighted), nonfinite, out_of_bounds, and task-specific ones.
    """

    metadata = {"render_modes": RENDER_MODES, "render_fps": 20}  # per instance: render_fps = 1 / control_dt

    def __init__(self, env_name: str, render_mode: str | None = None, render_width: int = 640, render_height: int = 480,
                 **overrides: Any):
        _check_render_mode(render_mode)
        self.env_name = env_name
        self._kernels = _kernels(env_name, overrides)
        self.marine_env: MarineEnv = self._kernels.env
        cfg = self.marine_env.config
        self.episode_length = int(cfg.episode_length)
        self.render_mode = render_mode
        self._frames = _Frames(self._kernels, render_width, render_height)
        self.metadata = {"render_modes": RENDER_MODES, "render_fps": int(round(1.0 / cfg.control_dt))}
        self.observation_space = _observation_space(self.marine_env.observation_size)
        self.action_space = spaces.Box(-1.0, 1.0, (self.marine_env.action_size,), np.float32)
        self._state: State | None = None
        self._elapsed_steps = 0

    @property
    def elapsed_steps(self) -> int:
        """Steps taken in the current episode."""
        return self._elapsed_steps

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Start an episode; `options` is accepted and ignored (nothing to configure per episode)."""
        super().reset(seed=seed)
        if seed is None:
            seed = int(self.np_random.integers(_SEED_BOUND))
        self._state = self._kernels.reset(_seed_keys([seed])[0])
        self._elapsed_steps = 0
        obs, metrics = jax.device_get((self._state.obs, self._state.metrics))
        return _np_obs(obs), {k: float(v) for k, v in metrics.items()}

    def step(self, action):
        if self._state is None:
            raise gymnasium.error.ResetNeeded("call reset() before step()")
        action = _float32_action(action, self.action_space.shape)
        self._state = self._kernels.step(self._state, action)
        self._elapsed_steps += 1
        s = self._state
        obs, reward, done, metrics = jax.device_get((s.obs, s.reward, s.done, s.metrics))
        terminated = bool(done > 0)
        truncated = self._elapsed_steps >= self.episode_length and not terminated
        info = {k: float(v) for k, v in metrics.items()}
        return _np_obs(obs), float(reward), terminated, truncated, info

    def render(self) -> np.ndarray | None:
        """With render_mode="rgb_array": the current frame, (render_height, render_width, 3) uint8."""
        if self.render_mode is None:
            return None
        if self._state is None:
            raise gymnasium.error.ResetNeeded("call reset() before render()")
        position, quaternion = jax.device_get(self._kernels.pose(self._state.pipeline_state))
        return self._frames(position, quaternion, self._state.info)

    def close(self) -> None:
        _close_frames(self)


def _close_frames(env) -> None:
    """Close an adapter's renderer. Gymnasium's `__del__` closes an env whose `__init__` raised (a bad
    argument) before the renderer existed: nothing to close then."""
    frames = getattr(env, "_frames", None)
    if frames is not None:
        frames.close()


# --- vector env ---------------------------------------------------------------------------


class MarineJaxVectorEnv(gymnasium.vector.VectorEnv):
    """`num_envs` copies of a marinejax env stepped together in one jitted vmapped call.

    NEXT_STEP autoreset (see the module docstring for the reset keys). Returns numpy arrays:
    observations (N, obs) float32, rewards (N,) float64, terminations and truncations (N,) bool,
    infos a dict of (N,) float arrays (the metrics), each with a boolean "_<key>" mask (Gymnasium's
    vector info convention; all True, except on a partial reset, where it is `reset_mask`).
    `reset(options={"reset_mask": mask})` resets only the envs where `mask` (N,) bool is True.
    """

    metadata = {"render_modes": RENDER_MODES, "render_fps": 20, "autoreset_mode": gymnasium.vector.AutoresetMode.NEXT_STEP}

    def __init__(self, env_name: str, num_envs: int, render_mode: str | None = None, autoreset_mode: Any = "next_step",
                 render_width: int = 640, render_height: int = 480, **overrides: Any):
        _check_render_mode(render_mode)
        if int(num_envs) < 1:
            raise UserError(f"num_envs must be >= 1, got {num_envs}")
        # the enum member itself, or our names of its values ("SameStep" is SAME_STEP's value)
        by_enum = {enum: name for name, enum in AUTORESET_MODES.items()}
        mode = by_enum.get(autoreset_mode, autoreset_mode) if isinstance(autoreset_mode, gymnasium.vector.AutoresetMode) else autoreset_mode
        if mode not in AUTORESET_MODES:
            raise UserError(f"autoreset_mode={autoreset_mode!r} is not supported; valid: {list(AUTORESET_MODES)} "
                             "(or the gymnasium.vector.AutoresetMode members NEXT_STEP, SAME_STEP)")
        self.autoreset_mode = AUTORESET_MODES[mode]
        self.env_name = env_name
        self.num_envs = int(num_envs)
        self._kernels = _kernels(env_name, overrides)
        self.marine_env: MarineEnv = self._kernels.env
        cfg = self.marine_env.config
        self.episode_length = int(cfg.episode_length)
        self.render_mode = render_mode
        self._frames = _Frames(self._kernels, render_width, render_height)
        self.metadata = {
            "render_modes": RENDER_MODES,
            "render_fps": int(round(1.0 / cfg.control_dt)),
            "autoreset_mode": self.autoreset_mode,
        }
        self.single_observation_space = _observation_space(self.marine_env.observation_size)
        self.single_action_space = spaces.Box(-1.0, 1.0, (self.marine_env.action_size,), np.float32)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._carry: _Carry | None = None

    @property
    def elapsed_steps(self) -> np.ndarray:
        """(N,) steps taken in each env's current episode (0 right after a reset or an autoreset)."""
        if self._carry is None:
            return np.zeros(self.num_envs, np.int64)
        return np.array(self._carry.steps, dtype=np.int64)

    def _seeds(self, seed: int | Sequence[int | None] | None) -> list[int]:
        if seed is None:
            seeds: list[int | None] = [None] * self.num_envs
        elif isinstance(seed, (int, np.integer)):
            seeds = [int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise UserError(f"seed must be None, an int or a list of num_envs={self.num_envs} seeds, got {len(seeds)} seeds")
        return [int(self.np_random.integers(_SEED_BOUND)) if s is None else int(s) for s in seeds]

    def reset(self, *, seed: int | Sequence[int | None] | None = None, options: dict[str, Any] | None = None):
        if isinstance(seed, (int, np.integer)):
            super().reset(seed=int(seed))
        elif seed is not None and all(s is not None for s in seed):
            # Seed np_random from the whole list, so later seedless resets are reproducible too.
            self._np_random = np.random.Generator(np.random.PCG64(np.random.SeedSequence([int(s) for s in seed])))
            self._np_random_seed = -1
        mask = None
        if options is not None and "reset_mask" in options:
            mask = np.asarray(options["reset_mask"])
            if mask.shape != (self.num_envs,) or mask.dtype != np.bool_:
                raise UserError(f"options['reset_mask'] must be a bool array of shape ({self.num_envs},), got {mask.dtype} {mask.shape}")
            if self._carry is None:
                raise gymnasium.error.ResetNeeded("a partial reset (reset_mask) needs a full reset() first")
        carry = self._kernels.vreset(_seed_keys(self._seeds(seed)))
        if mask is not None:
            carry = self._kernels.vmerge(jnp.asarray(mask), carry, self._carry)
        self._carry = carry
        obs, metrics = jax.device_get((carry.state.obs, carry.state.metrics))
        return _np_obs(obs), self._infos(metrics, mask)

    def step(self, actions):
        if self._carry is None:
            raise gymnasium.error.ResetNeeded("call reset() before step()")
        actions = _float32_action(actions, self.action_space.shape)
        if self.autoreset_mode == gymnasium.vector.AutoresetMode.NEXT_STEP:
            self._carry, out = self._kernels.vstep(self._carry, actions)
            obs, reward, terminated, truncated, metrics = jax.device_get(out)
            infos = self._infos(metrics, None)
        else:
            self._carry, out = self._kernels.vstep_same(self._carry, actions)
            obs, reward, terminated, truncated, metrics, final_obs, final_metrics, ended = jax.device_get(out)
            infos = self._infos(metrics, None)
            if ended.any():
                ended = np.array(ended, dtype=np.bool_)
                infos["final_obs"] = _np_obs(final_obs)
                infos["_final_obs"] = ended
                infos["final_info"] = self._infos(final_metrics, ended)
                infos["_final_info"] = ended.copy()
        return (
            _np_obs(obs),
            np.array(reward, dtype=np.float64),
            np.array(terminated, dtype=np.bool_),
            np.array(truncated, dtype=np.bool_),
            infos,
        )

    def _infos(self, metrics: dict[str, np.ndarray], mask: np.ndarray | None) -> dict[str, np.ndarray]:
        infos: dict[str, np.ndarray] = {}
        for k, v in metrics.items():
            infos[k] = np.array(v)
            infos[f"_{k}"] = np.ones(self.num_envs, np.bool_) if mask is None else mask.copy()
        return infos

    def render(self) -> tuple[np.ndarray, ...] | None:
        """With render_mode="rgb_array": one frame per env, each (render_height, render_width, 3) uint8."""
        if self.render_mode is None:
            return None
        if self._carry is None:
            raise gymnasium.error.ResetNeeded("call reset() before render()")
        (position, quaternion), info = jax.device_get((self._kernels.vpose(self._carry.state.pipeline_state), self._carry.state.info))
        return tuple(self._frames(position[i], quaternion[i], jax.tree.map(lambda x, i=i: x[i], info)) for i in range(self.num_envs))

    def close_extras(self, **kwargs: Any) -> None:
        _close_frames(self)
