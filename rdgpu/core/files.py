"""Writing files safely: every writer of rdgpu (checkpoints, data files, pictures, movies,
mesh files) goes through this module.

* `check_writable` -- refuse, before any work, a path that cannot be a file written
  by rdgpu: empty, with a NUL byte, a name too long, a folder, an existing path that is
  not a regular file (a device such as ``/dev/full``, a named pipe, a socket -- rdgpu never
  replaces one), or a path under something that is not a folder.
* `writing` -- an ``OSError`` raised while writing names the file and what it is
  (``[Errno 28] No space left on device (writing the checkpoint): 'ck.npz'``).
* `atomic_savez` and `atomic_path` -- a file appears complete or not at all:
  written to a temporary file beside it (``.NAME.HOST.PID.RANDOM.tmp``), flushed to disk,
  then renamed over the target; on any error the temporary is removed and an existing
  target is left as it was.
* `CheckpointLock` -- one writer per checkpoint: a lock file ``.NAME.lock`` beside
  it holds the writer's host and process id; a second writer is refused with
  `FileInUseError`; a lock left by a process that died is taken over.
* `remove_stale_temporaries` -- delete the temporaries killed writers left.
"""

from __future__ import annotations

import contextlib
import os
import socket
import stat
import tempfile
import time as _time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "CheckpointLock",
    "FileInUseError",
    "atomic_path",
    "atomic_savez",
    "check_writable",
    "lock_path",
    "remove_stale_temporaries",
    "writing",
]

PathLike = str | os.PathLike


class FileInUseError(RuntimeError):
    """Another live process is writing the same checkpoint (its lock file is held)."""


# ------------------------------------------------------------------------- the check
_KINDS = ((stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
          (stat.S_ISFIFO, "a named pipe (FIFO)"), (stat.S_ISSOCK, "a socket"))


def _kind(mode: int) -> str:
    for test, name in _KINDS:
        if test(mode):
            return name
    return "not a regular file"


def _name_max(folder: Path) -> int:
    try:
        return int(os.pathconf(folder if folder.is_dir() else ".", "PC_NAME_MAX"))
    except (OSError, ValueError, AttributeError):
        return 255


def check_writable(path: Any, what: str) -> Path:
    """``path`` as a `Path` when rdgpu may write ``what`` (e.g. ``"the
    checkpoint"``) there; otherwise a ``ValueError`` (``TypeError`` for a non-path) naming
    ``what``, the path and what is wrong.  A missing folder is fine (writers create it);
    an existing regular file is replaced; anything else that exists is refused."""
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"{what} must be a path (str or os.PathLike), got "
                        f"{type(path).__name__}")
    text = os.fspath(path)
    if isinstance(text, bytes):
        text = os.fsdecode(text)
    if text == "":
        raise ValueError(f"{what}: the path is empty; give a file name")
    if "\0" in text:
        raise ValueError(f"{what} {text!r}: a path cannot contain a NUL byte")
    p = Path(text)
    if p.name in ("", ".", ".."):
        raise ValueError(f"{what} {text!r} is a folder; give a file name")
    folder = p.parent if str(p.parent) else Path(".")
    if len(os.fsencode(p.name)) > _name_max(folder):
        raise ValueError(f"{what} {text!r}: the file name is {len(os.fsencode(p.name))} bytes "
                         f"long; this file system allows at most {_name_max(folder)}")
    temp = len(os.fsencode(_temp_prefix(p))) + 8 + len(".tmp")  # mkstemp's name beside it
    if temp > _name_max(folder):
        raise ValueError(f"{what} {text!r}: the file name is {len(os.fsencode(p.name))} bytes "
                         f"long; the temporary file written beside it needs {temp} and this "
                         f"file system allows at most {_name_max(folder)}: give a shorter name")
    try:
        mode = os.stat(p).st_mode
    except FileNotFoundError:
        mode = None
    except NotADirectoryError:
        mode = None  # a file where a folder should be: named below
    except OSError as exc:
        raise ValueError(f"{what} {text!r} cannot be used: {exc.strerror or exc}") from None
    if mode is not None:
        if stat.S_ISDIR(mode):
            raise ValueError(f"{what} {text!r} is a folder; give a file name")
        if not stat.S_ISREG(mode):
            raise ValueError(f"{what} {text!r} exists and is {_kind(mode)}, not a regular "
                             "file; rdgpu writes only regular files and never replaces a "
                             "device, a pipe or a socket: give another path")
        return p
    ancestor = folder
    while True:
        try:
            amode = os.stat(ancestor).st_mode
        except (FileNotFoundError, NotADirectoryError):
            if ancestor.parent == ancestor:
                break
            ancestor = ancestor.parent
            continue
        except OSError as exc:
            raise ValueError(f"{what} {text!r}: the folder {str(ancestor)!r} cannot be used "
                             f"({exc.strerror or exc})") from None
        if not stat.S_ISDIR(amode):
            raise ValueError(f"{what} {text!r}: {str(ancestor)!r} is not a folder")
        break
    return p


# -------------------------------------------------------------------- naming errors
def _named(exc: OSError, path: Path, what: str) -> OSError:
    """``exc`` again, its message saying what was being written, its filename the target."""
    reason = exc.strerror or str(exc) or type(exc).__name__
    if exc.errno is None:
        return OSError(f"writing {what} {str(path)!r} failed: {reason}")
    try:
        return type(exc)(exc.errno, f"{reason} (writing {what})", str(path))
    except TypeError:  # a subclass with another constructor
        return OSError(exc.errno, f"{reason} (writing {what})", str(path))


@contextlib.contextmanager
def writing(path: PathLike, what: str) -> Iterator[None]:
    """Re-raise an ``OSError`` from the block naming ``path`` and ``what`` (e.g. the disk
    full: ``[Errno 28] No space left on device (writing the checkpoint): 'ck.npz'``)."""
    try:
        yield
    except OSError as exc:
        if getattr(exc, "_rdgpu_named", False):
            raise
        new = _named(exc, Path(path), what)
        new._rdgpu_named = True  # type: ignore[attr-defined]
        raise new from exc


# ------------------------------------------------------------------- temporary files
def _host_tag() -> str:
    """This machine's name as it goes into temporary file names (no dots or separators)."""
    name = socket.gethostname() or "host"
    return "".join(c if c.isalnum() or c in "-_" else "-" for c in name)[:64] or "host"


def _temp_prefix(path: Path) -> str:
    """Temporary files of ``path`` are ``.NAME.HOST.PID.RANDOM.tmp`` beside it: the writer's
    machine and process id say whether the writer is still alive (see
    `remove_stale_temporaries`)."""
    return f".{path.name}.{_host_tag()}.{os.getpid()}."


def _pid_alive(pid: int) -> bool:
    if pid <= 0:
        return False
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # e.g. EPERM: a process of another user holds that id
        return True
    return True


#: temporary files without a writer's id (written by rdgpu before 0.1.1) count as stale
#: when untouched for this long
_LEGACY_TEMP_AGE = 3600.0


def remove_stale_temporaries(path: str | os.PathLike) -> list[Path]:
    """Delete the temporary files that killed writers of ``path`` left beside it; returns
    them.

    Only temporaries of this very file are considered (``.NAME.*.tmp`` in its folder), and
    of those only the ones whose writer -- named by machine and process id in the file
    name -- is a process of this machine that no longer runs; a live writer's file, or
    another machine's, is left alone.  Temporaries without a writer's id (the naming of
    earlier versions) are removed when untouched for an hour."""
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    head = f".{path.name}."
    host = _host_tag()
    removed: list[Path] = []
    try:
        names = os.listdir(folder)
    except OSError:
        return removed
    for name in names:
        if not (name.startswith(head) and name.endswith(".tmp")):
            continue
        middle = name[len(head):-len(".tmp")]
        parts = middle.rsplit(".", 2)
        tmp = folder / name
        if len(parts) == 3 and parts[1].isdigit():
            if parts[0] != host or _pid_alive(int(parts[1])):
                continue
        elif "." in middle:  # another file's temporary (NAME.something) or not ours
            continue
        else:
            try:
                if _time.time() - tmp.stat().st_mtime < _LEGACY_TEMP_AGE:
                    continue
            except OSError:
                continue
        try:
            if tmp.is_file() and not tmp.is_symlink():
                tmp.unlink()
                removed.append(tmp)
        except OSError:
            pass
    return removed


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


class _suppress:
    def __enter__(self):
        return self

    def __exit__(self, et, ev, tb):
        return et is not None and issubclass(et, OSError)


def _folder(path: Path) -> Path:
    folder = path.parent if str(path.parent) else Path(".")
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def _commit(tmp: str, path: Path, folder: Path, what: str) -> None:
    """Rename the finished temporary over ``path`` (checked again: a device node that
    appeared meanwhile is not replaced), then make the rename durable."""
    check_writable(path, what)
    os.replace(tmp, path)
    with _suppress():
        dfd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)


def atomic_savez(path: PathLike, arrays: dict[str, np.ndarray], compressed: bool = False,
                 what: str = "the data file") -> None:
    """Write an NPZ atomically: temporary file in the same folder, fsync, ``os.replace``.
    ``path`` is checked first (`check_writable`); an ``OSError`` names it."""
    path = check_writable(path, what)
    with writing(path, what):
        folder = _folder(path)
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=_temp_prefix(path), suffix=".tmp")
        try:
            os.fchmod(fd, 0o666 & ~_umask())  # mkstemp makes 0600; give the usual permissions
            with os.fdopen(fd, "wb") as fh:
                (np.savez_compressed if compressed else np.savez)(fh, **arrays)
                fh.flush()
                os.fsync(fh.fileno())
            _commit(tmp, path, folder, what)
        except BaseException:
            with _suppress():
                os.unlink(tmp)
            raise


@contextlib.contextmanager
def atomic_path(path: PathLike, what: str) -> Iterator[Path]:
    """A temporary path beside ``path`` with the same extension for a writer that needs a
    file name (imageio, matplotlib, mesh writers); once the block ends without an error it
    is flushed and renamed over ``path``, else removed.  ``path`` is checked first; an
    ``OSError`` names it."""
    path = check_writable(path, what)
    with writing(path, what):
        folder = _folder(path)
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=_temp_prefix(path),
                                   suffix=".tmp" + path.suffix)
        try:
            os.fchmod(fd, 0o666 & ~_umask())
            os.close(fd)
            yield Path(tmp)
            if os.path.getsize(tmp) == 0:
                raise OSError(f"writing {what} {str(path)!r} failed: the writer wrote nothing")
            with open(tmp, "rb") as fh:
                os.fsync(fh.fileno())
            _commit(tmp, path, folder, what)
        except BaseException:
            with _suppress():
                os.unlink(tmp)
            raise


# ------------------------------------------------------------------------ the lock
def lock_path(path: PathLike) -> Path:
    """The lock file of a checkpoint: ``.NAME.lock`` in its folder."""
    p = Path(path)
    return p.with_name(f".{p.name}.lock")


def _read_holder(lock: Path) -> str:
    try:
        text = lock.read_text(errors="replace").split()
    except OSError:
        return "another process"
    if len(text) >= 2 and text[1].isdigit():
        return f"process {text[1]} on {text[0]}"
    return "another process"


class CheckpointLock:
    """Hold the lock file of a checkpoint (`lock_path`) while a run writes it::

        with CheckpointLock("ck.npz"):
            ...  # the run; a second CheckpointLock("ck.npz") raises FileInUseError

    The lock file holds ``HOST PID``.  It is an ``flock`` on that file where the system
    has one (the kernel lets go of it when the process dies, so a lock left by a killed
    run is taken over); elsewhere the file's existence is the lock and a file naming a
    process of this machine that no longer runs is taken over.  Released (the file
    removed) when the block ends, by an error or Ctrl-C too."""

    def __init__(self, path: PathLike) -> None:
        self.path = Path(path)
        self.lock = lock_path(self.path)
        self._fd: int | None = None

    def _refuse(self) -> FileInUseError:
        return FileInUseError(
            f"checkpoint {str(self.path)!r} is being written by {_read_holder(self.lock)} "
            f"(lock file {str(self.lock)!r}); two runs must not write one checkpoint: wait "
            "for that run, or give another --checkpoint path (delete the lock file only if "
            "no such run exists)")

    def acquire(self) -> CheckpointLock:
        with writing(self.lock, "the checkpoint's lock file"):
            _folder(self.lock)
            for _ in range(20):
                fd = self._try_once()
                if fd is not None:
                    self._fd = fd
                    os.ftruncate(fd, 0)
                    os.write(fd, f"{_host_tag()} {os.getpid()}\n".encode())
                    return self
        raise self._refuse()

    def _try_once(self) -> int | None:
        try:
            import fcntl
        except ImportError:  # pragma: no cover - no flock: the file's existence is the lock
            return self._try_exclusive()
        fd = os.open(self.lock, os.O_RDWR | os.O_CREAT, 0o666 & ~_umask())
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise self._refuse() from None
        except OSError:
            os.close(fd)
            raise
        try:  # the file we locked may have been released (removed) meanwhile: retry
            same = os.stat(self.lock).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if not same:
            os.close(fd)
            return None
        return fd

    def _try_exclusive(self) -> int | None:  # pragma: no cover - systems without fcntl
        try:
            return os.open(self.lock, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o666 & ~_umask())
        except FileExistsError:
            text = self.lock.read_text(errors="replace").split() if self.lock.exists() else []
            if len(text) >= 2 and text[0] == _host_tag() and text[1].isdigit() \
                    and not _pid_alive(int(text[1])):
                with _suppress():
                    self.lock.unlink()
                return None
            raise self._refuse() from None

    def release(self) -> None:
        if self._fd is None:
            return
        fd, self._fd = self._fd, None
        try:
            with _suppress():
                if os.stat(self.lock).st_ino == os.fstat(fd).st_ino:
                    self.lock.unlink()
        finally:
            os.close(fd)

    def __enter__(self) -> CheckpointLock:
        return self.acquire()

    def __exit__(self, *exc: Any) -> None:
        self.release()
