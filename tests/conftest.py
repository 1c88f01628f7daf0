"""Test-session set-up."""

import os
from pathlib import Path

# Rendering tests (Gymnasium's rgb_array, check_env's render check) run headless: MuJoCo must use EGL,
# and it reads MUJOCO_GL when it is first imported, so this has to happen before any test imports it.
os.environ.setdefault("MUJOCO_GL", "egl")

# JAX's persistent compilation cache, shared by the test processes (both pytest-xdist workers, and
# every pytest run of a checkout, as .ci/run's): most of a test's time is XLA compiling, and some
# modules compile the same functions at the same shapes (from a cold cache the default suite took
# 22 min 11 s against 23 min 37 s without, on a 2-core AMD EPYC; a later run reads it). An
# executable read from the cache is the one XLA compiled, so every number is as without it. The
# CLI's settings (every compiled function cached), in .pytest_cache (git ignores it; delete it to
# compile everything afresh). The CLI's subprocesses keep their own (tests/train/cli_runner.py).
from marinejax.cli import enable_compile_cache  # noqa: E402 (after MUJOCO_GL)

enable_compile_cache(Path(__file__).resolve().parent.parent / ".pytest_cache" / "jax-compilation-cache")
