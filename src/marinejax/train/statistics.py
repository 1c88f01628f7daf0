"""Evaluation statistics of a policy: deterministic episodes and the error over each task's window.

Per episode, the mean position error over the task's evaluation window (last second of station
keeping, after the first 2 s of tracking, once the reference has ramped up); over episodes, the
mean, median and 95th percentile, and the success rate (that per-episode error below `success_m`).
"""

from __future__ import annotations

from typing import Any

import jax
import numpy as np

from marinejax.control import policy_controller, rollout
from marinejax.envs.base import MarineEnv

SUCCESS_M = 0.1  # m: an episode succeeds when its evaluated mean position error is below this


def rollout_policy(env: MarineEnv, policy, episodes: int, seed: int = 0) -> dict[str, np.ndarray]:
    """Run `episodes` full episodes (episode_length steps, no early reset) in one jitted call.

    Returns arrays: time (T,), position (E, T, 3), target (E, T, 3), error (E, T), qpos (E, T, 7),
    done (E, T), heading_error_deg (E, T).
    """
    steps = env.config.episode_length

    def record(s):
        q = s.pipeline_state.data.qpos
        return (q[:3], env.target_position(s.info), s.metrics["position_error"], q, s.done, s.metrics["heading_error_deg"])

    keys = jax.random.split(jax.random.PRNGKey(seed), episodes)
    _, (pos, target, err, qpos, done, head) = rollout(env, policy_controller(policy), keys, steps, record)
    to_np = lambda x: np.asarray(x, dtype=np.float64)  # noqa: E731
    return {
        "time": env.config.control_dt * np.arange(1, steps + 1),
        "position": to_np(pos), "target": to_np(target), "error": to_np(err),
        "qpos": to_np(qpos), "done": to_np(done), "heading_error_deg": to_np(head),
    }


def summarize(env: MarineEnv, result: dict[str, np.ndarray], success_m: float = SUCCESS_M) -> dict[str, Any]:
    mask = np.asarray(env.error_window(result["time"]))
    per_episode = result["error"][:, mask].mean(axis=1)
    ended = result["done"].max(axis=1) > 0
    return {
        "episodes": int(per_episode.size),
        "window": env.error_window_description,
        "position_error_mean_m": float(per_episode.mean()),
        "position_error_median_m": float(np.median(per_episode)),
        "position_error_p95_m": float(np.percentile(per_episode, 95)),
        "heading_error_mean_deg": float(result["heading_error_deg"][:, mask].mean()),
        "success_rate": float(np.mean((per_episode < success_m) & ~ended)),
        "success_threshold_m": success_m,
        "terminated_episodes": int(ended.sum()),
    }
