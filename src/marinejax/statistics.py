"""Evaluation statistics of a policy: deterministic episodes and the error over each task's window.

Per episode, the mean position error over the task's evaluation window (last second of station
keeping, after the first 2 s of tracking, once the reference has ramped up); over episodes, the
mean, median and 95th percentile, and the success rate (that per-episode error below the task's
`success_threshold_m`, and where the task sets `success_heading_deg` its mean heading error below that;
or, where the task sets `success_flag`, that error's value at the episode's last step).
"""

from __future__ import annotations

from typing import Any

import jax
import mujoco
import numpy as np

from marinejax.control import Controller, policy_controller, rollout
from marinejax.envs.base import MarineEnv


def rollout_policy(env: MarineEnv, policy, episodes: int, seed: int = 0) -> dict[str, np.ndarray]:
    """`rollout_controller` of a policy (observation → action)."""
    return rollout_controller(env, policy_controller(policy), episodes, seed)


def rollout_controller(env: MarineEnv, controller: Controller, episodes: int, seed: int = 0) -> dict[str, np.ndarray]:
    """Run `episodes` full episodes (episode_length steps, no early reset) in one jitted call.

    Returns arrays: time (T,), position (E, T, 3, m, world), quaternion (E, T, 4), target (E, T, 3),
    error (E, T), done (E, T), actuators (E, T, n: the actuator states, physical units), and (E, T)
    each of the task's other errors (`MarineEnv.error_names`: heading_error_deg, and e.g. speed_error).
    In a scene with movable geoms also layout (E, k, 3, m, world: where they were), layout_size
    (k, 3, the geoms' MuJoCo sizes) and layout_box (k, bool: a box, whose sizes are half-lengths);
    with scene sensors each of their observation fields, e.g. sonar (E, T, beams, m), altimeter (E, T, 1,
    m) and, with the sonar's intensities, sonar_intensity (E, T, beams).
    """
    steps = env.config.episode_length
    others = [name for name in env.error_names if name != "position_error"]
    scene_sensors = env.plant.scene_sensors

    def record(s):
        vs = env.plant.vehicle_state(s.pipeline_state)
        seen = scene_sensors.observe_fields(s.info["scene_sensors"]) if scene_sensors else {}
        return (vs.position, vs.quaternion, env.target_position(s.info), s.metrics["position_error"], s.done,
                {name: s.metrics[name] for name in others}, vs.actuators, seen, s.info["params"].layout)

    keys = jax.random.split(jax.random.PRNGKey(seed), episodes)
    _, (pos, quat, target, err, done, errors, actuators, seen, layout) = rollout(env, controller, keys, steps, record)
    to_np = lambda x: np.asarray(x, dtype=np.float64)  # noqa: E731
    out = {
        "time": env.config.control_dt * np.arange(1, steps + 1),
        "position": to_np(pos), "target": to_np(target), "error": to_np(err),
        "quaternion": to_np(quat), "done": to_np(done), "actuators": to_np(actuators),
        **{name: to_np(e) for name, e in errors.items()},
        **{name: to_np(r) for name, r in seen.items()},
    }
    ids = np.asarray(env.plant.sys.layout_ids, int)
    if ids.size:
        out["layout"] = to_np(layout[:, 0])
        out["layout_size"] = np.asarray(env.vehicle.mj_model.geom_size[ids], np.float64)
        out["layout_box"] = env.vehicle.mj_model.geom_type[ids] == int(mujoco.mjtGeom.mjGEOM_BOX)
    return out


def summarize(env: MarineEnv, result: dict[str, np.ndarray]) -> dict[str, Any]:
    """Statistics over episodes of the task's window error; success below the task's thresholds; the
    mean over the window of each other error (`<name>_mean`, e.g. heading_error_mean_deg) and its unit
    (`units`: name → unit, `MarineEnv.error_units`)."""
    success_m = env.success_threshold_m
    mask = np.asarray(env.error_window(result["time"]))
    per_episode = result["error"][:, mask].mean(axis=1)
    ended = result["done"].max(axis=1) > 0
    if env.success_flag is not None:
        success = (result[env.success_flag][:, -1] > 0) & ~ended
    else:
        success = (per_episode < success_m) & ~ended
        if env.success_heading_deg is not None:
            success &= result["heading_error_deg"][:, mask].mean(axis=1) < env.success_heading_deg
    others = {_mean_name(name): float(result[name][:, mask].mean()) for name in env.error_names if name != "position_error"}
    return {
        "episodes": int(per_episode.size),
        "window": env.error_window_description,
        "position_error_mean_m": float(per_episode.mean()),
        "position_error_median_m": float(np.median(per_episode)),
        "position_error_p95_m": float(np.percentile(per_episode, 95)),
        **others,
        "success_rate": float(np.mean(success)),
        "success_threshold_m": success_m,
        "success_heading_deg": env.success_heading_deg,
        "success_flag": env.success_flag,
        "terminated_episodes": int(ended.sum()),
        "units": {name: env.error_units[error] for error, name in zip(env.error_names, map(_mean_name, env.error_names))
                  if name in others},
    }


def _mean_name(error: str) -> str:
    """heading_error_deg → heading_error_mean_deg; speed_error → speed_error_mean."""
    base, unit = (error[: -len("_deg")], "_deg") if error.endswith("_deg") else (error, "")
    return f"{base}_mean{unit}"
