"""Test-session set-up."""

import os
from pathlib import Path

import jax

# Rendering tests (Gymnasium's rgb_array, check_env's render check) run headless: MuJoCo must use EGL,
# and it reads MUJOCO_GL when it is first imported, so this has to happen before any test imports it.
os.environ.setdefault("MUJOCO_GL", "egl")

# JAX's persistent compilation cache, shared by the test processes (both pytest-xdist workers, and
# every pytest run of a checkout, as .ci/run's): most of a test's time is XLA compiling, and some
# modules compile the same functions at the same shapes (from a cold cache the default suite took
# 22 min 11 s against 23 min 37 s without, on a 2-core AMD EPYC; a later run reads it). An
# executable read from the cache is the one XLA compiled, so every number is as without it. In
# .pytest_cache (git ignores it; delete it to compile everything afresh). The CLI's subprocesses
# keep their own (tests/train/cli_runner.py).
jax.config.update("jax_compilation_cache_dir", str(Path(__file__).resolve().parent.parent / ".pytest_cache" / "jax-compilation-cache"))
jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
