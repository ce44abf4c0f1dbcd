"""Exception and warning classes, by cause.

- :class:`InputError`: what the user can fix (a file, a column, an option value); the CLI turns
  it into one line on stderr and exit status 2.
- :class:`InternalError`: an inconsistency no input can cause (the package misused from
  inside, a broken invariant); the CLI reports it as a bug in pinn-mpc, exit status 1.
- :class:`PinnMpcWarning`: input that is accepted but deserves attention, through
  :mod:`warnings` (so a Python user can filter or capture it); the CLI prints each as one line.
"""

import warnings

__all__ = ["InputError", "InternalError", "ModelFileError", "PinnMpcWarning", "warn", "warn_once"]

_WARNED: set[str] = set()


class InputError(ValueError):
    """Bad user input: a file, a column, an option value. The message says what, where, how to fix."""


class ModelFileError(InputError):
    """A model directory that is missing, truncated, corrupted or inconsistent."""


class InternalError(RuntimeError):
    """A bug in pinn-mpc: an internal inconsistency that no input can cause. The message says
    what was inconsistent and the values."""


class PinnMpcWarning(UserWarning):
    """Input that is accepted but deserves attention (the message says what and why)."""


def warn(message: str) -> None:
    """Warn with ``message`` (:class:`PinnMpcWarning`), attributed to the line that calls this."""
    warnings.warn(message, PinnMpcWarning, stacklevel=2)


def warn_once(message: str) -> None:
    """:func:`warn`, but each message at most once per process (input read several times)."""
    if message not in _WARNED:
        _WARNED.add(message)
        warnings.warn(message, PinnMpcWarning, stacklevel=2)
