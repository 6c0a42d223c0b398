"""What ``rdgpu run`` writes and says after (or instead of) a run: the default picture's
name, the notes and warnings about the picture, and the outputs written one by one so that
a failure to write one (a full disk, a permission) names that file, leaves the others
written, and ends the command with exit status 1 -- a failed run, not bad input.  A run
whose checkpoint could not be written still writes ``--out``/``--data`` from its last good
state (issue 19, A7, D, E1, E5)."""

from __future__ import annotations

import argparse
import re
import sys
import warnings
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.cli.common import io_message
from rdgpu.core import optional
from rdgpu.io.images import FlatFieldWarning
from rdgpu.io.output import write_outputs
from rdgpu.simulation import Result, describe_domain

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain
    from rdgpu.models.model import Model

#: a displayed field whose range is below this fraction of its scale is "uniform"
UNIFORM_FRACTION = 0.05


def default_png(name: str) -> str:
    """The default picture of a run of ``name`` (a preset or model): in the current folder,
    every run of characters other than letters and digits made one ``_`` (``gray-scott``:
    ``gray_scott.png``; ``../x``: ``x.png``)."""
    stem = re.sub(r"[^A-Za-z0-9]+", "_", name).strip("_")
    return f"{stem or 'rdgpu'}.png"


def uniform_warning(result: Any, model: Model, field: str, has_presets: bool) -> str | None:
    """A warning when the pictured field has (nearly) no structure left, with a hint that
    works for this model (a user model has no presets)."""
    f = np.asarray(result.fields[field], dtype=np.float64)
    if f.size == 0 or not np.isfinite(f).all():
        return None
    lo, hi = float(f.min()), float(f.max())
    known = (getattr(model, "value_range", None) or {}).get(field)
    scale = float(known[1] - known[0]) if known else max(abs(lo), abs(hi))
    if scale > 0 and hi - lo > UNIFORM_FRACTION * scale:
        return None
    hint = "try other --param values, more --steps or another --init"
    if has_presets:
        hint += f", or a preset ('rdgpu presets {model.name}')"
    return (f"the field is uniform ({field} ∈ [{lo:.4g}, {hi:.4g}]) at step {result.step}: "
            f"no pattern formed; {hint}")


def slices_note(args: argparse.Namespace, domain: Domain, pictures: bool) -> str | None:
    """The note for a 3-D picture that will be slices because pyvista is missing."""
    if not pictures or args.view not in (None, "auto"):
        return None
    grid_3d = not domain.unstructured and len(domain.field_shape) == 3
    if not grid_3d or optional.available("pyvista"):
        return None
    return ("pyvista is not installed: the 3-D picture shows the mid-plane slices instead "
            "of an isosurface (pip install \"rdgpu[mesh]\" for it; --view slices says so "
            "and silences this)")


def result_of(sim: Any, exc: BaseException) -> Any:
    """The last good state of a run stopped by ``exc`` (a failed checkpoint write): the
    exception's ``result`` where it has one, else the simulation's current state (a
    checkpoint is written only from a checked state), without snapshots."""
    result = getattr(exc, "result", None)
    if result is not None:
        return result
    try:
        fields = sim.host_state()
    except Exception:  # noqa: BLE001 - the device itself failed: nothing to write
        return None
    empty = {s: np.zeros((0, *sim.field_shape), sim.dtype) for s in sim.species}
    return Result(model=sim.model.name, fields={s: fields[s] for s in sim.species},
                  snapshots=empty, times=np.zeros(0), snapshot_steps=np.zeros(0, np.int64),
                  step=sim.step, time=sim.time, dt=sim.dt, params=dict(sim.params),
                  domain=sim.domain, domain_info=describe_domain(sim.domain, sim.domain_source),
                  backend=sim.backend.name, device=sim.backend.device, dtype=sim.dtype.name,
                  seed=sim.seed, init=sim.init, members=sim.members,
                  diverged_members=dict(sim.frozen))


def write_each(result: Any, outputs: list[tuple[str, Any]], options: dict,
               ) -> tuple[list, list[str]]:
    """Write ``outputs`` (``("png"|"movie"|"data", path)``) one by one; returns the paths
    written and a message per output that failed (the others are still written)."""
    written, failed = [], []
    for kind, path in outputs:
        if kind == "movie" and len(result.snapshot_steps) == 0:
            failed.append(f"--movie {path}: not written (the run kept no snapshots)")
            continue
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", FlatFieldWarning)
                written += write_outputs(result, **{kind: path}, **options)
        except OSError as exc:
            failed.append(io_message(exc, path))
            continue
        for w in caught:  # a picture drawn flat: said once, as a note, in the CLI's words
            if issubclass(w.category, FlatFieldWarning):
                text = str(w.message).replace("give vmin/vmax", "give --range LO:HI")
                print(f"rdgpu: note: {path}: {text}", file=sys.stderr)
            else:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return written, failed

