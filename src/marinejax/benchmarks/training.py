"""Training results over seeds: train every env on seeds 0..N-1, evaluate each, report median and worst.

    marinejax bench training ENV [ENV ...] [--seeds 5] [--out-dir runs/bench-training]
                             [--target-error 0.02] [--timesteps N] [--ppo KEY=VALUE] [--env KEY=VALUE]

Each seed is exactly `marinejax train ENV --seed S` (the tuned settings plus any overrides) followed
by the evaluation of `marinejax eval` (64 deterministic episodes, seed 12345, the task's error
window, the best checkpoint), and of the latest checkpoint on the same episodes (convergence: is
the final policy as good as the best?). Per env it prints and writes the median and worst (largest)
final error over the seeds, the latest checkpoint's error over the best's, success rates, training
wall time (compilation included) and the time to target: env steps and wall seconds at the first
evaluation during training whose error met `--target-error`. Files in --out-dir: results.json,
results.csv (one row per seed), <ENV>-seeds.png (every seed's learning curve against env steps and
wall time, with the median and min-max band), and each seed's run directory <ENV>/seed-<S>/.

Finished seeds are kept: rerunning the same command skips them and resumes an interrupted one from
its newest checkpoint, so a long benchmark can be stopped (Ctrl-C) and continued.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import shutil
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from marinejax.benchmarks.common import positive
from marinejax.machine import machine_info

DEFAULT_TARGET_M = 0.02


class _Parser(argparse.ArgumentParser):
    """argparse that reports a bad argument on one line (no usage block) and exits with 2."""

    def error(self, message: str):
        print(f"{self.prog}: error: {message}", file=sys.stderr)
        raise SystemExit(2)


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="marinejax bench training", description=__doc__.splitlines()[0])
    p.add_argument("envs", nargs="+", metavar="ENV", help="env names (see marinejax.list_envs())")
    p.add_argument("--seeds", type=positive(int), default=5, help="train seeds 0..N-1 (default 5)")
    p.add_argument("--out-dir", type=Path, default=Path("runs/bench-training"), help="where runs and results go")
    p.add_argument("--target-error", type=positive(float), default=DEFAULT_TARGET_M,
                   help=f"error (m) for the time-to-target figures (default {DEFAULT_TARGET_M})")
    p.add_argument("--timesteps", type=positive(int), help="env steps per run (default: the tuned value)")
    p.add_argument("--algo", choices=["ppo", "sac"], default="ppo", help="training algorithm (default ppo)")
    p.add_argument("--algo-opts", action="append", metavar="KEY=VALUE", help="override a setting of the algorithm for every run")
    p.add_argument("--ppo", action="append", metavar="KEY=VALUE", help="override a PPO setting for every run (--algo ppo)")
    p.add_argument("--env", action="append", metavar="KEY=VALUE", help="override an env setting for every run")
    p.add_argument("--episodes", type=positive(int), default=64, help="evaluation episodes per seed (default 64)")
    p.add_argument("--profile", action="store_true",
                   help="instead of training over seeds, show where a PPO training step's time goes (env, policy, "
                        "loss and gradient, optimizer, evaluation, compilation); writes profile-<ENV>.json")
    return p


def run_seed(env_name: str, seed: int, run_dir: Path, agent: dict, env: dict, target: float, episodes: int,
             log=print, trace_cache: Path | None = None, algorithm: str = "ppo", stop_at_target: bool = False) -> dict[str, Any]:
    """Train (or resume, or reuse) one seed and evaluate it; returns its result row. `agent`: overrides
    of the algorithm's settings; `trace_cache`: as `train`'s; `stop_at_target`: end the training at
    the first evaluation within `target` m (the benchmark trains the whole budget)."""
    from marinejax.train.evaluate import evaluate_finished_run
    from marinejax.train.hyperparams import load_train_config, tuned_config, with_overrides
    from marinejax.train.curves import WINDOW_ERROR
    from marinejax.train.checkpoints import latest_checkpoint
    from marinejax.train.runner import resumable, train_and_evaluate

    summary_path = run_dir / "summary.json"
    summary = json.loads(summary_path.read_text()) if summary_path.exists() else {}
    if summary.get("status") == "finished" and "evaluation_latest" in summary:
        log(f"{env_name} seed {seed}: finished earlier, reusing {run_dir}")
    elif summary.get("status") == "finished":  # evaluated before the latest checkpoint was
        log(f"{env_name} seed {seed}: finished earlier, evaluating its checkpoints in {run_dir}")
        evaluate_finished_run(run_dir, summary, episodes=episodes, video=False, latest=True)
    else:
        resume = (run_dir / "config.json").exists()
        config = load_train_config(run_dir) if resume else None
        # nothing to resume: stopped before its first checkpoint, or SAC (Brax cannot restore it, `train.sac`)
        if resume and (latest_checkpoint(run_dir) is None or not resumable(config)):
            log(f"{env_name} seed {seed}: the unfinished run cannot be resumed; training it again in {run_dir}")
            shutil.rmtree(run_dir)
            resume = False
        if not resume:
            config = with_overrides(tuned_config(env_name, algorithm), agent={**agent, "seed": seed}, env=env)

        def on_eval(r: dict) -> None:
            err = r.get(WINDOW_ERROR)
            log(f"{env_name} seed {seed}: {r['step']:>10,} env steps, {r['elapsed']:6.0f} s, "
                f"evaluation error {err if err is None else f'{err:.4f} m'}")

        summary, _ = train_and_evaluate(config, run_dir, episodes=episodes, video=False, latest=True, resume=resume, on_eval=on_eval,
                                        target_error=target, stop_at_target=stop_at_target, trace_cache=trace_cache)
    ev, latest = summary["evaluation"], summary["evaluation_latest"]
    reached = summary.get("time_to_target") or {}
    return {
        "env": env_name, "seed": seed, "run_dir": str(run_dir),
        "error_mean_m": ev["position_error_mean_m"], "error_p95_m": ev["position_error_p95_m"],
        "heading_error_mean_deg": ev.get("heading_error_mean_deg"),
        # m/s, for tasks with a commanded speed (the torpedo autopilot), else None
        "speed_error_mean": ev.get("speed_error_mean"),
        "success_rate": ev["success_rate"], "checkpoint": ev["checkpoint"],
        # the training evaluations' window error (m) of the best and of the last checkpoint: convergence
        "best_eval_error_m": (summary.get("best") or {}).get("window_error"),
        "last_eval_error_m": (summary.get("last_eval") or {}).get(WINDOW_ERROR),
        # the latest checkpoint on the same evaluation episodes as the best (the training evaluations
        # draw new episodes each time, so the best of them is partly the luck of its episodes)
        "latest_error_mean_m": latest["position_error_mean_m"], "latest_heading_error_mean_deg": latest.get("heading_error_mean_deg"),
        "latest_speed_error_mean": latest.get("speed_error_mean"),
        "latest_checkpoint": latest["checkpoint"], "latest_over_best": latest_over_best(latest["position_error_mean_m"], ev["position_error_mean_m"]),
        "env_steps": summary["env_steps"], "wall_time_s": summary["wall_time_s"],
        "target_m": target,
        "target_steps": reached.get("step"), "target_wall_s": reached.get("elapsed"),
    }


def latest_over_best(latest: float, best: float) -> float:
    """The latest checkpoint's evaluation error over the best's: 1 where both are 0 (a docking task's
    policies that dock every episode), infinite where only the best's is."""
    if best > 0:
        return latest / best
    return 1.0 if latest == 0 else math.inf


def aggregate(rows: list[dict[str, Any]], target: float) -> dict[str, Any]:
    """Median and worst over the seeds of one env."""
    err = np.array([r["error_mean_m"] for r in rows])
    reached = [r for r in rows if r["target_steps"] is not None]
    out = {
        "env": rows[0]["env"], "seeds": [r["seed"] for r in rows], "errors_m": err.tolist(),
        "error_median_m": float(np.median(err)), "error_worst_m": float(err.max()),
        **_median_worst("heading_error_deg", [r.get("heading_error_mean_deg") for r in rows]),
        **_median_worst("speed_error", [r.get("speed_error_mean") for r in rows]),
        **_median_worst("latest_over_best", [r["latest_over_best"] for r in rows]),
        "success_median": float(np.median([r["success_rate"] for r in rows])),
        "success_worst": float(min(r["success_rate"] for r in rows)),
        "wall_median_s": float(np.median([r["wall_time_s"] for r in rows])),
        "wall_worst_s": float(max(r["wall_time_s"] for r in rows)),
        "final_error_met_target": int(np.sum(err <= target)),
        "reached_target_during_training": len(reached),
    }
    if reached:
        out["target_steps_median"] = float(np.median([r["target_steps"] for r in reached]))
        out["target_wall_median_s"] = float(np.median([r["target_wall_s"] for r in reached]))
    return out


def _median_worst(name: str, values: list) -> dict[str, float]:
    """`<name>_median` and `<name>_worst` (the largest) of values that every seed has, else nothing."""
    if not values or any(v is None for v in values):
        return {}
    return {f"{name}_median": float(np.median(values)), f"{name}_worst": float(max(values))}


def plot_seeds(env_name: str, rows: list[dict[str, Any]], target: float, out: Path) -> Path:
    """Every seed's evaluation error against env steps and wall time, with median and min-max band."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from marinejax.train.curves import evaluation_error

    curves = []
    for r in rows:
        recs = [json.loads(line) for line in (Path(r["run_dir"]) / "metrics.jsonl").read_text().splitlines() if line.strip()]
        recs = [x for x in recs if evaluation_error(x) is not None]
        curves.append((np.array([x["step"] for x in recs]), np.array([x["elapsed"] for x in recs]),
                       np.array([evaluation_error(x) for x in recs])))
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.4), sharey=True)
    n = min(len(c[0]) for c in curves)
    stack = np.stack([c[2][:n] for c in curves])
    for ax, col, label in ((axes[0], 0, "env steps"), (axes[1], 1, "wall time (s, compilation included)")):
        for (seed_row, c) in zip(rows, curves):
            ax.plot(c[col], c[2], lw=0.8, alpha=0.6, label=f"seed {seed_row['seed']}")
        x = np.median(np.stack([c[col][:n] for c in curves]), axis=0)
        ax.fill_between(x, stack.min(axis=0), stack.max(axis=0), color="0.6", alpha=0.3, label="min-max")
        ax.plot(x, np.median(stack, axis=0), "k", lw=2, label="median")
        ax.axhline(target, color="C3", ls="--", lw=1, label=f"target {target} m")
        ax.set_yscale("log")
        ax.set_xlabel(label)
    axes[0].set_ylabel("evaluation position error (m)")
    axes[1].legend(fontsize=8)
    fig.suptitle(f"{env_name}: {len(rows)} seeds")
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    plt.close(fig)
    return out


def main(argv: list[str] | None = None, trace_cache: Path | None = None) -> int:
    """`marinejax bench training`; `trace_cache` as `train`'s (the CLI passes its folder)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    from marinejax.config import parse_key_values
    from marinejax.envs import list_envs

    unknown = [e for e in args.envs if e not in list_envs()]
    if unknown:
        print(f"marinejax bench training: error: unknown env {unknown[0]!r}; valid: {list_envs()}", file=sys.stderr)
        return 2
    if args.ppo and args.algo != "ppo":
        print(f"marinejax bench training: error: --ppo applies to --algo ppo; use --algo-opts for {args.algo}", file=sys.stderr)
        return 2
    if args.profile and args.algo != "ppo":
        print(f"marinejax bench training: error: --profile profiles PPO's training step, not {args.algo}'s", file=sys.stderr)
        return 2
    agent = {**parse_key_values(args.ppo, "--ppo"), **parse_key_values(args.algo_opts, "--algo-opts")}
    if args.timesteps:
        agent["num_timesteps"] = args.timesteps
    env_overrides = parse_key_values(args.env, "--env")
    out_dir = args.out_dir
    out_dir.mkdir(parents=True, exist_ok=True)
    # before anything starts JAX's backend: as many CPU devices as the recipes train on
    from marinejax.train.hyperparams import tuned_config, with_overrides
    from marinejax.train.runner import use_cpu_devices

    use_cpu_devices(max(with_overrides(tuned_config(e, args.algo), agent=agent).agent.cpu_devices for e in args.envs))
    info = machine_info()
    if args.profile:
        return _profile(args, agent, env_overrides, info)
    print(f"marinejax bench training: {args.envs}, seeds 0..{args.seeds - 1}, target {args.target_error} m -> {out_dir}", flush=True)
    print(f"machine: {info['cpu']} | {info['cpu_count']} cores | jax {info['jax']} {info['backend']}", flush=True)
    start = time.perf_counter()
    all_rows, summaries = [], []
    for env_name in args.envs:
        rows = []
        for seed in range(args.seeds):
            row = run_seed(env_name, seed, out_dir / env_name / f"seed-{seed}", agent, env_overrides,
                           args.target_error, args.episodes, log=lambda m: print(m, flush=True), trace_cache=trace_cache,
                           algorithm=args.algo)
            others = "" if row["heading_error_mean_deg"] is None else f", heading {row['heading_error_mean_deg']:.2f}°"
            others += "" if row["speed_error_mean"] is None else f", speed {row['speed_error_mean']:.3f} m/s"
            print(f"{env_name} seed {seed}: error {row['error_mean_m']:.4f} m{others}, success {100 * row['success_rate']:.0f} %, "
                  f"training {row['wall_time_s']:.0f} s; latest checkpoint {row['latest_error_mean_m']:.4f} m "
                  f"({row['latest_over_best']:.2f}× the best)", flush=True)
            rows.append(row)
        agg = aggregate(rows, args.target_error)
        agg["plot"] = str(plot_seeds(env_name, rows, args.target_error, out_dir / f"{env_name}-seeds.png"))
        all_rows += rows
        summaries.append(agg)
        _write(out_dir, info, args, all_rows, summaries)
    print()
    print(f"{'env':36s} {'median error':>13s} {'worst error':>12s} {'seeds <= target':>16s} {'success (worst)':>16s} "
          f"{'wall median/worst':>18s} {'to target (median)':>22s}")
    for a in summaries:
        to_target = (f"{a['target_steps_median'] / 1e6:.1f} M, {a['target_wall_median_s']:.0f} s"
                     if "target_steps_median" in a else "never")
        print(f"{a['env']:36s} {a['error_median_m']:11.4f} m {a['error_worst_m']:10.4f} m "
              f"{a['final_error_met_target']:>10d} of {len(a['seeds'])} {100 * a['success_worst']:>15.0f} % "
              f"{a['wall_median_s']:8.0f} / {a['wall_worst_s']:.0f} s {to_target:>22s}")
    print(f"total {time.perf_counter() - start:.0f} s; results in {out_dir / 'results.json'} and results.csv")
    return 0


def _profile(args: argparse.Namespace, agent: dict, env_overrides: dict, info: dict) -> int:
    from marinejax.benchmarks.profile import profile, report

    print(f"machine: {info['cpu']} | {info['cpu_count']} cores | jax {info['jax']} {info['backend']}", flush=True)
    for env_name in args.envs:
        result = profile(env_name, agent, env_overrides)
        print(report(result), flush=True)
        (args.out_dir / f"profile-{env_name}.json").write_text(json.dumps({"machine": info, **result}, indent=2))
    return 0


def _write(out_dir: Path, info: dict, args: argparse.Namespace, rows: list[dict], summaries: list[dict]) -> None:
    settings = {"envs": args.envs, "seeds": args.seeds, "target_error_m": args.target_error, "timesteps": args.timesteps,
                "algorithm": args.algo, "ppo": args.ppo or [], "algo_opts": args.algo_opts or [], "env": args.env or [],
                "episodes": args.episodes}
    (out_dir / "results.json").write_text(json.dumps({"machine": info, "settings": settings, "envs": summaries,
                                                      "seeds": rows}, indent=2))
    with (out_dir / "results.csv").open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


if __name__ == "__main__":
    raise SystemExit(main())
