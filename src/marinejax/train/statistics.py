"""Evaluation statistics of a policy: deterministic episodes and the error over each task's window.

Per episode, the mean position error over the task's evaluation window (last second of station
keeping, after the first 2 s of tracking, once the reference has ramped up); over episodes, the
mean, median and 95th percentile, and the success rate (that per-episode error below the task's
`success_threshold_m`).
"""

from __future__ import annotations

from typing import Any

import jax
import numpy as np

from marinejax.control import Controller, policy_controller, rollout
from marinejax.envs.base import MarineEnv

def rollout_policy(env: MarineEnv, policy, episodes: int, seed: int = 0) -> dict[str, np.ndarray]:
    """`rollout_controller` of a policy (observation → action)."""
    return rollout_controller(env, policy_controller(policy), episodes, seed)


def rollout_controller(env: MarineEnv, controller: Controller, episodes: int, seed: int = 0) -> dict[str, np.ndarray]:
    """Run `episodes` full episodes (episode_length steps, no early reset) in one jitted call.

    Returns arrays: time (T,), position (E, T, 3, m, world), quaternion (E, T, 4), target (E, T, 3),
    error (E, T), done (E, T), heading_error_deg (E, T).
    """
    steps = env.config.episode_length

    def record(s):
        vs = env.plant.vehicle_state(s.pipeline_state)
        return (vs.position, vs.quaternion, env.target_position(s.info), s.metrics["position_error"], s.done,
                s.metrics["heading_error_deg"])

    keys = jax.random.split(jax.random.PRNGKey(seed), episodes)
    _, (pos, quat, target, err, done, head) = rollout(env, controller, keys, steps, record)
    to_np = lambda x: np.asarray(x, dtype=np.float64)  # noqa: E731
    return {
        "time": env.config.control_dt * np.arange(1, steps + 1),
        "position": to_np(pos), "target": to_np(target), "error": to_np(err),
        "quaternion": to_np(quat), "done": to_np(done), "heading_error_deg": to_np(head),
    }


def summarize(env: MarineEnv, result: dict[str, np.ndarray]) -> dict[str, Any]:
    """Statistics over episodes of the task's window error; success below the task's threshold."""
    success_m = env.success_threshold_m
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
