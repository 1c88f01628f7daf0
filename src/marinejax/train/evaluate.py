"""Deterministic evaluation of a trained policy: statistics, path plot and video.

Error statistics use, per episode, the mean position error over the last second (station keeping)
or after the first 2 s (tracking, once the reference has ramped up), then report the mean, median
and 95th percentile over episodes, and the success rate (that per-episode error below `success_m`).
"""

from __future__ import annotations

import json
import logging
import warnings
from importlib import resources
from pathlib import Path
from typing import Any

import jax
import numpy as np

from marinejax.control import policy_controller, rollout
from marinejax.envs.base import MarineEnv
from marinejax.errors import UserError
from marinejax.train.hyperparams import TrainConfig

SUCCESS_M = 0.1  # m: an episode succeeds when its evaluated mean position error is below this


class CheckpointError(UserError):
    """A checkpoint or run directory that cannot be used (missing, incomplete or corrupt)."""


def shipped_policies() -> dict[str, Path]:
    """Env name → run directory of the trained policies installed with marinejax."""
    root = Path(str(resources.files("marinejax"))) / "policies"
    return {p.name: p for p in sorted(root.iterdir()) if (p / "config.json").exists()} if root.is_dir() else {}


CHECKPOINT_CHOICES = ("best", "latest")


def resolve_checkpoint(path: Path | str, which: str = "best") -> tuple[Path, Path]:
    """(run directory, checkpoint step directory) for a run directory, a checkpoint directory, or the
    name of an env with a shipped policy (e.g. "BlueROV2Heavy-StationKeeping").

    For a run directory, `which` picks "best" (lowest evaluation error during training, from
    best.json; the newest if the run has none) or "latest" (the newest checkpoint)."""
    from marinejax.train.runner import CHECKPOINTS, best_checkpoint, latest_checkpoint

    if which not in CHECKPOINT_CHOICES:
        raise UserError(f"unknown checkpoint choice {which!r}; valid: {list(CHECKPOINT_CHOICES)}")

    shipped = shipped_policies()
    if not Path(path).exists() and str(path) in shipped:
        path = shipped[str(path)]
    path = Path(path)
    if not path.exists():
        raise CheckpointError(f"no such run directory or checkpoint: {path} (shipped policies: {sorted(shipped)})")
    path = path.resolve()  # orbax reads absolute paths only
    if (path / "config.json").exists():
        ckpt = (best_checkpoint(path) if which == "best" else None) or latest_checkpoint(path)
        if ckpt is None:
            raise CheckpointError(f"run directory {path} has no complete checkpoint in {path / CHECKPOINTS}")
        return path, ckpt
    if path.parent.name == CHECKPOINTS and (path.parent.parent / "config.json").exists():
        return path.parent.parent, path
    raise CheckpointError(f"{path} is neither a run directory (with config.json) nor a checkpoint inside one")


def load_policy(path: Path, env_overrides: dict[str, Any] | None = None, which: str = "best"):
    """(train config, env, deterministic policy fn obs -> action, checkpoint dir) from a run or checkpoint."""
    from brax.training import types
    from brax.training.acme import running_statistics
    from brax.training.agents.ppo import checkpoint as ppo_checkpoint
    from brax.training.agents.ppo import networks as ppo_networks

    from marinejax.train.runner import build_env, load_train_config, network_factory

    run_dir, ckpt = resolve_checkpoint(path, which)
    try:
        config = load_train_config(run_dir)
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise CheckpointError(f"cannot read {run_dir / 'config.json'}: {err}") from None
    if env_overrides:
        config = TrainConfig(env=config.env, ppo=config.ppo, env_overrides={**config.env_overrides, **env_overrides})
    env = build_env(config)
    try:
        net_config = json.loads((ckpt / "ppo_network_config.json").read_text())
        absl = logging.getLogger("absl")
        level = absl.level
        with warnings.catch_warnings():  # orbax warns about sharding metadata of CPU checkpoints
            warnings.simplefilter("ignore")
            absl.setLevel(logging.ERROR)  # ... and logs them through absl: quiet for this load only
            try:
                params = ppo_checkpoint.load(ckpt)
            finally:
                absl.setLevel(level)
    except Exception as err:  # orbax raises many kinds of errors on damaged files
        raise CheckpointError(f"checkpoint {ckpt} could not be read: {type(err).__name__}: {err}") from None
    if net_config.get("observation_size") != env.observation_size or net_config.get("action_size") != env.action_size:
        raise CheckpointError(
            f"checkpoint {ckpt} expects observations of size {net_config.get('observation_size')} and actions of size "
            f"{net_config.get('action_size')}; env {config.env} has {env.observation_size} and {env.action_size}"
        )
    # Brax 0.14's checkpoint.load_policy cannot rebuild networks it saved itself; build it as ppo.train does.
    normalize = running_statistics.normalize if config.ppo.normalize_observations else types.identity_observation_preprocessor
    network = network_factory(config.ppo)(env.observation_size, env.action_size, preprocess_observations_fn=normalize)
    inference = ppo_networks.make_inference_fn(network)(params, deterministic=True)
    return config, env, (lambda obs: inference(obs, jax.random.PRNGKey(0))[0]), ckpt


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


def plot_paths(result: dict[str, np.ndarray], title: str, out: Path, episode: int = 0) -> Path:
    """PNG: the vehicle's path against the reference in 3-D and from the top, and the error over time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    p, r, t = result["position"][episode], result["target"][episode], result["time"]
    fig = plt.figure(figsize=(14, 4.6))
    station = bool(np.allclose(r, r[0]))  # station keeping: the reference is one point
    ax = fig.add_subplot(1, 3, 1, projection="3d")
    ax.plot(*(r[:1].T if station else r.T), "r*" if station else "k--", lw=1, ms=10, label="target" if station else "reference")
    ax.plot(*p.T, "C0", lw=1.5, label="vehicle")
    ax.set_xlabel("x (m)"), ax.set_ylabel("y (m)"), ax.set_zlabel("z (m)")
    ax.legend(loc="upper left")
    ax2 = fig.add_subplot(1, 3, 2)
    ax2.plot(r[:1, 0] if station else r[:, 0], r[:1, 1] if station else r[:, 1], "r*" if station else "k--", lw=1, ms=12,
             label="target" if station else "reference")
    ax2.plot(p[:, 0], p[:, 1], "C0", lw=1.5, label="vehicle")
    ax2.plot(p[0, 0], p[0, 1], "go", label="start")
    ax2.set_aspect("equal", adjustable="datalim")
    ax2.set_xlabel("x (m)"), ax2.set_ylabel("y (m)"), ax2.set_title("top view")
    ax2.legend()
    ax3 = fig.add_subplot(1, 3, 3)
    for e in range(result["error"].shape[0]):
        ax3.plot(t, result["error"][e], color="0.8", lw=0.6)
    ax3.plot(t, result["error"][episode], "C0", lw=1.5, label=f"episode {episode}")
    ax3.plot(t, np.median(result["error"], axis=0), "C3", lw=1.2, label="median of episodes")
    ax3.set_yscale("log"), ax3.set_xlabel("time (s)"), ax3.set_ylabel("position error (m)")
    ax3.legend()
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def evaluate_run(path: Path, out_dir: Path | None = None, episodes: int = 64, seed: int = 12345,
                 env_overrides: dict[str, Any] | None = None, video: bool = True, which: str = "best") -> dict[str, Any]:
    """Evaluate a run directory or checkpoint (`which`: "best" or "latest" of a run directory);
    write eval.json, path PNG and video into out_dir."""
    from marinejax.train.runner import best_checkpoint, latest_checkpoint

    config, env, policy, ckpt = load_policy(path, env_overrides, which)
    run_dir = ckpt.parent.parent  # checkpoints live in <run>/checkpoints/<step>
    if ckpt == best_checkpoint(run_dir):
        kind = "best (lowest evaluation error during training)"
    elif ckpt == latest_checkpoint(run_dir):
        kind = "newest"
    else:
        kind = "as given"
    if out_dir is None and run_dir.parent == Path(str(resources.files("marinejax"))) / "policies":
        out_dir = Path("runs") / f"eval-{config.env}"  # never write into the installed package
    out_dir = Path(out_dir) if out_dir else run_dir / "eval"
    out_dir.mkdir(parents=True, exist_ok=True)
    result = rollout_policy(env, policy, episodes, seed)
    summary = {"env": config.env, "checkpoint": str(ckpt), "checkpoint_kind": kind, "env_overrides": env_overrides or {}, "seed": seed,
               **summarize(env, result)}
    summary["plot"] = str(plot_paths(result, f"{config.env}: checkpoint {ckpt.name}, episode 0", out_dir / "paths.png"))
    if video:
        from marinejax.render import render_video
        from marinejax.vehicle import model_dir

        model = model_dir() / f"{env.vehicle.name}.xml"
        try:
            summary["video"] = str(render_video(model, result["qpos"][0], result["target"][0], 1.0 / env.config.control_dt, out_dir / "episode0"))
        except RuntimeError as err:
            summary["video_error"] = str(err)
    (out_dir / "eval.json").write_text(json.dumps(summary, indent=2))
    return summary
