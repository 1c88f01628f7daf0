"""Deterministic evaluation of a trained policy or a classical controller, as `marinejax eval` runs
it: statistics (`statistics`), path plot (`paths`) and video (`marinejax.render`) of a run's
checkpoint (`checkpoints`) or of `marinejax.controllers`, written to eval.json."""

from __future__ import annotations

import copy
import json
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from marinejax.train.checkpoints import best_checkpoint, latest_checkpoint, load_policy
from marinejax.train.paths import plot_paths, plot_sonar
from marinejax.statistics import rollout_controller, rollout_policy, summarize


def evaluate_run(path: Path, out_dir: Path | None = None, episodes: int = 64, seed: int = 12345,
                 env_overrides: dict[str, Any] | None = None, video: bool = True, which: str = "best") -> dict[str, Any]:
    """Evaluate a run directory or checkpoint (`which`: "best" or "latest" of a run directory);
    write eval.json, path PNG and video into out_dir."""
    config, env, policy, ckpt = load_policy(path, env_overrides, which)
    run_dir = ckpt.parent.parent  # checkpoints live in <run>/checkpoints/<step>
    if ckpt == best_checkpoint(run_dir):
        kind = ("best (nearest to meeting every target during training)" if config.agent.best_on == "targets"
                else "best (lowest evaluation error during training)")
    elif ckpt == latest_checkpoint(run_dir):
        kind = "newest"
    else:
        kind = "as given"
    if out_dir is None and run_dir.parent == Path(str(resources.files("marinejax"))) / "policies":
        out_dir = Path("runs") / f"eval-{config.env}"  # never write into the installed package
    out_dir = Path(out_dir) if out_dir else run_dir / "eval"
    out_dir.mkdir(parents=True, exist_ok=True)
    result = rollout_policy(env, policy, episodes, seed)
    summary = {"env": config.env, "checkpoint": str(ckpt), "checkpoint_kind": kind, "env_overrides": env_overrides or {}, "seed": seed}
    return _write(env, result, summary, f"{config.env}: checkpoint {ckpt.name}, episode 0", out_dir, video)


def evaluate_finished_run(run_dir: Path, summary: dict[str, Any], episodes: int = 64, video: bool = True,
                          latest: bool = False) -> dict[str, Any]:
    """The final evaluation of a run that `train` just finished: `evaluate_run` of its best
    checkpoint, recorded as summary["evaluation"] in its summary.json; returns the evaluation. With
    `latest`, also the newest checkpoint on the same episodes (into eval-latest/, without video;
    the best's evaluation where the two are one), as summary["evaluation_latest"]."""
    result = evaluate_run(run_dir, episodes=episodes, video=video)
    summary["evaluation"] = result
    if latest:
        newest = latest_checkpoint(Path(run_dir))
        summary["evaluation_latest"] = (result if str(newest) == result["checkpoint"] else
                                        evaluate_run(run_dir, Path(run_dir) / "eval-latest", episodes, video=False, which="latest"))
    (Path(run_dir) / "summary.json").write_text(json.dumps(summary, indent=2))
    return result


def evaluate_controller(env_name: str, controller: str, out_dir: Path | None = None, episodes: int = 64, seed: int = 12345,
                        env_overrides: dict[str, Any] | None = None, video: bool = True, progress=None) -> dict[str, Any]:
    """Evaluate a classical controller (`marinejax.controllers`, tuned first) on env `env_name`
    exactly as a policy; write eval.json, path PNG and video into out_dir (default runs/eval-<env>-<controller>)."""
    import marinejax
    from marinejax.controllers import make_controller

    env = marinejax.make(env_name, **(env_overrides or {}))
    ctrl, description = make_controller(controller, env, progress=progress)
    out_dir = Path(out_dir) if out_dir else Path("runs") / f"eval-{env_name}-{controller}"
    out_dir.mkdir(parents=True, exist_ok=True)
    result = rollout_controller(env, ctrl, episodes, seed)
    summary = {"env": env_name, **description, "env_overrides": env_overrides or {}, "seed": seed}
    return _write(env, result, summary, f"{env_name}: {controller}, episode 0", out_dir, video)


def _write(env, result: dict, summary: dict[str, Any], title: str, out_dir: Path, video: bool) -> dict[str, Any]:
    summary = {**summary, **summarize(env, result)}
    summary["plot"] = str(plot_paths(result, title, out_dir / "paths.png"))
    sonar = _sonar_trace(env, result, episode=0) if "sonar" in result else None
    if sonar is not None:
        summary["sonar"] = _write_sonar(env, result, title, out_dir)
    if video:
        from marinejax.render import render_video

        model = env.vehicle.mj_model
        if "layout" in result:  # the scene as it was in episode 0
            model = copy.deepcopy(model)
            model.geom_pos[np.asarray(env.plant.sys.layout_ids, int)] = result["layout"][0]
        try:
            summary["video"] = str(render_video(model, result["position"][0], result["quaternion"][0], result["target"][0],
                                                1.0 / env.config.control_dt, out_dir / "episode0", env.vehicle.sys.qpos_adr,
                                                result["actuators"][0], env.vehicle.actuator_names, sonar))
        except RuntimeError as err:
            summary["video_error"] = str(err)
    (out_dir / "eval.json").write_text(json.dumps(summary, indent=2))
    return summary


def _sonar_trace(env, result: dict, episode: int):
    """The sonar's readings in one episode, to draw (`render.SonarTrace`): the observed ranges (a
    beam reading max_range had no echo) and, with `intensity`, the intensities."""
    from marinejax.plant.rays import fan
    from marinejax.render import SonarTrace

    sonar = env.plant.scene_sensors.sensors["sonar"]
    c = sonar.config
    ranges = result["sonar"][episode]
    return SonarTrace(ranges=ranges, hit=ranges < c.max_range, intensity=result["sonar_intensity"][episode] if c.intensity else None,
                      mount=np.asarray(c.position, np.float64), directions=fan(c.beams, c.horizontal_fov, 1, 0.0, c.tilt)[:, 0],
                      azimuth=np.asarray(sonar.azimuth), max_range=c.max_range)


def _write_sonar(env, result: dict, title: str, out_dir: Path) -> dict[str, str]:
    """The sonar's range images: every episode's in sonar.npz (ranges (E, T, beams), m; with the
    sonar's `intensity`, intensity (E, T, beams), 0-1; time, s; azimuth, rad, positive to the left)
    and episode 0's as a PNG."""
    sonar = env.plant.scene_sensors.sensors["sonar"]
    azimuth = sonar.azimuth
    extra = {"intensity": result["sonar_intensity"].astype(np.float32)} if sonar.config.intensity else {}
    np.savez_compressed(out_dir / "sonar.npz", ranges=result["sonar"].astype(np.float32), time=result["time"], azimuth=azimuth, **extra)
    png = plot_sonar(result, np.degrees(azimuth), sonar.config.max_range, f"{title}: sonar", out_dir / "sonar.png")
    return {"ranges": str(out_dir / "sonar.npz"), "image": str(png)}
