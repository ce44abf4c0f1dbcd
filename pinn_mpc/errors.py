"""Exception and warning classes, by cause.

- :class:`InputError`: what the user can fix (a file, a column, an option value); the CLI turns
  it into one line on stderr and exit status 2.
- :class:`InternalError`: an inconsistency no input can cause (the package misused from
  inside, a broken invariant); the CLI reports it as a bug in pinn-mpc, exit status 1.
- :class:`PinnMpcWarning`: input that is accepted but deserves attention, through
  :mod:`warnings` (so a Python user can filter or capture it); the CLI prints each as one line.

A Python caller's misuse of the API (an argument out of its range, of the wrong type) is a
plain :class:`ValueError` or :class:`TypeError`, as Python's own functions raise.

A message names a setting (a parameter, a config field, a key) by its name, marked with
:func:`setting`: a Python caller reads the name, and the command line, which knows which flag
sets what, names the flag instead (:meth:`InputError.text`); a warning's message too
(:meth:`PinnMpcWarning.text`).
"""

import re
import warnings
from collections.abc import Mapping

__all__ = [
    "InputError",
    "InternalError",
    "ModelFileError",
    "PinnMpcWarning",
    "setting",
    "warn",
    "warn_once",
]

_WARNED: set[str] = set()

#: A marked setting in a message: ``\x1fNAME\x1f``, or ``\x1fNAME\x1eWORDS\x1f`` where a
#: Python caller reads WORDS instead of the name (see :func:`setting`).
_MARKED = re.compile("\x1f([^\x1e\x1f]+)(?:\x1e([^\x1f]*))?\x1f")


def setting(name: str, *, python: str | None = None) -> str:
    """The setting ``name`` (a parameter, a config field or a key) as a message names it:
    ``name`` to a Python caller (or ``python``, where the words a Python caller reads differ
    from the setting's name), and the flag that sets it where the command line reports the
    message. Use it inside an :class:`InputError`'s or a warning's (:func:`warn`) message only."""
    return f"\x1f{name}\x1f" if python is None else f"\x1f{name}\x1e{python}\x1f"


def _render(message: str, flags: Mapping[str, str]) -> str:
    """``message`` with each marked setting as ``flags`` names it, else as a Python caller reads it."""
    return _MARKED.sub(lambda m: flags.get(m[1]) or (m[1] if m[2] is None else m[2]), message)


class _NamesSettings(Exception):
    """A message that may name settings (:func:`setting`): ``str()`` as a Python caller reads
    it, :meth:`text` as the command line reports it."""

    def __str__(self) -> str:
        return _render(super().__str__(), {})

    @property
    def marked(self) -> str:
        """The message with its settings still marked (:func:`setting`), for a message that
        quotes this one and leaves their naming to whoever reports it."""
        return super().__str__()

    def text(self, flags: Mapping[str, str]) -> str:
        """The message with each setting named as ``flags`` ({setting: flag}) names it (the
        command line's flags); a setting not in ``flags`` by its name, as :func:`str` gives it."""
        return _render(super().__str__(), flags)


class InputError(_NamesSettings, ValueError):
    """Bad user input: a file, a column, an option value. The message says what, where, how to fix."""


class ModelFileError(InputError):
    """A model directory that is missing, truncated, corrupted or inconsistent."""


class InternalError(RuntimeError):
    """A bug in pinn-mpc: an internal inconsistency that no input can cause. The message says
    what was inconsistent and the values."""


class PinnMpcWarning(_NamesSettings, UserWarning):
    """Input that is accepted but deserves attention (the message says what and why; it may
    name settings, as an :class:`InputError`'s does)."""


def warn(message: str | PinnMpcWarning) -> None:
    """Warn with ``message`` (:class:`PinnMpcWarning`, or the text of one), attributed to the
    line that calls this."""
    warnings.warn(message, PinnMpcWarning, stacklevel=2)


def warn_once(message: str) -> None:
    """:func:`warn`, but each message at most once per process (input read several times)."""
    if message not in _WARNED:
        _WARNED.add(message)
        warnings.warn(message, PinnMpcWarning, stacklevel=2)
