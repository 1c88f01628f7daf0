"""Evaluation records of a run (metrics.jsonl): their errors, the score a best checkpoint is chosen
on, and the learning-curve PNG."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Mapping

WINDOW_ERROR = "eval/episode_window_error"  # mean over evaluation episodes of the task's window error, m
# What the best checkpoint is chosen on (the algorithm's `best_on`): the lowest window error, or the
# lowest of each target's error over its target, the largest ratio counting (`MarineEnv.targets`)
BEST_ON = ("window_error", "targets")


def evaluation_error(record: dict) -> float | None:
    """The evaluation error of a metrics.jsonl record (m): the task's window error (what `marinejax
    eval` reports), or for runs from before it was logged, the mean error over whole episodes."""
    if WINDOW_ERROR in record:
        return record[WINDOW_ERROR]
    if "eval/episode_position_error" in record:
        return record["eval/episode_position_error"] / max(record.get("eval/avg_episode_length", 1.0), 1.0)
    return None


def checkpoint_score(record: dict, targets: Mapping[str, float] | None = None) -> float | None:
    """What a best checkpoint minimises, from an evaluation record: the window error (m), or with
    `targets` (error name → target, `MarineEnv.targets`) the largest of the errors' means over the
    window each divided by its target (≤ 1: every target met). None: the record has no evaluation."""
    if not targets:
        return record.get(WINDOW_ERROR)
    keys = {name: WINDOW_ERROR if name == "position_error" else f"eval/episode_window_{name}" for name in targets}
    if any(key not in record for key in keys.values()):
        return None
    return max(record[keys[name]] / target for name, target in targets.items())


def plot_learning_curve(run_dir: Path) -> Path:
    """curve.png: evaluation return and evaluation error against env steps and wall time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    run_dir = Path(run_dir)
    records = [json.loads(line) for line in (run_dir / "metrics.jsonl").read_text().splitlines() if line.strip()]
    records = [r for r in records if "eval/episode_reward" in r]
    steps = [r["step"] for r in records]
    minutes = [r["elapsed"] / 60 for r in records]
    ret = [r["eval/episode_reward"] for r in records]
    err = [evaluation_error(r) for r in records]
    fig, axes = plt.subplots(2, 2, figsize=(11, 6.5), sharey="row")
    for col, (x, label) in enumerate([(steps, "env steps"), (minutes, "wall time (min, compilation included)")]):
        axes[0, col].plot(x, ret, "o-", ms=3)
        axes[1, col].plot(x, err, "o-", ms=3, color="C3")
        axes[1, col].set_yscale("log")
        axes[1, col].set_xlabel(label)
    axes[0, 0].set_ylabel("evaluation return")
    axes[1, 0].set_ylabel("evaluation position error (m)\n(task window, mean over episodes)")
    config = json.loads((run_dir / "config.json").read_text())
    fig.suptitle(f"{config['env']}: {run_dir.name}")
    fig.tight_layout()
    out = run_dir / "curve.png"
    fig.savefig(out, dpi=100)
    plt.close(fig)
    return out
