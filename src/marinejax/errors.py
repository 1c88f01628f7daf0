"""Exception types: what the user asked for is wrong (`UserError`), as opposed to a bug.

The CLI reports a `UserError` in one line and exits with code 2; any other exception is a bug and
shows its traceback. `UserError` subclasses ValueError, so code that catches ValueError keeps working.
"""

from __future__ import annotations


class UserError(ValueError):
    """A bad value in what the user asked for: the message names it and the valid choices."""


class MissingFileError(UserError, FileNotFoundError):
    """A file or directory the user named does not exist (or is not what it should be)."""
