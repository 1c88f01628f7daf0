"""Test-session set-up."""

import os

# Rendering tests (Gymnasium's rgb_array, check_env's render check) run headless: MuJoCo must use EGL,
# and it reads MUJOCO_GL when it is first imported, so this has to happen before any test imports it.
os.environ.setdefault("MUJOCO_GL", "egl")


def pytest_configure(config):
    """The default run (pyproject's -m 'not slow', the README's test command) compiles at XLA's
    backend optimisation level 0: three quarters of a default test's time is compilation, and at
    level 0 the default suite passed whole in 14 min 43 s against 23 min 35 s (2-core AMD EPYC). The
    slow suite's trainings run long compiled code, so they, and any run that names other markers,
    keep XLA's default. A user's own XLA_FLAGS win. Set before the workers start and before any test
    module is imported, so before JAX reads it."""
    if config.option.markexpr == "not slow":
        os.environ.setdefault("XLA_FLAGS", "--xla_backend_optimization_level=0")
