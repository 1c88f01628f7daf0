"""Checkpoints of a run directory: which one to use, and the trained policy they hold.

A run directory keeps its algorithm's Brax checkpoints (PPO or SAC) in checkpoints/<env steps>/ and
names the one with the lowest evaluation error in best.json; shipped policies are run directories
inside the package.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import warnings
from importlib import resources
from pathlib import Path
from typing import Any

from marinejax.errors import UserError
from marinejax.train.hyperparams import ALGORITHMS, build_env, load_train_config

CHECKPOINTS = "checkpoints"
BEST = "best.json"


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

    For a run directory, `which` picks "best" (best.json's: the lowest evaluation error during
    training, or with `best_on="targets"` the nearest to every target; the newest if the run has
    none) or "latest" (the newest checkpoint)."""
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


def load_params(path: Path | str, env_overrides: dict[str, Any] | None = None, which: str = "best"):
    """(train config, env, the algorithm's Brax params (normalizer, policy[, value]), checkpoint dir)
    from a run, a checkpoint or a shipped policy's env name; checks the env's sizes against the
    checkpoint's."""
    run_dir, ckpt = resolve_checkpoint(path, which)
    try:
        config = load_train_config(run_dir)
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise CheckpointError(f"cannot read {run_dir / 'config.json'}: {err}") from None
    if env_overrides:
        config = dataclasses.replace(config, env_overrides={**config.env_overrides, **env_overrides})
    env = build_env(config)
    try:
        net_config = json.loads((ckpt / config.module.NETWORK_CONFIG).read_text())
        absl = logging.getLogger("absl")
        level = absl.level
        with warnings.catch_warnings():  # orbax warns about sharding metadata of CPU checkpoints
            warnings.simplefilter("ignore")
            absl.setLevel(logging.ERROR)  # ... and logs them through absl: quiet for this load only
            try:
                params = config.module.load(ckpt)
            finally:
                absl.setLevel(level)
    except Exception as err:  # orbax raises many kinds of errors on damaged files
        raise CheckpointError(f"checkpoint {ckpt} could not be read: {type(err).__name__}: {err}") from None
    if net_config.get("observation_size") != json.loads(json.dumps(env.observation_size)) or net_config.get("action_size") != env.action_size:
        raise CheckpointError(
            f"checkpoint {ckpt} expects observations of size {net_config.get('observation_size')} and actions of size "
            f"{net_config.get('action_size')}; env {config.env} has {env.observation_size} and {env.action_size}"
        )
    return config, env, params, ckpt


def load_policy(path: Path, env_overrides: dict[str, Any] | None = None, which: str = "best"):
    """(train config, env, deterministic policy fn obs -> action, checkpoint dir) from a run or checkpoint."""
    config, env, params, ckpt = load_params(path, env_overrides, which)
    return config, env, config.module.policy(config.agent, env, params), ckpt


def _complete(ckpt: Path) -> bool:
    """Whether a checkpoint directory was written to the end (its network config comes last)."""
    return any((ckpt / module.NETWORK_CONFIG).exists() for module in ALGORITHMS.values())


def latest_checkpoint(run_dir: Path) -> Path | None:
    """Newest complete checkpoint directory of a run, or None."""
    root = Path(run_dir) / CHECKPOINTS
    steps = sorted((p for p in root.glob("*") if p.is_dir() and p.name.isdigit()), key=lambda p: int(p.name))
    for p in reversed(steps):
        if _complete(p):
            return p
    return None


def best_checkpoint(run_dir: Path) -> Path | None:
    """The checkpoint named in the run's best.json (lowest evaluation error), or None."""
    try:
        best = json.loads((Path(run_dir) / BEST).read_text())
    except (OSError, ValueError):
        return None
    path = Path(run_dir) / CHECKPOINTS / f"{int(best['step']):012d}"
    return path if _complete(path) else None
