"""Exception classes. The CLI turns :class:`InputError` into one line on stderr and exit 2."""

import sys

__all__ = ["InputError", "ModelFileError", "warn", "warn_once"]

_WARNED: set[str] = set()


class InputError(ValueError):
    """Bad user input: a file, a column, an option value. The message says what, where, how to fix."""


class ModelFileError(InputError):
    """A model directory that is missing, truncated, corrupted or inconsistent."""


def warn(message: str) -> None:
    """Input that is accepted but deserves attention: one line on stderr, as the CLI's errors."""
    print(f"pinn-mpc: warning: {message}", file=sys.stderr)


def warn_once(message: str) -> None:
    """:func:`warn`, but each message at most once per process (input read several times)."""
    if message not in _WARNED:
        _WARNED.add(message)
        warn(message)
