"""The CLI's output: a live display on a terminal, plain unwrapped lines in a file or pipe."""

from __future__ import annotations

import sys
from typing import IO

from rich.console import Console

# Wide enough that a benchmark table is never folded; soft_wrap keeps long lines (paths) whole.
_PLAIN_WIDTH = 240


def make_console(file: IO[str] | None = None) -> Console:
    """A rich Console for `file` (default stdout): colours and live bars on a terminal; otherwise no
    markup, colour or wrapping, so that every line can be parsed and paths stay whole."""
    file = file if file is not None else sys.stdout
    if file.isatty():
        return Console(file=file)
    return Console(file=file, soft_wrap=True, width=_PLAIN_WIDTH, no_color=True, highlight=False, emoji=False,
                   force_terminal=False)
