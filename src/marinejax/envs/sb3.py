"""Stable-Baselines3 `VecEnv` over marinejax's batched Gymnasium vector env.

    from stable_baselines3 import PPO
    from marinejax.envs.sb3 import MarineJaxSB3VecEnv
    venv = MarineJaxSB3VecEnv("BlueROV2Heavy-CircleTracking", num_envs=16)
    PPO("MlpPolicy", venv).learn(100_000)

All envs advance in one jitted, vmapped call (SB3's `DummyVecEnv` steps them one by one in Python).
SB3 conventions: an env whose episode ends is reset in the same step; its last observation is in
`infos[i]["terminal_observation"]` and `infos[i]["TimeLimit.truncated"]` tells a time limit from a
termination. Seeds: `venv.seed(s)` makes the next reset give env i the seed s + i. Keyword arguments
are config overrides, as for `marinejax.make`. Needs the optional extra: pip install "marinejax[sb3]".
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

try:
    from stable_baselines3.common.vec_env import VecEnv
except ImportError as err:  # pragma: no cover - depends on the install
    raise ImportError('marinejax.envs.sb3 needs Stable-Baselines3: pip install "marinejax[sb3]"') from err

from marinejax.envs.gym_adapter import MarineJaxVectorEnv


class MarineJaxSB3VecEnv(VecEnv):
    """`num_envs` copies of marinejax env `env_name` as an SB3 VecEnv (numpy in and out)."""

    def __init__(self, env_name: str, num_envs: int, render_mode: str | None = None, **overrides: Any):
        self.venv = MarineJaxVectorEnv(env_name, num_envs, render_mode=render_mode, autoreset_mode="same_step", **overrides)
        self._actions: np.ndarray | None = None
        super().__init__(self.venv.num_envs, self.venv.single_observation_space, self.venv.single_action_space)

    def reset(self) -> np.ndarray:
        seeds = None if all(s is None for s in self._seeds) else list(self._seeds)
        obs, infos = self.venv.reset(seed=seeds)
        self.reset_infos = self._split_infos(infos)
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions, dtype=np.float32)

    def step_wait(self):
        obs, rewards, terminated, truncated, infos = self.venv.step(self._actions)
        dones = terminated | truncated
        out = self._split_infos(infos)
        for i in np.flatnonzero(dones):
            out[i]["terminal_observation"] = infos["final_obs"][i]
            out[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
            out[i].update({k: float(v[i]) for k, v in infos["final_info"].items() if not k.startswith("_")})
        return obs, rewards.astype(np.float32), dones, out

    def _split_infos(self, infos: dict[str, Any]) -> list[dict[str, Any]]:
        """Gymnasium's dict of (N,) arrays → SB3's list of N dicts (the env's metrics as floats)."""
        keys = [k for k, v in infos.items() if not k.startswith("_") and isinstance(v, np.ndarray) and v.shape == (self.num_envs,)]
        return [{k: float(infos[k][i]) for k in keys} for i in range(self.num_envs)]

    def close(self) -> None:
        self.venv.close()

    def get_images(self) -> Sequence[np.ndarray | None]:
        if self.render_mode != "rgb_array":
            return [None] * self.num_envs
        return list(self.venv.render())

    def _indices(self, indices) -> list[int]:
        if indices is None:
            return list(range(self.num_envs))
        return [indices] if isinstance(indices, int) else list(indices)

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        """The attribute of the (one, shared) vector env, once per requested index."""
        value = getattr(self.venv, attr_name)
        return [value for _ in self._indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        raise AttributeError(f"the envs of a MarineJaxSB3VecEnv share one batched env; set_attr({attr_name!r}) is not supported")

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        result = getattr(self.venv, method_name)(*method_args, **method_kwargs)
        return [result for _ in self._indices(indices)]

    def env_is_wrapped(self, wrapper_class: type, indices=None) -> list[bool]:
        return [False for _ in self._indices(indices)]
