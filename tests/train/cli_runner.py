"""The CLI as a user runs it, for the CLI's test modules: a console-script call with the tests' own
compilation cache, and the smallest training settings."""

import os
import subprocess
import sys
import tempfile
from pathlib import Path

TINY = [
    "--timesteps", "1600", "--episodes", "4",
    "--ppo", "num_envs=8", "--ppo", "batch_size=8", "--ppo", "num_minibatches=2", "--ppo", "unroll_length=5",
    "--ppo", "num_evals=3", "--ppo", "num_eval_envs=4", "--ppo", "policy_hidden=(16,)", "--ppo", "value_hidden=(16,)",
    "--env", "episode_length=20",
]


# JAX's persistent compilation cache of these CLI runs (on by default) goes here, not in the user's.
CACHE_HOME = Path(tempfile.mkdtemp(prefix="marinejax-test-cache-"))
TRACED = CACHE_HOME / "marinejax" / "traced-envs"


def traced() -> dict[str, int]:
    """The envs' traced functions the CLI has kept so far (`envs/trace_cache.py`): name -> mtime."""
    return {p.name: p.stat().st_mtime_ns for p in TRACED.iterdir()} if TRACED.is_dir() else {}


def marinejax(*args, timeout=600, cwd=None, extra_env=None):
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "XDG_CACHE_HOME": str(CACHE_HOME), **(extra_env or {})}
    return subprocess.run([sys.executable, "-m", "marinejax.cli", *args], capture_output=True, text=True, timeout=timeout,
                          env=env, cwd=cwd)
