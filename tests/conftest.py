"""Test-session set-up."""

import os

# Rendering tests (Gymnasium's rgb_array, check_env's render check) run headless: MuJoCo must use EGL,
# and it reads MUJOCO_GL when it is first imported, so this has to happen before any test imports it.
os.environ.setdefault("MUJOCO_GL", "egl")
