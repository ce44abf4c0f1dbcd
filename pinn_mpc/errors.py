"""Exception classes. The CLI turns :class:`InputError` into one line on stderr and exit 2."""


class InputError(ValueError):
    """Bad user input: a file, a column, an option value. The message says what, where, how to fix."""


class ModelFileError(InputError):
    """A model directory that is missing, truncated, corrupted or inconsistent."""
