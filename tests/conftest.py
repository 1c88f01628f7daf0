"""Test-session set-up."""

import os
from pathlib import Path

# Rendering tests (Gymnasium's rgb_array, check_env's render check) run headless: MuJoCo must use EGL,
# and it reads MUJOCO_GL when it is first imported, so this has to happen before any test imports it.
os.environ.setdefault("MUJOCO_GL", "egl")

# JAX's persistent compilation cache, shared by the test processes (both pytest-xdist workers, and
# every pytest run of a checkout): most of a test's time is XLA compiling, and some modules compile
# the same functions at the same shapes (from a cold cache the default suite took 22 min 11 s against
# 23 min 37 s without, on a 2-core AMD EPYC, at XLA's default optimisation level; a later run reads
# it). An executable read from the cache is the one XLA compiled with the same flags, so every
# number is as without it. The CLI's settings (every compiled function cached), in .pytest_cache (git
# ignores it; delete it to compile everything afresh). The CLI's subprocesses keep their own
# (tests/train/cli_runner.py).
from marinejax.cli import enable_compile_cache  # noqa: E402 (after MUJOCO_GL)

enable_compile_cache(Path(__file__).resolve().parent.parent / ".pytest_cache" / "jax-compilation-cache")


def pytest_configure(config):
    """The default run (pyproject's -m 'not slow', the README's test command) compiles at XLA's
    backend optimisation level 0: most of a default test's time is compilation, and at level 0 the
    default suite passes whole in about two thirds of the time (14 min 43 s against 23 min 35 s on a
    2-core AMD EPYC). Its assertions hold under either compilation (a level changes the rounding of
    the arithmetic, not its result beyond that). The slow suite's trainings and recorded numbers,
    and any run that names other markers (-m "", CI's RL-client and oldest-stack runs), keep XLA's
    default, as users' runs do; a user's own XLA_FLAGS win. Set before the workers start and before
    anything is compiled, so before XLA reads it."""
    if config.option.markexpr == "not slow":
        os.environ.setdefault("XLA_FLAGS", "--xla_backend_optimization_level=0")
