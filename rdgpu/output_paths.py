"""One check of a path that a run will write (a checkpoint, a data file, a picture),
made before the run starts, by the Python API and the CLI alike: a run of hours must not
end in an error at its first checkpoint because the path could never be written.

:func:`check_output_path` raises a ``ValueError`` that names the option and the path:
an empty path, a NUL byte, a name longer than the file system allows (with the temporary
file written beside it), a folder, a missing folder (unless the caller makes folders), a
file where a folder belongs, a folder that cannot be written, or an existing path that is
not a regular file (a device, a pipe, a socket: never replaced by a file).
"""

from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import Any

__all__ = ["check_output_path"]

#: the characters the atomic writers add to a name for their temporary file:
#: ``.NAME.HOST.PID.RANDOM.tmp`` (host up to 64, pid up to 10, random 8)
TEMP_EXTRA = 1 + 1 + 64 + 1 + 10 + 1 + 8 + 4


def _name_max(folder: Path) -> int:
    try:
        return int(os.pathconf(folder, "PC_NAME_MAX"))
    except (OSError, ValueError, AttributeError):
        return 255


def _exists(p: Path) -> bool:
    try:
        return p.exists()
    except OSError:  # e.g. a name too long: nothing there that can be used
        return False


def check_output_path(path: Any, option: str = "output", *, make_folders: bool = False,
                      temporary: bool = True) -> Path:
    """``path`` as a :class:`~pathlib.Path` a file can be written to, or a ``ValueError``
    (a ``TypeError`` for something that is no path) naming ``option`` and the path.

    ``make_folders``: a missing folder is fine where the nearest existing one above it is
    a folder that can be written (the writer makes the rest); otherwise the folder must
    exist.  ``temporary``: the file is written through a temporary file beside it (atomic
    writers), whose longer name must fit too."""
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"{option} must be a path (str or os.PathLike), got "
                        f"{type(path).__name__} {path!r:.60}")
    text = os.fspath(path)
    if isinstance(text, bytes):
        text = os.fsdecode(text)
    if text == "":
        raise ValueError(f"{option} is an empty path; give a file name")
    if "\0" in text:
        raise ValueError(f"{option} {text!r} contains a NUL byte, which no file name can hold")
    p = Path(text)
    folder = p.parent if str(p.parent) else Path(".")
    limit = _name_max(Path("."))
    for part in p.parts[:-1]:
        if len(os.fsencode(part)) > limit:
            raise ValueError(f"{option} {text!r}: the folder name {part[:40]!r}... is "
                             f"{len(os.fsencode(part))} bytes long; this file system allows "
                             f"{limit}")
    existing = folder
    while not _exists(existing) and existing != existing.parent:
        existing = existing.parent
    limit = _name_max(existing if existing.is_dir() else Path("."))
    name_bytes = len(os.fsencode(p.name))
    if name_bytes > limit:
        raise ValueError(f"{option} {text!r}: the file name is {name_bytes} bytes long; this "
                         f"file system allows {limit}")
    if temporary and name_bytes + TEMP_EXTRA > limit:
        raise ValueError(f"{option} {text!r}: the file name is {name_bytes} bytes long; the "
                         f"temporary file written beside it needs {TEMP_EXTRA} more and this "
                         f"file system allows {limit} (give a name of at most "
                         f"{limit - TEMP_EXTRA} bytes)")
    if not _exists(folder):
        if not _exists(existing) or not existing.is_dir():
            blocker = existing if _exists(existing) else folder
            raise ValueError(f"{option} {text!r}: {str(blocker)!r} is not a folder")
        if not make_folders:
            raise ValueError(f"{option} {text}: the folder {str(folder)!r} does not exist")
        folder = existing
    if not folder.is_dir():
        raise ValueError(f"{option} {text}: {str(folder)!r} is not a folder")
    if p.is_dir():
        raise ValueError(f"{option} {text} is a folder; give a file name")
    try:
        mode = os.stat(p).st_mode
    except FileNotFoundError:
        mode = None
    except OSError as exc:
        raise ValueError(f"{option} {text}: cannot be examined ({exc.strerror})") from None
    if mode is not None and not stat.S_ISREG(mode):
        raise ValueError(f"{option} {text} exists and is not a regular file (a device, a pipe "
                         "or a socket); give the name of a file")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ValueError(f"{option} {text}: the folder {str(folder)!r} is not writable")
    if mode is not None and not os.access(p, os.W_OK):
        raise ValueError(f"{option} {text} exists and is not writable")
    return p
