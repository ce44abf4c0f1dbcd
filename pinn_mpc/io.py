"""Safe writes: nothing half-written, nothing of the user's lost or overwritten unasked.

Files are written to a temporary sibling, then renamed. A command that writes a directory
writes only its own files there (:class:`DirectoryLayout`); an existing directory holding
anything else is refused unless the user says ``force``, and even then only the command's own
files are replaced. Before any work, :func:`check_writable` and :func:`check_distinct` refuse
outputs that cannot be written or that would overwrite an input or another output, and
:func:`check_new_files` an existing output file the user has not said ``force`` to replace.
"""

from __future__ import annotations

import contextlib
import contextvars
import errno
import fcntl
import hashlib
import json
import os
import shutil
import signal
import tempfile
import threading
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pinn_mpc.errors import InputError, InternalError, setting

__all__ = [
    "DirectoryLayout",
    "PathArg",
    "PathsArg",
    "atomic_directory",
    "atomic_write",
    "atomic_write_json",
    "atomic_write_text",
    "check_distinct",
    "check_new_files",
    "check_output_directory",
    "check_writable",
    "file_sha256",
    "output_lock",
    "setting_changes",
    "staged",
    "written_at_once",
    "written_together",
]

PathArg = str | os.PathLike[str]


def _check_parent(path: Path) -> None:
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise InputError(f"cannot write {path}: directory {parent} does not exist; create it first")
    if not os.access(parent, os.W_OK):
        raise InputError(f"cannot write {path}: directory {parent} is not writable")


def atomic_write(path: str | os.PathLike[str], writer: Callable[[Path], object]) -> Path:
    """Call ``writer(tmp_path)`` then rename the temporary file onto ``path``."""
    target = Path(path)
    _check_parent(target)
    if target.is_dir():
        raise InputError(f"cannot write {target}: it is a directory; give a file name")
    if target.exists() and not target.is_file():  # a device or pipe must not be replaced
        raise InputError(f"cannot write {target}: it is not a regular file")
    batch = _BATCH.get()
    with _interrupt_deferred():
        try:
            fd, tmp_name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
        except OSError as exc:  # the user's file named, not the temporary one
            raise OSError(exc.errno, exc.strerror or str(exc), str(target)) from None
        os.close(fd)
        tmp = Path(tmp_name)
        try:
            try:
                writer(tmp)
            except OSError as exc:
                raise OSError(exc.errno, exc.strerror or str(exc), str(target)) from None
            os.chmod(tmp, 0o644)
            if batch is None:
                os.replace(tmp, target)
            else:
                batch.append((tmp, target))
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise
    return target


#: The files of a :func:`written_together` block, each (temporary, target), to be renamed at
#: its end (None outside such a block).
_BATCH: contextvars.ContextVar[list[tuple[Path, Path]] | None] = contextvars.ContextVar(
    "pinn_mpc_io_batch", default=None
)


@contextlib.contextmanager
def written_together() -> Iterator[None]:
    """Write every file :func:`atomic_write` writes inside the block (in this thread) together
    or not at all: each goes to its temporary sibling as usual, and only when the block ends
    without an error are they all renamed into place, one after another; on an error (a full
    disk on the last file) every temporary file is removed and no target changes."""
    if _BATCH.get() is not None:  # nested: the outer block renames
        yield
        return
    pending: list[tuple[Path, Path]] = []
    token = _BATCH.set(pending)
    try:
        yield
    except BaseException:
        for tmp, _ in pending:
            tmp.unlink(missing_ok=True)
        raise
    finally:
        _BATCH.reset(token)
    with _interrupt_deferred():
        for tmp, target in pending:
            os.replace(tmp, target)


@contextlib.contextmanager
def written_at_once() -> Iterator[None]:
    """Inside a :func:`written_together` block, write every file :func:`atomic_write` writes in
    this block into place as it is written (each still atomically), not when the outer block
    ends: what a long run saves to survive an interruption (an online run's state each night)
    must be on disk before the interruption, not held for the command's last files."""
    token = _BATCH.set(None)
    try:
        yield
    finally:
        _BATCH.reset(token)


def staged(path: PathArg) -> Path:
    """The file that holds ``path``'s new content: inside a :func:`written_together` block
    that has written ``path``, the temporary file renamed onto it when the block ends;
    otherwise ``path`` itself (for what reads a file just written, e.g. its checksum)."""
    target = os.path.abspath(path)
    for tmp, pending in reversed(_BATCH.get() or []):
        if os.path.abspath(pending) == target:
            return tmp
    return Path(path)


@contextlib.contextmanager
def _interrupt_deferred() -> Iterator[None]:
    """Hold a Ctrl-C (SIGINT) that arrives while a file is replaced until it is done: an
    interrupt between creating the temporary file and the ``try`` that removes it would
    leave it behind (seen in an interrupted sweep). Outside the main thread signals cannot
    be handled, and arrive there anyway."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received: list[int] = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: received.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if received:
            if callable(previous):
                previous(signal.SIGINT, None)
            elif previous == signal.SIG_DFL:
                raise KeyboardInterrupt


def file_sha256(path: PathArg) -> str:
    """The sha256 of a file's bytes (hex), read in blocks."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def atomic_write_text(path: str | os.PathLike[str], text: str) -> Path:
    return atomic_write(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))


def atomic_write_json(path: str | os.PathLike[str], data: Any) -> Path:
    return atomic_write_text(
        path, json.dumps(data, indent=2, sort_keys=False, allow_nan=False) + "\n"
    )


def check_writable(*paths: PathArg | None, create_parents: bool = False) -> None:
    """Fail before any work if an output file cannot be written: it is a directory, its folder
    is missing (unless ``create_parents``, then the nearest existing ancestor counts) or
    read-only. ``None`` entries (optional outputs not asked for) are skipped."""
    for path in paths:
        if path is None:
            continue
        if not str(path).strip():
            raise InputError("an output file name is empty; give a file name")
        target = Path(path)
        if target.is_dir() or target.name in ("", ".", ".."):
            raise InputError(f"cannot write {path}: it is a directory; give a file name")
        if target.exists() and not target.is_file():
            raise InputError(f"cannot write {target}: it is not a regular file")
        parent = target.parent
        while create_parents and not parent.exists() and parent != parent.parent:
            parent = parent.parent
        if parent.exists() and not parent.is_dir():
            raise InputError(f"cannot write {target}: {parent} is a file, not a directory")
        if not parent.is_dir():
            raise InputError(f"cannot write {target}: directory {parent} does not exist; create it")
        if not os.access(parent, os.W_OK):
            raise InputError(f"cannot write {target}: directory {parent} is not writable")


def _same_file(a: Path, b: Path) -> bool:
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:  # hard links, case-insensitive file systems
        return os.path.samefile(a, b)
    except OSError:
        return False


PathsArg = PathArg | Sequence[PathArg] | None


def _entries(paths: Mapping[str, PathsArg]) -> list[tuple[str, Path]]:
    out = []
    for label, value in paths.items():
        if value is None:
            continue
        if isinstance(value, str | os.PathLike):
            out.append((label, Path(value)))
        else:
            out += [(label, Path(v)) for v in value]
    return out


def check_distinct(*, inputs: Mapping[str, PathsArg], outputs: Mapping[str, PathsArg]) -> None:
    """Refuse (one-line :class:`InputError`) when an output is an input or another output.

    Keys name the paths in the message (a flag such as ``--data``); a value is a path, several
    (the files of a directory argument, see :meth:`DirectoryLayout.paths`) or ``None`` (not
    given). Paths are compared after resolving ``..``, symbolic links and hard links, so
    ``./d.csv`` and ``sub/../d.csv`` are the same file.
    """
    seen = [(label, path, True) for label, path in _entries(inputs)]
    for label, path in _entries(outputs):
        for other_label, other, is_input in seen:
            if not _same_file(path, other):
                continue
            if is_input:
                raise InputError(
                    f"{label} {path} is the same file as the input {other_label} {other}: "
                    f"writing it would destroy the input; choose another {label}"
                )
            raise InputError(
                f"{label} {path} and {other_label} {other} are the same file, so one output "
                "would overwrite the other; give them different names"
            )
        seen.append((label, path, False))


def check_new_files(files: Mapping[str, PathsArg], *, force: bool) -> None:
    """Fail before any work (one-line :class:`InputError`) if an output file exists, unless
    ``force``: a file the user owns (a recorded data set, an edited RC) is replaced only when
    asked to.

    Keys are the settings that name the files (``out``; the command line names them by their
    flags); a value is the file (``None``: not given) or several, the file the setting names
    first and then those written beside it (a fleet's parameters file next to its data).
    """
    if force:
        return
    for name, value in files.items():
        if value is None:
            continue
        named, *beside = [value] if isinstance(value, str | os.PathLike) else list(value)
        for path in (named, *beside):
            if path is None or not Path(path).exists():
                continue
            what = (
                f"{setting(name)} {path}" if path is named
                else f"{path} (written beside {setting(name)} {named})"
            )
            another = "another name" if path is named else f"another {setting(name)}"
            raise InputError(
                f"{what} already exists; choose {another}, or add {setting('force')} to replace it"
            )


@dataclass(frozen=True, kw_only=True)
class DirectoryLayout:
    """A directory a command writes (or reads): ``kind`` names it in messages, ``files`` are
    the command's own file names (nothing else is ever written or replaced there), and an
    existing directory counts as the same kind of output when it holds every name of
    ``markers`` and nothing but ``files``."""

    kind: str
    files: tuple[str, ...]
    markers: tuple[str, ...]

    def __post_init__(self) -> None:
        if not self.files or not set(self.markers) <= set(self.files):
            raise ValueError(f"DirectoryLayout {self.kind!r}: markers must be among the files")

    def paths(self, path: PathArg) -> list[Path]:
        """The own files inside ``path`` (for :func:`check_distinct`)."""
        return [Path(path) / name for name in self.files]


def _listing(names: list[str], limit: int = 4) -> str:
    shown = ", ".join(names[:limit])
    return shown + (f" and {len(names) - limit} more" if len(names) > limit else "")


def _shown(target: Path) -> str:
    """The path as given, plus where it is when that is not obvious (``.``, ``..``)."""
    resolved = os.path.abspath(target)
    return str(target) if target.name not in ("", ".", "..") else f"{target} ({resolved})"


def check_output_directory(path: PathArg, layout: DirectoryLayout, *, force: bool) -> None:
    """Fail before any work unless ``path`` may receive ``layout``'s files: it does not exist
    (its parent must), is empty, or is already that kind of output; with ``force`` any existing
    directory will do, as only ``layout.files`` are replaced and everything else is kept."""
    if not str(path).strip():  # Path("") would be the working directory
        raise InputError(f"the {layout.kind} name is empty; give a directory name")
    target = Path(path)
    if target.exists() and not target.is_dir():
        raise InputError(
            f"cannot write {layout.kind} {target}: a file of that name exists; "
            "give a directory name"
        )
    if not target.exists():
        _check_parent(target)
        return
    if not os.access(target, os.W_OK | os.X_OK):
        raise InputError(f"cannot write {layout.kind} {_shown(target)}: it is not writable")
    entries = sorted(os.listdir(target))
    blocking = [n for n in layout.files if n in entries and not (target / n).is_file()]
    if blocking:
        raise InputError(
            f"cannot write {layout.kind} {_shown(target)}: {_listing(blocking)} in it "
            "is a directory, not a file; move it away"
        )
    foreign = [n + ("/" if (target / n).is_dir() else "") for n in entries if n not in layout.files]
    if force or not entries:
        return
    if foreign or not set(layout.markers) <= set(entries):
        raise InputError(
            f"{_shown(target)} already holds {_listing(foreign or entries)}, so it is not a "
            f"{layout.kind}; give a new or empty directory, or add {setting('force')} to replace only "
            f"{_listing(list(layout.files), 3)} there (the rest is kept)"
        )


@contextlib.contextmanager
def atomic_directory(
    path: PathArg, layout: DirectoryLayout, *, force: bool = False
) -> Iterator[Path]:
    """Yield a temporary directory to write ``layout``'s files into; on success they land in
    ``path`` and nothing else there is touched.

    A new ``path`` is the temporary directory renamed (all or nothing). Into an existing one
    (allowed as :func:`check_output_directory` says) each file is renamed into place, so a
    reader sees every file either old or new, never half-written. On failure nothing changes.
    """
    check_output_directory(path, layout, force=force)
    target = Path(path)
    exists = target.is_dir()
    # Inside an existing target (it is writable; its parent may not be); else a sibling.
    where = target if exists else Path(os.path.abspath(target)).parent
    tmp = Path(tempfile.mkdtemp(prefix=".pinn-mpc-", suffix=".tmp", dir=where))
    try:
        try:
            yield tmp
            written = sorted(os.listdir(tmp))
            stray = [n for n in written if n not in layout.files]
            if stray:  # a bug in the writer, not user input: never put foreign files in place
                raise InternalError(f"{layout.kind}: wrote {stray}, not among {layout.files}")
            if exists:
                for name in (n for n in layout.files if n in written):
                    os.replace(tmp / name, target / name)
                tmp.rmdir()
            else:
                tmp.chmod(0o755)  # mkdtemp makes it private
                os.rename(tmp, target)
        except OSError as exc:  # the user's directory named, not the temporary one
            if isinstance(exc.filename, str | os.PathLike) and not _inside(exc.filename, tmp):
                raise
            raise OSError(exc.errno, exc.strerror or str(exc), str(target)) from None
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def _inside(filename: PathArg, folder: Path) -> bool:
    """True when ``filename`` is ``folder`` or a path inside it."""
    path, root = os.path.abspath(filename), os.path.abspath(folder)
    return path == root or path.startswith(root + os.sep)


def setting_changes(before: Mapping[str, Any], now: Mapping[str, Any]) -> str:
    """``"key before -> now"`` for each key of ``now`` whose value ``before`` differs, comma
    separated (empty when none does): what a refused rerun of a stored run names."""
    return ", ".join(f"{k} {before.get(k)!r} -> {v!r}" for k, v in now.items() if before.get(k) != v)


#: The lock file of an output directory ``DIR``: ``.DIR.lock`` beside it.
LOCK_SUFFIX = ".lock"


def _lock_path(target: Path) -> Path:
    """Beside the output (it may not exist yet); where its folder is not writable, in the
    system's temporary folder under a name made from the output's full path."""
    absolute = Path(os.path.realpath(target))
    if os.access(absolute.parent, os.W_OK) or not absolute.parent.is_dir():
        return absolute.parent / f".{absolute.name}{LOCK_SUFFIX}"
    digest = hashlib.sha256(str(absolute).encode("utf-8")).hexdigest()[:16]
    return Path(tempfile.gettempdir()) / f"pinn-mpc-{digest}{LOCK_SUFFIX}"


@contextlib.contextmanager
def output_lock(path: PathArg, *, option: str = "out", create_parents: bool = False) -> Iterator[None]:
    """Hold the output ``path`` (a directory or a file) for this run: a second run writing
    there while this one does is refused in one line (:class:`InputError`, naming the
    holder's pid and the setting ``option`` that named ``path``).

    The lock is a file beside ``path`` holding the holder's pid, locked with ``flock`` (atomic;
    the system releases it when the holder exits however it exits, so a lock file left by a
    dead process is taken over); it is removed when the block ends. Where ``path`` is empty or its folder
    does not exist it is made with ``create_parents`` (and removed again if still empty at the
    end); otherwise nothing is locked, as the command refuses such an output itself.
    """
    if not str(path).strip():  # no output named: the command refuses it
        yield
        return
    lock = _lock_path(Path(path))
    made: list[Path] = []
    if not lock.parent.is_dir():
        if not create_parents:
            yield
            return
        missing = lock.parent
        while not missing.exists():
            made.append(missing)
            missing = missing.parent
        lock.parent.mkdir(parents=True)
    try:
        with _locked(lock, path, option):
            yield
    finally:
        for folder in made:  # deepest first
            with contextlib.suppress(OSError):
                folder.rmdir()


@contextlib.contextmanager
def _locked(lock: Path, path: PathArg, option: str) -> Iterator[None]:
    """Hold ``lock`` (see :func:`output_lock`)."""
    while True:
        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:
            raise InputError(f"cannot lock {setting(option)} {path}: {exc.strerror or exc} ({lock})") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            holder = os.pread(fd, 32, 0).decode("ascii", "replace").strip() or "unknown"
            os.close(fd)
            if exc.errno not in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
                raise
            raise InputError(
                f"{setting(option)} {path} is being written by another run (pid {holder}; its lock "
                f"is {lock}): wait for it to end, or give another {setting(option)}"
            ) from None
        try:  # the file locked may have been removed by the holder that just ended: retry
            same = os.fstat(fd).st_ino == os.stat(lock).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode("ascii"), 0)
        yield
    finally:
        Path(lock).unlink(missing_ok=True)
        os.close(fd)
