"""Command line: ``pinn-mpc COMMAND ...`` (also ``python -m pinn_mpc`` and ``python -m pinn_mpc_cli``).

:mod:`pinn_mpc_cli.parser` builds the parser, one function per command; each command is one
function of :mod:`pinn_mpc_cli.model_commands` (``train``, ``evaluate``, ``export-rc``,
``identify``), :mod:`pinn_mpc_cli.loop_commands` (``simulate``, ``closed-loop``),
:mod:`pinn_mpc_cli.experiment_commands` (``compare``, ``reproduce``, ``sweep``) or
:mod:`pinn_mpc_cli.scenario_commands` (``scenario``), imported when it runs, that writes the
outputs and returns a short summary, printed here. It is the application entry point, the one
place above all three layers.

What goes wrong is reported by its cause, as one line on stderr:

- bad input (:class:`~pinn_mpc.errors.InputError`, or a file the user named that the system
  refuses: not found, no permission, a full disk under ``--out``): what is wrong and how to fix
  it, exit status 2; a setting the message names (:func:`pinn_mpc.errors.setting`) is named by
  its flag (:func:`pinn_mpc_cli.parser.command_flags`);
- anything else (:class:`~pinn_mpc.errors.InternalError`, a Python-API check of the library
  the command line failed, an :class:`OSError` on a file the user did not name, such as a
  temporary file or a socket, memory that ran out where no check foresaw it, or any other
  exception): a bug in pinn-mpc, with what failed and where, and how to report it; exit status
  1. The traceback follows with ``--debug``.

The library's warnings (:class:`~pinn_mpc.errors.PinnMpcWarning`) are printed as one line each,
``pinn-mpc: warning: ...``, and its notes (``logging`` at level INFO) as ``pinn-mpc: ...``.
"""

from __future__ import annotations

import atexit
import contextlib
import importlib
import logging
import os
import sys
import traceback
import warnings
from argparse import Namespace
from collections.abc import Iterator, Mapping, Sequence
from typing import NoReturn, TextIO

from pinn_mpc.errors import InputError, PinnMpcWarning
from pinn_mpc_cli.parser import MAX_DAYS, build_parser, command_flags

__all__ = ["BUG_EXIT", "INTERRUPT_EXIT", "MAX_DAYS", "build_parser", "bug_line", "main"]

#: Exit status of a bug (bad input is 2, an interruption 130).
BUG_EXIT = 1
#: Exit status of a run ended by Ctrl-C (128 + SIGINT, as a shell reports it).
INTERRUPT_EXIT = 130
#: The packages whose notes (``logging``) the command line shows.
_LOGGERS = ("pinn_mpc", "controllers", "scenarios")


def bug_line(command: str, exc: BaseException) -> str:
    """The one line that reports ``exc`` as a bug in pinn-mpc: what failed, where it was
    raised (the innermost frame: file, line and function), and how to report it."""
    where = ""
    frames = traceback.extract_tb(exc.__traceback__)
    if frames:
        last = frames[-1]
        where = f" at {os.path.basename(last.filename)}:{last.lineno} in {last.name}"
    what = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__
    if isinstance(exc, MemoryError):
        what += " (out of memory where no check of the run's size foresaw it)"
    return (
        f"pinn-mpc {command}: internal error (a bug in pinn-mpc, not in your input): {what}"
        f"{where}; please report it on the project's issue tracker with the output of the "
        "same command run with `pinn-mpc --debug ...`"
    )


@contextlib.contextmanager
def _library_messages(flags: Mapping[str, str]) -> Iterator[None]:
    """Within: each library warning printed every time it is raised (``warn_once`` keeps its
    own once per process), a setting it names named by its flag (``flags``), and the library's
    notes printed; the settings restored on exit."""
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("pinn-mpc: %(message)s"))
    loggers = [logging.getLogger(name) for name in _LOGGERS]
    levels = [logger.level for logger in loggers]
    with warnings.catch_warnings():
        shown = warnings.showwarning

        def show(
            message: Warning | str,
            category: type[Warning],
            filename: str,
            lineno: int,
            file: TextIO | None = None,
            line: str | None = None,
        ) -> None:
            """The library's warnings as one line on stderr; any other as Python shows it."""
            if issubclass(category, PinnMpcWarning):
                text = message.text(flags) if isinstance(message, PinnMpcWarning) else message
                print(f"pinn-mpc: warning: {text}", file=sys.stderr)
            else:
                shown(message, category, filename, lineno, file, line)

        warnings.simplefilter("always", PinnMpcWarning)
        warnings.showwarning = show
        for logger in loggers:
            logger.addHandler(handler)
            logger.setLevel(logging.INFO)
        try:
            yield
        finally:
            for logger, level in zip(loggers, levels, strict=True):
                logger.removeHandler(handler)
                logger.setLevel(level)


def user_named(exc: OSError, args: Namespace) -> bool:
    """True when ``exc`` is about a file the user named: a path given on the command line (any
    option's or argument's value), a file inside a directory given as one (a model or output
    directory), or a file named after one beside it (what a command writes next to its output:
    ``fleet.csv`` -> ``fleet.fleet.json``, ``k.json`` -> ``k.fleet.png``, the lock
    ``.out.lock``). A file the package chose itself elsewhere (a temporary file, a socket) is
    not the user's to fix."""
    named = [
        os.path.abspath(value) for key, value in vars(args).items()
        if isinstance(value, str) and value and key not in ("command", "handler")
    ]
    for filename in (exc.filename, exc.filename2):
        if isinstance(filename, str | os.PathLike) and os.fspath(filename):
            path = os.path.abspath(os.fspath(filename))
            if any(_of(path, user) for user in named):
                return True
    return False


def _of(path: str, user: str) -> bool:
    """True when ``path`` is ``user``, inside it, or named after it beside it."""
    if path == user or path.startswith(user.rstrip(os.sep) + os.sep):
        return True
    folder, name = os.path.split(user)
    stem = os.path.splitext(name)[0]
    return bool(stem) and os.path.dirname(path) == folder and os.path.basename(path).startswith(
        (f"{stem}.", f".{name}")
    )


def _report_bug(command: str, exc: BaseException, debug: bool) -> int:
    if debug:
        traceback.print_exception(type(exc), exc, exc.__traceback__, file=sys.stderr)
    print(bug_line(command, exc), file=sys.stderr)
    return BUG_EXIT


def _end_process(status: int) -> NoReturn:
    """End the process at once with ``status``: the exit handlers run (temporary directories,
    Ray) and the streams are flushed, but the interpreter's teardown of its modules, which
    takes seconds once torch is loaded, is skipped, so that Ctrl-C ends a command promptly."""
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    os._exit(status)


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``pinn-mpc`` with ``argv`` (default: the process's); the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    # The numerical work here is many small matrices (MPC, observers, identification): a
    # multi-threaded BLAS only adds synchronisation on top of them. Torch keeps its own threads.
    from threadpoolctl import threadpool_limits

    flags = command_flags(parser, args.command)
    try:
        with _library_messages(flags), threadpool_limits(limits=1, user_api="blas"):
            module, function = args.handler.split(":")
            summary = getattr(importlib.import_module(module), function)(args)
    except InputError as exc:
        text = exc.text(flags)
        print(f"pinn-mpc {args.command}: error: {text}", file=sys.stderr)
        return 2
    except OSError as exc:
        if not user_named(exc, args):
            return _report_bug(args.command, exc, args.debug)
        print(f"pinn-mpc {args.command}: error: {exc.strerror or exc} ({exc.filename})", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"pinn-mpc {args.command}: interrupted", file=sys.stderr)
        if argv is None:  # the process's own command: end it now (a caller's argv: return)
            _end_process(INTERRUPT_EXIT)
        return INTERRUPT_EXIT
    except Exception as exc:  # an internal error, or any other: a bug, reported as one
        return _report_bug(args.command, exc, args.debug)
    if summary:
        try:
            print(summary, flush=True)
        except BrokenPipeError:  # the reader (e.g. `| head`) has gone: the work is done
            # Python would report the pipe again when it flushes stdout at exit.
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return 0

