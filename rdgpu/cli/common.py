"""What every ``rdgpu`` command shares: the usage error and the exit statuses, the defaults
named in the help, messages in the command line's words, and the checks of an output path
and of the memory a run needs.  Light on purpose: the parser imports it, and ``rdgpu
--help`` loads no model."""

from __future__ import annotations

import argparse
import os
import re
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rdgpu.core.errors import ResourceLimitError
from rdgpu.core.files import check_writable
from rdgpu.core.resources import check_fields

if TYPE_CHECKING:
    from rdgpu.models.model import Model

DEFAULT_SIZE = (256, 256)
#: steps of a model that has no default run length of its own
DEFAULT_STEPS = 10_000
EXIT_BAD_INPUT = 2
EXIT_DIVERGED = 1
EXIT_FAILED = 1
EXIT_INTERRUPTED = 130


class UsageError(ValueError):
    """Bad command-line input (exit status 2)."""


def say(args: argparse.Namespace, text: str) -> None:
    """A progress message on stderr, unless ``--quiet``."""
    if not args.quiet:
        print(text, file=sys.stderr)


def grid_text(shape: Any) -> str:
    """``256x256``."""
    return "x".join(str(int(n)) for n in shape)


def cli_words(text: str) -> str:
    """A library message in the command line's words."""
    text = re.sub(r"pass check_stability=False", "use --no-stability-check", text)
    return text.replace("check_stability=False", "--no-stability-check")


def one_line(exc: BaseException) -> str:
    """The first line of an exception's message (its type's name if it has none)."""
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def io_message(exc: OSError, path: Any = None) -> str:
    """``[Errno 28] No space left on device`` with the file it was writing."""
    where = path if path is not None else exc.filename
    why = exc.strerror or str(exc).strip() or type(exc).__name__
    return f"cannot write {where}: {why}" if where is not None else why


def model_name(model: Model) -> str:
    """The name of a model given as a name or as a model (a preset's ``model``)."""
    return model if isinstance(model, str) else model.name


def check_output(option: str, path: str) -> None:
    """An output path whose folder exists and can be written, and is not a folder itself."""
    p = Path(path)
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.exists():
        raise UsageError(f"{option} {path}: the folder {str(folder)!r} does not exist")
    if not folder.is_dir():
        raise UsageError(f"{option} {path}: {str(folder)!r} is not a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise UsageError(f"{option} {path}: the folder {str(folder)!r} is not writable")
    if p.is_dir():
        raise UsageError(f"{option} {path} is a folder; give a file name")
    try:  # the writers' own check: never a device, a pipe or a socket; no NUL byte
        check_writable(path, option)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    if p.exists() and not os.access(p, os.W_OK):
        raise UsageError(f"{option} {path} exists and is not writable")


def check_memory(what: str, cells: int, n_species: int, itemsize: int, snapshots: int = 0,
                 frame_pixels: int = 0) -> None:
    """The shared estimate (``rdgpu.core.resources.check_fields``), as a usage error."""
    try:
        check_fields(what, cells, n_species, itemsize, snapshots=snapshots,
                     frame_pixels=frame_pixels)
    except ResourceLimitError as exc:
        raise UsageError(str(exc)) from None
