"""Run a training (PPO or SAC: `hyperparams.ALGORITHMS`) into a run directory, with progress,
metrics, checkpoints and resume.

Run directory layout:
  config.json        the resolved env config, the algorithm and its settings, versions and machine
  metrics.jsonl      one line per evaluation: env steps, wall time, evaluation metrics
  checkpoints/<step> the algorithm's Brax checkpoints (params + network config)
  best.json          the best evaluated checkpoint so far (lowest evaluation error, or per `best_on`)
  curve.png          learning curve (return and position error vs env steps and wall time)
  summary.json       written when training ends (or is interrupted)
  tensorboard/       every evaluation's metrics as TensorBoard scalars (`tensorboard --logdir runs`)
  wandb_id.txt, wandb/  with --wandb: the Weights & Biases run's id and W&B's own files (`wandb_log`)
"""

from __future__ import annotations

import dataclasses
import functools
import json
import os
import time
import warnings
from pathlib import Path
from typing import Any, Callable

import jax
import numpy as np

from marinejax.config import to_dict
from marinejax.envs import wrap_for_training
from marinejax.envs.base import MarineEnv
from marinejax.errors import MissingFileError, UserError
from marinejax.machine import machine_info
from marinejax.train.checkpoints import BEST, CHECKPOINTS, latest_checkpoint
from marinejax.train.curves import WINDOW_ERROR, checkpoint_score
from marinejax.train import wandb_log
from marinejax.train.hyperparams import PPOConfig, SACConfig, TrainConfig, build_env

TENSORBOARD = "tensorboard"  # the run directory's TensorBoard event files


class _TargetReached(Exception):
    """Raised from the progress callback to end the training once the target error is met."""


def machine() -> dict[str, Any]:
    """The machine a run trained on, as config.json records it."""
    info = machine_info()
    return {"cpu": info["cpu"], "cores": info["cpu_count"], "jax_backend": info["backend"], "devices": info["devices"],
            "jax": info["jax"], "python": info["python"]}


def use_cpu_devices(n: int) -> bool:
    """Split this host's CPU into `n` JAX devices (`jax_num_cpu_devices`), as a recipe's
    `cpu_devices` asks. Only before JAX's first operation, and not where XLA_FLAGS already sets
    `--xla_force_host_platform_device_count` (that count stays); returns whether it was set."""
    if n < 1:
        raise UserError(f"the number of CPU devices must be >= 1, got {n}")
    if "xla_force_host_platform_device_count" in os.environ.get("XLA_FLAGS", ""):
        return False
    try:
        jax.config.update("jax_num_cpu_devices", n)
    except RuntimeError:  # JAX's backend has started: its devices stay as they are
        return False
    return True


def check_devices(devices: int | None, agent: PPOConfig | SACConfig) -> int:
    """The number of local devices to train on; raises UserError naming the valid range. None: on a
    CPU host the recipe's `cpu_devices` (fewer, with a warning, where JAX started with fewer: call
    `use_cpu_devices` first), elsewhere all of `jax.local_devices()`. With several processes
    (`jax.distributed`) each trains on as many and the envs are split over all."""
    available = jax.local_device_count()
    n = available if devices is None else devices
    if devices is None and jax.default_backend() == "cpu":
        n = min(agent.cpu_devices, available)
        if n < agent.cpu_devices:
            warnings.warn(f"this recipe trains on {agent.cpu_devices} CPU devices but JAX started with {available}, so its "
                          f"results will differ from the recipe's: call marinejax.train.runner.use_cpu_devices("
                          f"{agent.cpu_devices}) before any JAX operation", stacklevel=2)
    if not 1 <= n <= available:
        raise UserError(f"devices must be between 1 and the {available} local device(s) "
                         f"({', '.join(str(d) for d in jax.local_devices())}), got {devices}")
    if agent.num_envs % (n * jax.process_count()):
        raise UserError(f"num_envs ({agent.num_envs}) must be a multiple of the number of devices ({n}"
                        + (f" × {jax.process_count()} processes" if jax.process_count() > 1 else "") + ")")
    return n


def resumable(config: TrainConfig) -> bool:
    """Whether a run of this config can be resumed from its checkpoints (not SAC: `train.sac`)."""
    return config.algorithm != "sac"


def check_resumable(config: TrainConfig, run_dir: Path) -> None:
    """Raises UserError for a run that cannot be resumed (SAC: `train.sac`)."""
    if not resumable(config):
        raise UserError(f"{run_dir}: a SAC run cannot be resumed (Brax 0.14's SAC fails to restore its own checkpoints, "
                        "and they hold neither the critics nor the replay buffer); its checkpoints still evaluate and export")


def save_config(run_dir: Path, config: TrainConfig, env: MarineEnv) -> None:
    from importlib.metadata import version

    data = {
        "env": config.env,
        "env_overrides": dict(config.env_overrides),
        "env_config": to_dict(env.config),
        "algorithm": config.algorithm,
        config.algorithm: dataclasses.asdict(config.agent),
        "observation_size": env.observation_size,
        "action_size": env.action_size,
        "versions": {p: version(p) for p in ("marinejax", "jax", "brax", "mujoco", "mujoco-mjx")},
        "machine": machine(),
        "processes": jax.process_count(),
    }
    (run_dir / "config.json").write_text(json.dumps(data, indent=2))


def _json_metrics(metrics: dict[str, Any]) -> dict[str, float]:
    return {k: float(np.asarray(v)) for k, v in metrics.items() if np.ndim(v) == 0}


def train(
    config: TrainConfig,
    run_dir: Path,
    resume: bool = False,
    on_eval: Callable[[dict[str, float]], None] | None = None,
    target_error: float | None = None,
    stop_at_target: bool = True,
    devices: int | None = None,
    trace_cache: Path | None = None,
    wandb_project: str | None = None,
) -> dict[str, Any]:
    """Train `config` into `run_dir`; resume from its newest checkpoint when `resume`.

    Calls `on_eval(record)` after every evaluation, where record has 'step' (env steps, counted
    across resumes), 'elapsed' (s of wall time, across resumes) and the evaluation metrics; the
    same record is appended to metrics.jsonl. On KeyboardInterrupt the newest checkpoint stays
    usable and the summary says 'interrupted'.

    After every evaluation the checkpoint with the lowest `eval/episode_window_error` (m) is named in
    best.json, or with the algorithm's `best_on="targets"` the one with the lowest
    `curves.checkpoint_score` over the task's targets (best.json's 'score'). With `target_error` (m),
    the summary records when the window error first met the target (env steps and wall seconds), and
    training stops there if `stop_at_target`.

    `devices` local devices share the env batch (Brax's pmap; gradients are averaged over them);
    None: `check_devices`'s default. `num_envs` must be a multiple of it.

    `trace_cache` (a folder) keeps the training env's traced reset and step between runs
    (`envs/trace_cache.py`); the CLI passes one whenever JAX's compilation cache is on.

    With several processes (`jax.distributed.initialize` first, in each), every process calls this
    with the same arguments; they split the envs and average their gradients, and process 0 alone
    evaluates and writes the run directory (the others return a summary without evaluations). The
    trace cache is then not used (the processes would write the same files), and training does not
    stop at `target_error` (Brax cannot stop the other processes with process 0).

    `wandb_project`: also log every evaluation to Weights & Biases (`wandb_log`), from process 0.
    """
    run_dir = Path(run_dir).resolve()  # orbax needs absolute paths
    lead = jax.process_index() == 0
    if jax.process_count() > 1:
        trace_cache, stop_at_target = None, False
    if resume:
        check_resumable(config, run_dir)
    agent, algorithm = config.agent, config.module
    devices = check_devices(devices, agent)
    env = build_env(config)
    if agent.best_on == "targets" and not env.targets:
        raise UserError(f"{config.algorithm} 'best_on' is 'targets' but {config.env} has no targets (MarineEnv.targets); "
                        "use 'window_error'")
    targets = dict(env.targets) if agent.best_on == "targets" else None
    steps_done, elapsed_before, restore = 0, 0.0, None
    if resume:
        ckpt = latest_checkpoint(run_dir)
        if ckpt is None:
            raise MissingFileError(f"no checkpoint to resume from in {run_dir / CHECKPOINTS}")
        steps_done, restore = int(ckpt.name), ckpt
        lines = (run_dir / "metrics.jsonl").read_text().splitlines() if (run_dir / "metrics.jsonl").exists() else []
        records = [json.loads(line) for line in lines if line.strip()]
        kept = [r for r in records if r["step"] <= steps_done]
        elapsed_before = kept[-1]["elapsed"] if kept else 0.0
        if lead:
            (run_dir / "metrics.jsonl").write_text("".join(json.dumps(r) + "\n" for r in kept))
    elif lead:
        run_dir.mkdir(parents=True, exist_ok=True)
        save_config(run_dir, config, env)
    remaining = agent.num_timesteps - steps_done
    if remaining <= 0:
        return json.loads((run_dir / "summary.json").read_text()) if (run_dir / "summary.json").exists() else {}

    start = time.monotonic()
    records: list[dict[str, float]] = []
    reached: dict[str, float] = {}
    best_path = run_dir / BEST
    best = json.loads(best_path.read_text()) if resume and best_path.exists() else None

    from tensorboardX import SummaryWriter  # a dependency of brax

    # a resumed run drops the events after its checkpoint, as metrics.jsonl does (Brax reports
    # evaluations to process 0 only)
    board = SummaryWriter(str(run_dir / TENSORBOARD), purge_step=steps_done if resume else None) if lead else None
    wandb_run = (wandb_log.start(wandb_project, run_dir, json.loads((run_dir / "config.json").read_text()), resume)
                 if wandb_project and lead else None)

    def progress(step: int, metrics: dict[str, Any]) -> None:
        if step == 0 and steps_done > 0:
            return  # the resumed policy was already evaluated at this step
        record = {"step": steps_done + int(step), "elapsed": elapsed_before + time.monotonic() - start, **_json_metrics(metrics)}
        records.append(record)
        with (run_dir / "metrics.jsonl").open("a") as f:
            f.write(json.dumps(record) + "\n")
        for key, value in record.items():
            if key != "step":
                board.add_scalar(key, value, record["step"])
        board.flush()
        if wandb_run is not None:
            wandb_log.log(wandb_run, record)
        nonlocal best
        err, score = record.get(WINDOW_ERROR), checkpoint_score(record, targets)
        if score is not None and record["step"] > 0 and (best is None or score < best.get("score", best["window_error"])):
            best = {"step": record["step"], "window_error": err, "elapsed": record["elapsed"],
                    **({"score": score} if targets else {})}
            best_path.write_text(json.dumps(best, indent=2))
        if on_eval:
            on_eval(record)
        if target_error is not None and err is not None and record["step"] > 0 and err <= target_error and not reached:
            reached.update(step=record["step"], elapsed=record["elapsed"], window_error=err)
            if stop_at_target:
                raise _TargetReached

    def save_params(step: int, params) -> None:
        algorithm.save(run_dir / CHECKPOINTS, steps_done + int(step), params, env, agent)

    status = "finished"
    try:
        algorithm.run(env, agent, num_timesteps=remaining, seed=agent.seed + steps_done,
                      wrap_env_fn=functools.partial(wrap_for_training, trace_cache=trace_cache), progress_fn=progress,
                      save_fn=save_params, restore=restore, devices=devices, checkpoint_dir=run_dir / CHECKPOINTS)
    except KeyboardInterrupt:
        status = "interrupted"
    except _TargetReached:
        status = "target reached"
    finally:
        if board is not None:
            board.close()
        if wandb_run is not None:
            wandb_run.finish()
    summary = {
        "status": status,
        "env": config.env,
        "devices": devices,
        "env_steps": records[-1]["step"] if records else steps_done,
        "wall_time_s": records[-1]["elapsed"] if records else elapsed_before,
        "last_eval": records[-1] if records else None,
        "checkpoint": str(latest_checkpoint(run_dir)) if latest_checkpoint(run_dir) else None,
        "best": best,
        "target_error": target_error,
        "time_to_target": reached or None,
    }
    if lead:
        (run_dir / "summary.json").write_text(json.dumps(summary, indent=2))
    if status == "interrupted":
        raise KeyboardInterrupt
    return summary


def train_and_evaluate(config: TrainConfig, run_dir: Path, *, evaluate: bool = True, episodes: int = 64, video: bool = True,
                       latest: bool = False, on_trained: Callable[[dict[str, Any]], None] | None = None,
                       **train_kwargs) -> tuple[dict[str, Any], dict[str, Any] | None]:
    """`train` (its keyword arguments pass through), then the final evaluation of the finished run
    (`evaluate.evaluate_finished_run`: the best checkpoint on `episodes` episodes, with `video`; the
    latest too with `latest`), what `marinejax train` and `marinejax bench training` both do. No
    evaluation without `evaluate` or with several processes (a checkpoint loaded through orbax waits
    for every process, and the others have finished). `on_trained(summary)` runs between the two.
    Returns the summary and the evaluation (None where there was none)."""
    from marinejax.train.evaluate import evaluate_finished_run

    summary = train(config, run_dir, **train_kwargs)
    if on_trained is not None:
        on_trained(summary)
    if not evaluate or jax.process_count() > 1:
        return summary, None
    return summary, evaluate_finished_run(run_dir, summary, episodes=episodes, video=video, latest=latest)
