"""What a run produced: `Result` (fields, snapshots, times, the settings it ran
with) and `package_versions` (recorded with it)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.core.hardware import package_versions
from rdgpu.core.renderers import render
from rdgpu.simulation.dataset import result_dataset

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain

__all__ = ["Result", "package_versions"]


@dataclass
class Result:
    """What a run produced (`Simulation.run` returns it; `rdgpu.output.load_npz` reads
    one back). In a notebook it draws its final state (`rdgpu.io.display`).

    Attributes
    ----------
    model : str
        The model's name.
    fields : dict of str to numpy.ndarray
        The final fields, one per species, of the domain's field shape (``[ny, nx]`` on a
        2-D grid, one value per vertex on a mesh; ``[members, *shape]`` for an ensemble);
        the last good state if the run diverged.
    snapshots : dict of str to numpy.ndarray
        ``snapshots[name]`` is an ``[n_snap, *shape]`` array taken at ``snapshot_steps``,
        at the times ``times`` (model time units).
    times, snapshot_steps : numpy.ndarray
        The snapshots' times (float, ``snapshot_steps * dt``) and steps (int64), one each.
    step, time, dt : int, float, float
        Steps done, the model time reached (``step * dt``) and the time step.
    params : dict
        The parameters the run used (numbers or per-cell fields).
    domain, domain_info : Domain, dict
        The Grid, graph surface or SurfaceMesh, and its description.
    backend, device, dtype : str
        Where and in what precision it ran.
    seed : int, list of int or None
        The seed of the initial condition and of random parameter fields (one per member
        where an ensemble was given one each).
    init : dict, list of dict or None
        The initial condition's spec (one per member where the members' defaults differ);
        None where the `Simulation` was given explicit ``fields`` (a resumed one keeps
        its checkpoint's).
    versions : dict of str to str
        `package_versions` at the time the result was made.
    wall_seconds : float
        Wall-clock seconds the run took.
    diverged : str or None
        Why the run stopped early, if it did (for an ensemble: how many members diverged).
    members : int or None
        An ensemble's member count (fields ``[members, *shape]``).
    diverged_members : dict of int to str
        The members that diverged and were frozen at their last good state, with what
        happened to each.
    mask : numpy.ndarray or None
        A masked run's mask (bool, the domain's field shape; `rdgpu.integrators.masks`):
        the pictures show the cells outside it grey.
    """

    model: str
    fields: dict[str, np.ndarray]
    snapshots: dict[str, np.ndarray]
    times: np.ndarray
    snapshot_steps: np.ndarray
    step: int
    time: float
    dt: float
    params: dict[str, Any]
    domain: Domain
    domain_info: dict
    backend: str
    device: str
    dtype: str
    seed: int | None = None
    init: Any = None
    versions: dict[str, str] = field(default_factory=package_versions)
    wall_seconds: float = 0.0
    diverged: str | None = None
    #: ensembles: the number of members (fields ``[members, *shape]``), and the members
    #: that diverged and were frozen at their last good state, with what happened
    members: int | None = None
    diverged_members: dict[int, str] = field(default_factory=dict)
    mask: np.ndarray | None = None

    @property
    def species(self) -> tuple[str, ...]:
        return tuple(self.fields)

    def to_xarray(self) -> Any:
        """The result as an ``xarray.Dataset``: one variable per species on dims ``(x,)``,
        ``(y, x)`` or ``(z, y, x)`` (cell-centre coordinates) or ``(vertex,)`` (a mesh:
        coordinates ``x``, ``y``, ``z``, ``faces``), led by ``member`` for an ensemble and
        by ``time`` when snapshots were taken (the final state appended if it is not the
        last one); parameter fields as ``param_<name>``, a graph surface's ``height``; the
        model, parameters, dt, backend, dtype and domain as attributes. Needs xarray. See
        `rdgpu.simulation.dataset` for the full layout."""

        return result_dataset(self)

    def _repr_png_(self) -> bytes | None:
        """Jupyter's picture: the final state as PNG (`rdgpu.io.display.result_png`: a
        mosaic for an ensemble, the rendering for a mesh)."""
        return render("image/png", self)

    def _repr_html_(self) -> str | None:
        """Jupyter's rich view: the picture under a one-line summary of the run
        (`rdgpu.io.display.result_html`)."""
        return render("text/html", self)

    def __repr__(self) -> str:
        shape = next(iter(self.fields.values())).shape if self.fields else ()
        return (f"Result(model={self.model!r}, step={self.step}, time={self.time:g}, "
                f"shape={shape}, snapshots={len(self.times)}, backend={self.backend!r}, "
                f"dtype={self.dtype!r}{', diverged' if self.diverged else ''})")
