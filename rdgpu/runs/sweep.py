"""Parameter sweeps: a model run over the Cartesian product of parameter values, as
ensembles, in batches that are Dask tasks.

    import rdgpu
    ds = rdgpu.sweep("gray-scott", {"F": "0.01:0.08:64", "k": "0.03:0.07:64"},
                     size=128, steps=10_000, store="map.zarr")
    rdgpu.sweep_map(ds, "map.png")

The product of the swept axes (in the order given: the first varies slowest) is cut into
batches of members; each batch is one ensemble run (``Simulation(..., members=B)``) and
one Dask task.  With a ``.zarr`` store the results stream into it as batches finish, and a
sweep run again with the same settings skips the batches already there.

Needs the ``dask`` extra: ``pip install "rdgpu[dask]"`` (dask[distributed], xarray, zarr;
matplotlib for the map).
"""

from __future__ import annotations

import itertools
import json
import math
import os
import sys
import time
import types
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.analysis import classify_pattern
from rdgpu.backends.registry import get_backend
from rdgpu.core.conventions import AXIS_NAMES, VERSION, axis_names
from rdgpu.core.optional import require
from rdgpu.core.validation import scalar
from rdgpu.domains.specs import build_domain
from rdgpu.models import MODELS, PRESETS, define_model
from rdgpu.runs.axes import axis_values, parse_axis
from rdgpu.runs.mosaic import sweep_map
from rdgpu.runs.notebook import register
from rdgpu.runs.store import (
    SETTINGS_ATTR,
    check_sweep_memory,
    load_store,
    open_store,
    read_done,
    stored_batch,
    verify_done,
)
from rdgpu.simulation import default_dt, describe_domain, domain_defaults
from rdgpu.simulation.checks import model_definition, whole
from rdgpu.simulation.defaults import accepts, lookup_model
from rdgpu.simulation.driver import Simulation

if TYPE_CHECKING:
    from rdgpu.backends.base import Backend
    from rdgpu.domains.base import Domain
    from rdgpu.models.model import Model

__all__ = ["PATTERN_CLASSES", "open_sweep", "parse_axis", "sweep", "sweep_map"]

#: the values of ``pattern`` (stored in a zarr/netCDF file as their index; -1: not run)
PATTERN_CLASSES = ("uniform", "spots", "inverted-spots", "stripes", "mixed", "diverged")
#: fraction for `rdgpu.analysis.classify_pattern`'s ``mixed`` class in a sweep
MIXED_SHARE = 0.25
#: memory (bytes) that one batch's fields may take, for the default batch size
BATCH_MEMORY = 256 * 2**20


# ------------------------------------------------------------------------ optional extra
def _need(*modules: str) -> list[Any]:
    """Import the optional modules of the ``dask`` extra, or say how to get them (and give
    xarray's Datasets the ``ds.rdgpu`` notebook view, `rdgpu.runs.notebook`)."""
    found = [require(name, "rdgpu.sweep") for name in modules]
    if "xarray" in modules:
        register(found[modules.index("xarray")])
    return found




# ------------------------------------------------------------------------ the job
def _default_domain(model: Model | str, size: Any) -> dict:
    """A grid of ``size`` (``N``, ``(ny, nx)``, ...) with the model's spacing and boundary
    conditions (periodic unless its default domain says otherwise)."""
    base = dict(getattr(model, "default_domain", None) or {})
    spec = {k: base[k] for k in ("dx", "dy", "dz", "bc") if "grid" in base and k in base}
    spec.setdefault("dx", float(getattr(model, "spacing", 1.0)))
    spec.setdefault("bc", "periodic")
    shape = ((whole(size, "size", 1),) * 2 if isinstance(size, (str, bytes)) or
             np.ndim(size) == 0 else tuple(whole(n, "size", 1) for n in size))
    if not 1 <= len(shape) <= 3:
        raise ValueError(f"size must be N or 1 to 3 whole numbers, got {size!r}")
    if len(shape) != 3:
        spec.pop("dz", None)
    if len(shape) == 1:
        spec.pop("dy", None)
    return {"grid": shape, **spec}


def pattern_species(model: Model | str) -> str:
    """The species whose pattern a sweep classifies and pictures by default: the one the
    model's presets classify (Gray-Scott ``v``, Brusselator ``u``, ...), else the first."""
    for p in PRESETS.values():
        field = (p.classify or {}).get("field")
        if p.model == model.name and field in model.species:
            return field
    return model.species[0]


def run_batch(job: Mapping[str, Any], values: Mapping[str, Sequence[float]]) -> dict:
    """One batch of a sweep (a pure function: the same arguments give the same bits, so a
    re-run of a lost task changes nothing).  ``job``: the sweep's settings (see
    `sweep`); ``values``: each swept parameter's value for every member.  Returns
    ``{"fields": {species: [B, *shape] array}, "pattern": [B] int8 codes}``."""
    names = list(values)
    count = len(values[names[0]]) if names else 1
    kwargs = {"dt": job["dt"], "backend": job["backend"], "dtype": job["dtype"],
              "seed": job["seed"], "init": job["init"], "options": job["options"] or None}
    model = job["model"]
    if isinstance(model, Mapping):  # a model defined by its equations
        model = define_model(job["name"], dict(model["equations"]), dict(model["defaults"]))
    model = lookup_model(model)
    if accepts(model.stepper, "members"):  # one ensemble: all members in one launch a step
        params = {**job["fixed"], **{k: np.asarray(v, dtype=np.float64)
                                     for k, v in values.items()}}
        sim = Simulation(model, job["domain"], params, members=count, **kwargs)
        res = sim.run(job["steps"], progress=False, check_every=0)
        fields = {s: np.asarray(a) for s, a in res.fields.items()}
        domain = sim.domain
    else:  # a model that cannot run as an ensemble (e.g. allen-cahn): one by one
        runs = []
        for i in range(count):
            params = {**job["fixed"], **{k: float(v[i]) for k, v in values.items()}}
            sim = Simulation(model, job["domain"], params, **kwargs)
            runs.append(sim.run(job["steps"], progress=False, check_every=0).fields)
        fields = {s: np.stack([np.asarray(r[s]) for r in runs]) for s in runs[0]}
        domain = sim.domain
    labels = classify_pattern(fields[job["classify"]], domain, threshold=None,
                              mixed=MIXED_SHARE, nonfinite="diverged", members=True)
    codes = np.array([PATTERN_CLASSES.index(c) for c in labels], dtype=np.int8)
    return {"fields": fields, "pattern": codes}


def _common_dt(model: Model | str, domain: Domain | Mapping | None, fixed: Mapping[str, Any],
               axes: Mapping[str, np.ndarray], options: Mapping[str, Any]) -> float:
    """The default time step that suits every member: the smallest of theirs."""
    base = {**model.defaults, **domain_defaults(model, domain, options), **fixed}
    return min(default_dt(model, domain, {**base, **dict(zip(axes, combo, strict=True))},
                          options)
               for combo in itertools.product(*axes.values()))


# ------------------------------------------------------------------------ the store
def _store_kind(store: Any) -> str | None:
    if store is None:
        return None
    suffix = Path(store).suffix.lower()
    if suffix == ".zarr":
        return "zarr"
    if suffix in (".nc", ".netcdf", ".nc4"):
        return "netcdf"
    raise ValueError(f"store must be a path ending in .zarr (streamed, resumable) or .nc "
                     f"(netCDF, written at the end), got {str(store)!r}")


def _template(xr: Any, da: Any, settings: dict, axes: dict[str, np.ndarray],
              space: tuple[int, ...], dx: dict[str, float], species: Sequence[str],
              n_batches: int) -> Any:
    """The sweep's Dataset with lazy empty arrays (NaN fields, pattern -1, done False),
    chunked one member per chunk."""
    dims = (*axes, *axis_names(len(space)))
    shape = (*(a.size for a in axes.values()), *space)
    chunks = (*(1 for _ in axes), *space)
    data = {s: (dims, da.full(shape, np.nan, dtype=settings["dtype"], chunks=chunks))
            for s in species}
    data["pattern"] = (tuple(axes), da.full(shape[: len(axes)], -1, dtype=np.int8),
                       {"flag_values": list(range(len(PATTERN_CLASSES))),
                        "flag_meanings": " ".join(PATTERN_CLASSES),
                        "description": "rdgpu.analysis.classify_pattern of the final "
                        f"{settings['classify']!r} (-1: not run yet)"})
    data["done"] = (("batch",), da.zeros(n_batches, dtype=bool))
    coords: dict[str, Any] = {k: (k, v) for k, v in axes.items()}
    for d, n in zip(axis_names(len(space)), space, strict=True):
        coords[d] = (d, (np.arange(n) + 0.5) * dx[d], {"description": "cell centre"})
    ds = xr.Dataset(data, coords=coords)
    ds.attrs.update(_attrs(settings))
    return ds


def _attrs(settings: dict) -> dict:
    """The Dataset's attributes: plain values, and the full settings as JSON."""
    out = {"model": settings["name"], "steps": settings["steps"], "dt": settings["dt"],
           "dtype": settings["dtype"], "backend": settings["backend_name"],
           "seed": settings["seed"], "classify": settings["classify"],
           "rdgpu_version": VERSION, SETTINGS_ATTR: json.dumps(settings, sort_keys=True)}
    for k, v in settings["fixed"].items():
        out[f"param_{k}"] = v
    return out


def _decode(ds: Any) -> Any:
    """``pattern`` codes → class names (``""``: not run yet); ``done`` dropped."""
    if ds["pattern"].dtype.kind in "UO":  # decoded already
        return ds.drop_vars(["done"], errors="ignore")
    codes = ds["pattern"].values.astype(int)
    names = np.array([*PATTERN_CLASSES, ""], dtype=object)[codes]
    ds = ds.drop_vars(["done"], errors="ignore")
    ds["pattern"] = (ds["pattern"].dims, names.astype(str),
                     {"description": ds["pattern"].attrs.get("description", "")})
    return ds


def open_sweep(path: str | os.PathLike) -> Any:
    """Open a sweep's Dataset from its zarr or netCDF file.

    Parameters
    ----------
    path : str or os.PathLike
        A ``.zarr`` or ``.nc`` file that `sweep` wrote.

    Returns
    -------
    xarray.Dataset
        Loaded, with ``pattern`` as class names (``""`` where a batch has not run yet).
    """
    xr, = _need("xarray")
    kind = _store_kind(path)
    if kind == "zarr":
        ds = load_store(xr, Path(path), PATTERN_CLASSES.index("diverged"))
    else:
        with xr.open_dataset(str(path)) as f:
            ds = f.load()
    return _decode(ds)


# ------------------------------------------------------------------------ schedulers
def _nothing() -> None:
    """Nothing to close."""


def _client(scheduler: Any, workers: int | None, n_batches: int) -> tuple[Any, Callable]:
    """``(client, close)``: ``client`` None for an in-process run."""
    if scheduler in (None, "serial"):
        return None, _nothing
    distributed, = _need("distributed")
    if isinstance(scheduler, distributed.Client):
        return scheduler, _nothing
    if scheduler == "local":
        n = workers or max(1, min(os.cpu_count() or 1, n_batches))
        cluster = distributed.LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                           dashboard_address=None)
        client = distributed.Client(cluster)

        def close() -> None:
            client.close()
            cluster.close()

        return client, close
    _check_scheduler(scheduler)
    client = distributed.Client(scheduler)  # an address
    return client, client.close


def _check_scheduler(scheduler: Any) -> None:
    """Refuse what `_client` cannot take (a Client passes by its class's name, so
    that no Dask import is needed here)."""
    if scheduler in (None, "serial", "local") or type(scheduler).__name__ == "Client" or (
            isinstance(scheduler, str) and "://" in scheduler):
        return
    raise ValueError(f"scheduler must be 'local' (a LocalCluster here), 'serial' (in this "
                     f"process), an address such as 'tcp://host:8786' or a "
                     f"distributed.Client; got {scheduler!r}")


def _default_batch(n_members: int, cells: int, n_species: int, itemsize: int,
                   workers: int) -> int:
    """Members per batch: about 4 batches per worker, at most what fits in
    `BATCH_MEMORY` (about 6 copies of each field)."""
    fits = max(1, BATCH_MEMORY // max(1, cells * n_species * itemsize * 6))
    return max(1, min(fits, math.ceil(n_members / (4 * max(1, workers)))))


def _swept_and_fixed(mdl: Any, params: Any) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """``(axes, fixed)``: the swept parameters' values and the fixed ones (`sweep`)."""
    if not isinstance(params, Mapping):
        raise TypeError(f"params must be a dict of parameter → values, got "
                        f"{type(params).__name__}")
    unknown = [k for k in params if k not in mdl.defaults]
    if unknown:
        raise ValueError(f"unknown parameter(s) {', '.join(map(repr, unknown))} of model "
                         f"{mdl.name}; it has {', '.join(mdl.defaults)}")
    axes: dict[str, np.ndarray] = {}
    fixed: dict[str, float] = {}
    for name, value in params.items():
        v = axis_values(name, value)
        if isinstance(v, np.ndarray):
            axes[name] = v
        else:
            fixed[name] = v
    if not axes:
        raise ValueError("nothing to sweep: give at least one parameter several values, "
                         "e.g. {'F': '0.01:0.08:16'}")
    return axes, fixed


def _check_names(axes: Mapping[str, Any], species: Sequence[str]) -> None:
    """No swept parameter or species may take a name the Dataset uses itself."""
    own = (*AXIS_NAMES, "batch", "pattern", "done")  # the Dataset's own names
    clash = [k for k in axes if k in own or k in species]
    if clash:
        raise ValueError(f"a swept parameter may not be called {', '.join(clash)} (a "
                         "dimension or variable of the Dataset)")
    clash = [s for s in species if s in own]
    if clash:
        raise ValueError(f"a sweep cannot hold species {', '.join(clash)}: the Dataset "
                         f"uses {', '.join(own)} for its own dimensions and variables; "
                         "rename the species")


def _task_model(mdl: Any, definition: Any) -> Any:
    """What a task carries of the model: its name (a built-in), its equations, or (a model
    of Python code) the model itself, which must then pickle for a cluster."""
    builtin = MODELS.get(mdl.name) is mdl
    return definition or (mdl.name if builtin else mdl)


# ------------------------------------------------------------------------ sweep
def sweep(
    model: Model | str,
    params: Mapping[str, Any],
    *,
    steps: int,
    size: Any = 128,
    domain: Domain | Mapping | None = None,
    dt: float | None = None,
    dtype: str = "float32",
    backend: str | None = None,
    seed: int = 0,
    init: Mapping[str, Any] | None = None,
    options: Mapping[str, Any] | None = None,
    batch: int | None = None,
    store: str | os.PathLike | None = None,
    scheduler: Any = "local",
    workers: int | None = None,
    classify: str | None = None,
    progress: bool = True,
    on_batch: Callable[[int], None] | None = None,
) -> Any:
    """Run ``model`` at every point of the Cartesian product of the swept parameters.

    The product is cut into batches of ``batch`` members; each batch is one ensemble run
    and one task.  A worker that dies has its batch re-run by Dask; batches are pure, so
    the bits do not change.

    Parameters
    ----------
    model : Model or str
        A model or a model's name (``"gray-scott"``).
    params : mapping
        Parameter → a number (fixed), a list/array of values (swept) or text
        (``"0.01:0.08:64"`` = ``np.linspace(0.01, 0.08, 64)``, ``"0.02,0.03"``,
        ``"0.05"``).  The swept axes keep their order: the first varies slowest.
    steps : int
        Time steps of ``dt`` per member.
    size : int or tuple of int
        Cells, ``N`` or ``(ny, nx)``; periodic, the model's spacing.  Ignored when
        ``domain`` is given.
    domain : dict or rdgpu.domains.Grid, optional
        A grid spec dict or a `rdgpu.domains.Grid`.
    dt : float, optional
        Time step (default: the smallest default step of all the members, so every member
        runs with the same ``dt``).
    dtype, backend, seed, init, options
        As `rdgpu.simulation.Simulation` takes them; ``seed`` gives one initial condition
        for all members.
    batch : int, optional
        Members per batch (default: about 4 batches per worker, within `BATCH_MEMORY`;
        resuming a ``.zarr`` store: the store's).
    store : str or os.PathLike, optional
        A ``.zarr`` path is created up front (every array, one member per chunk, and
        ``done`` per batch) and each batch is written as it finishes, from this process
        only; running the same sweep again (on any scheduler) skips the batches marked
        done (their data checked first: `rdgpu.runs.store`), and a store made with other
        settings is refused.  A ``.nc`` path (netCDF) is written once at the end: no
        streaming, no resume.
    scheduler : str or distributed.Client
        ``"local"`` (default: a ``distributed.LocalCluster`` of ``workers``
        single-threaded processes, default one per core), an address
        ``"tcp://host:port"``, a ``distributed.Client``, or ``"serial"`` (in this process,
        no Dask); the workers of a cluster elsewhere need rdgpu installed.
    workers : int, optional
        Processes of the local cluster.
    classify : str, optional
        The species classified (default: `pattern_species`).
    progress : bool
        A tqdm bar counting batches.
    on_batch : callable, optional
        ``on_batch(b)`` is called after batch ``b`` is stored (an exception from it stops
        the sweep; the batches stored so far stay).

    Returns
    -------
    xarray.Dataset
        Dims the swept parameters, then the space dims (``y, x``; cell centres); a
        variable per species (the final fields, NaN where a member diverged), ``pattern``
        (`rdgpu.analysis.classify_pattern` of the species ``classify`` with
        ``threshold=None``, ``mixed=0.25``: one of `PATTERN_CLASSES`); attrs ``model,
        steps, dt, dtype, backend, seed, classify, rdgpu_version``, ``param_NAME`` for
        each fixed parameter and the settings as JSON.  In a notebook ``ds.rdgpu`` shows
        the parameter map and a summary with this call's wall time, ``ds.rdgpu.wall_s``
        in seconds (`rdgpu.runs.notebook.SweepView`).

    Raises
    ------
    ValueError
        An unknown parameter, nothing swept, a store that is neither ``.zarr`` nor
        ``.nc``, an unknown scheduler or species to classify.
    MissingExtraError
        The ``dask`` extra (xarray, dask, distributed, zarr) is not installed.

    Notes
    -----
    Gray-Scott is classified on ``v`` as its presets are: islands of low ``v`` (Pearson's
    δ) are ``"spots"``, islands of high ``v`` (Pearson's λ) ``"inverted-spots"``.
    """
    xr, da = _need("xarray", "dask.array")
    start = time.perf_counter()
    kind = _store_kind(store)
    _check_scheduler(scheduler)
    plan = _plan(model, params, steps=steps, size=size, domain=domain, dt=dt, dtype=dtype,
                 seed=seed, init=init, options=options, batch=batch, workers=workers,
                 store=store, classify=classify)
    be = get_backend(backend)
    plan.dtype = str(np.dtype(dtype))
    definition, desc = model_definition(plan.model), describe_domain(plan.grid)
    if plan.batch is None and kind == "zarr":  # resuming: the store's batches
        plan.batch = stored_batch(Path(store))
    client, close = None, _nothing
    try:
        if plan.batch is None:  # about 4 batches a worker: ask the cluster how many it has
            client, close = _client(scheduler, plan.workers, plan.n_members)
            n_workers = 1 if client is None else len(client.scheduler_info()["workers"])
            plan.batch = _default_batch(plan.n_members, math.prod(plan.grid.field_shape),
                                        len(plan.species), np.dtype(plan.dtype).itemsize,
                                        n_workers)
        plan.batch = int(plan.batch)
        n_batches = math.ceil(plan.n_members / plan.batch)
        settings, job = _settings_and_job(plan, be, backend, definition, desc)
        result = _collector(xr, da, plan, settings, n_batches, store if kind == "zarr" else None)
        todo = [b for b in range(n_batches) if not result.done(b)]
        if todo and client is None:  # no cluster is started for a finished sweep
            client, close = _client(scheduler, plan.workers, len(todo))
        _run(client, job, result, todo, n_batches, progress, on_batch)
    finally:
        close()
    if kind == "zarr":
        ds = open_sweep(store)
    else:
        ds = result.dataset()
        if kind == "netcdf":
            ds.to_netcdf(str(store))  # pattern as codes, as in a zarr store
        ds = _decode(ds)
    ds.rdgpu.wall_s = time.perf_counter() - start  # this call's; not an attr (nor stored)
    return ds


@dataclass
class _Plan:
    """A sweep's arguments, checked, with what follows from them: the model, the swept
    ``axes`` and ``fixed`` parameters, the grid, the members and the run's settings."""

    model: Model
    axes: dict[str, np.ndarray]
    fixed: dict[str, float]
    grid: Domain
    n_members: int
    species: tuple[str, ...]
    classify: str
    steps: int
    seed: int
    dt: float
    dtype: Any
    init: Mapping[str, Any] | None
    options: dict[str, Any]
    batch: int | None
    workers: int | None


def _plan(model: Model | str, params: Mapping[str, Any], *, steps: Any, size: Any,
          domain: Domain | Mapping | None, dt: Any, dtype: Any, seed: Any, init: Any,
          options: Any, batch: Any, workers: Any, store: Any,
          classify: str | None) -> _Plan:
    """`sweep`'s arguments checked, in the order its errors come, and the defaults
    that follow from them (the grid, ``classify``, the common ``dt``)."""
    mdl = lookup_model(model)
    axes, fixed = _swept_and_fixed(mdl, params)
    steps, seed = whole(steps, "steps", 0), whole(seed, "seed", 0)
    batch, workers = (None if n is None else whole(n, what, 1)
                      for n, what in ((batch, "batch"), (workers, "workers")))
    if dt is not None:
        if isinstance(dt, (bool, np.bool_)):
            raise TypeError(f"dt must be a real number > 0, got {dt!r} (a bool)")
        dt = scalar(dt, "dt", minimum=0.0, strict=True)
    grid = build_domain(domain if domain is not None else _default_domain(mdl, size))
    if grid.unstructured:
        raise ValueError("a sweep runs on a grid (size= or a grid domain), not a mesh")
    n_members = math.prod(a.size for a in axes.values())
    check_sweep_memory(n_members, tuple(grid.field_shape), len(mdl.species),
                       np.dtype(dtype).itemsize, batch, BATCH_MEMORY, store)
    _check_names(axes, mdl.species)
    species = tuple(mdl.species)
    classify = classify or pattern_species(mdl)
    if classify not in species:
        raise ValueError(f"classify={classify!r}: model {mdl.name} has {', '.join(species)}")
    options = dict(options or {})
    if dt is None:
        dt = _common_dt(mdl, grid, fixed, axes, options)
    return _Plan(mdl, axes, fixed, grid, n_members, species, classify, steps, seed, dt,
                 dtype, init, options, batch, workers)


def _settings_and_job(plan: _Plan, be: Backend, backend: Backend | str | None,
                      definition: dict, desc: dict) -> tuple[dict, dict]:
    """The sweep's settings (kept with its data; a resumed store must match them) and the
    job every batch's task runs (`run_batch`); ``definition``, ``desc``: the model's
    and the grid's descriptions."""
    mdl = plan.model
    settings = {
        "name": mdl.name, "model": definition or mdl.name, "axes":
        {k: v.tolist() for k, v in plan.axes.items()}, "fixed": plan.fixed,
        "domain": desc, "steps": plan.steps, "dt": float(plan.dt),
        "dtype": plan.dtype, "seed": int(plan.seed),
        "init": None if plan.init is None else json.loads(json.dumps(plan.init)),
        "options": json.loads(json.dumps(plan.options)), "batch": plan.batch,
        "backend_name": be.name, "classify": plan.classify, "species": list(plan.species),
    }
    job = {"name": mdl.name, "model": _task_model(mdl, definition), "domain": plan.grid,
           "fixed": plan.fixed, "steps": plan.steps, "dt": float(plan.dt),
           "dtype": plan.dtype, "seed": int(plan.seed), "init": plan.init,
           "options": plan.options,
           "backend": backend if isinstance(backend, str) or backend is None else be.name,
           "classify": plan.classify}
    return settings, job


def _collector(xr: Any, da: Any, plan: _Plan, settings: dict, n_batches: int,
               store: Any) -> _Collector:
    """Where the batches go: the zarr ``store`` created (or opened to resume), else
    arrays in memory, on the Dataset's template."""
    grid = plan.grid
    dx = {"x": grid.dx, "y": grid.dy or grid.dx, "z": grid.dz}
    template = _template(xr, da, settings, plan.axes, tuple(grid.field_shape), dx,
                         plan.species, n_batches)
    group = open_store(Path(store), template, settings) if store is not None else None
    return _Collector(template, group, plan.axes, plan.species, plan.batch, store)


class _Collector:
    """Where finished batches go: the zarr group, or arrays in memory."""

    def __init__(self, template: Any, group: Any, axes: dict[str, np.ndarray],
                 species: Sequence[str], batch: int, store: Any = None) -> None:
        self.template, self.group, self.species, self.batch = template, group, species, batch
        self.counts = tuple(a.size for a in axes.values())
        self.n = math.prod(self.counts)
        self.values = axes
        if group is None:
            self.arrays = {s: np.full(template[s].shape, np.nan, dtype=template[s].dtype)
                           for s in species}
            self.pattern = np.full(self.counts, -1, dtype=np.int8)
            self.flags = np.zeros(template["done"].shape, dtype=bool)
        else:  # the flags as stored, each checked against the batch's data
            self.flags = verify_done(group, Path(store), read_done(group, Path(store)),
                                     self.members, self.counts, tuple(species),
                                     PATTERN_CLASSES.index("diverged"), len(PATTERN_CLASSES))

    def members(self, b: int) -> range:
        return range(b * self.batch, min((b + 1) * self.batch, self.n))

    def batch_values(self, b: int) -> dict[str, list[float]]:
        idx = np.unravel_index(np.asarray(self.members(b)), self.counts)
        return {k: v[i].tolist() for (k, v), i in zip(self.values.items(), idx, strict=True)}

    def done(self, b: int) -> bool:
        return bool(self.flags[b])

    def store(self, b: int, out: Mapping[str, Any]) -> None:
        """Write batch ``b``'s fields and classes, then mark it done."""
        pattern = np.asarray(out["pattern"], dtype=np.int8)
        target = self.arrays if self.group is None else self.group
        codes = self.pattern if self.group is None else self.group["pattern"]
        for j, m in enumerate(self.members(b)):
            idx = np.unravel_index(m, self.counts)
            for s in self.species:
                target[s][idx] = out["fields"][s][j]
            codes[idx] = pattern[j]
        if self.group is not None:
            self.group["done"][b] = True
        self.flags[b] = True

    def dataset(self) -> Any:
        ds = self.template.copy()
        for s in self.species:
            ds[s] = (ds[s].dims, self.arrays[s], ds[s].attrs)
        ds["pattern"] = (ds["pattern"].dims, self.pattern, ds["pattern"].attrs)
        ds["done"] = (("batch",), self.flags)
        return ds


def _run(client: Any, job: dict, result: _Collector, todo: list[int], n_batches: int,
         progress: bool, on_batch: Callable[[int], None] | None) -> None:
    """Run the batches ``todo`` (in this process, or as tasks of ``client``) and store each
    as it finishes."""
    from tqdm.auto import tqdm

    bar = tqdm(total=n_batches, initial=n_batches - len(todo), unit="batch",
               desc=f"sweep {job['name']}", disable=not progress)
    try:
        if client is None:
            for b in todo:
                result.store(b, run_batch(job, result.batch_values(b)))
                bar.update(1)
                if on_batch is not None:
                    on_batch(b)
            return
        from distributed import as_completed

        token = _token(result)
        futures = {client.submit(run_batch, job, result.batch_values(b),
                                 key=f"rdgpu-sweep-{token}-{b}"): b for b in todo}
        try:
            for fut in as_completed(futures):
                b = futures[fut]
                result.store(b, fut.result())
                fut.release()
                bar.update(1)
                if on_batch is not None:
                    on_batch(b)
        except BaseException:
            client.cancel(list(futures))
            raise
    finally:
        bar.close()


def _token(result: _Collector) -> str:
    """A key prefix for this sweep's tasks (same settings → same keys)."""
    import hashlib

    text = json.dumps([result.template.attrs[SETTINGS_ATTR]], sort_keys=True)
    return hashlib.sha1(text.encode()).hexdigest()[:12]


class _CallableModule(types.ModuleType):
    """``rdgpu.sweep(...)`` calls `sweep` even after ``import rdgpu.sweep`` has made
    ``rdgpu.sweep`` this module."""

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return sweep(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
