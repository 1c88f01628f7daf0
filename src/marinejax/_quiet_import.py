"""Imports MuJoCo MJX without its start-up chatter.

`mujoco.mjx` prints "Failed to import warp: ..." and "Failed to import mujoco_warp: ..." on standard
output when the optional GPU backend `warp` is not installed (the normal case). A user cannot act on
it and it ends up in anything they pipe, so marinejax imports MJX first, here, and drops exactly those
lines; anything else MJX prints passes through. Nothing global is changed after the import.
"""

from __future__ import annotations

import contextlib
import io
import re
import sys

_WARP_NOTICE = re.compile(r"^Failed to import (mujoco_)?warp\b")


def import_mjx_quietly() -> None:
    """Import `mujoco.mjx` (once per process), dropping only its "Failed to import warp" lines."""
    if "mujoco.mjx" in sys.modules:
        return
    captured = io.StringIO()
    with contextlib.redirect_stdout(captured):
        import mujoco.mjx  # noqa: F401
    for line in captured.getvalue().splitlines():
        if not _WARP_NOTICE.match(line):
            print(line)
