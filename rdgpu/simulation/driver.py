"""Running a model: `Simulation`, its construction, checkpoints and ``run``.

A `Simulation` binds a model (`rdgpu.models`) to a domain (any
`Domain`: a grid, a graph surface, a mesh), parameter
values, a time step, a backend and a dtype, and runs it::

    sim = Simulation("gray-scott", Grid((128, 128)), {"F": 0.03, "k": 0.055}, dt=1.0)
    result = sim.run(5000, snapshot_every=100)

While it runs, the fields stay on the device.  Snapshots are device-to-device copies into
preallocated buffers, downloaded in batches (when the batch is full, at a checkpoint and at
the end).  Every ``check_every`` steps the state is downloaded and checked for NaN, Inf and
blow-up (``|x| >`` `DEFAULT_BOUND`, or the model's
optional ``blowup_bound``: a number or a per-species dict); a bad state stops the run with
`SimulationDiverged`, naming the first bad step (found by replaying
from the last good state), the field and a likely cause, and keeping the last good state
in ``exc.result``.

Checkpoints (``checkpoint=PATH``) are NPZ files written atomically (temporary file in the
same folder, ``fsync``, ``os.replace``): the state, the step, the parameters, the model,
the domain, the run settings and the snapshots taken so far.  ``run(steps, resume=PATH)``
(or `Simulation.resume`) continues from one and ends with the same result, bitwise,
as the uninterrupted run on the same backend: step boundaries fall on the same absolute
step numbers in both runs, and a model's stepper must give the same
arithmetic for ``advance(a); advance(b)`` as for ``advance(a + b)``.

The loop itself is `rdgpu.simulation.runner`; the checkpoint files
`rdgpu.simulation.checkpoints`.
"""

from __future__ import annotations

import json
import math
import numbers
import os
from collections.abc import Mapping
from contextlib import nullcontext
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.backends import interop
from rdgpu.backends.registry import get_backend
from rdgpu.core.conventions import REAL_DTYPES
from rdgpu.core.files import CheckpointLock, check_writable, remove_stale_temporaries
from rdgpu.domains.specs import build_domain, from_description
from rdgpu.ir.program import PerMember
from rdgpu.models import resolve_params
from rdgpu.models.ensemble import member_seeds, resolve_members, stack_members
from rdgpu.simulation import checkpoints
from rdgpu.simulation.checks import (
    MAX_STEPS,
    check_options,
    check_run_memory,
    check_simulation_memory,
    checkpoint_model,
    init_spec,
    whole,
)
from rdgpu.simulation.defaults import (
    DEFAULT_CHECK_EVERY,
    DEFAULT_CHECKPOINT_EVERY,
    accepts,
    default_dt,
    default_init,
    default_steps,
    domain_defaults,
    dt_limit,
    lookup_model,
    lookup_preset,
)
from rdgpu.simulation.initial import initial_state
from rdgpu.simulation.result import Result
from rdgpu.simulation.runner import Runner, restore

if TYPE_CHECKING:
    from rdgpu.backends.base import Backend
    from rdgpu.domains.base import Domain
    from rdgpu.models.model import Model

__all__ = ["Simulation"]


class Simulation:
    """A model bound to a domain, parameters, ``dt``, a backend and a dtype, with its state.

    Parameters
    ----------
    model : Model or str
        A model (``rdgpu.define_model``) or a name in ``rdgpu.models.MODELS``.
    domain : Grid, SurfaceMesh or dict
        Where it runs (a dict as in `build_domain`).
    params : dict
        Parameter values over ``model.defaults``: numbers, per-cell/per-vertex arrays or
        field specs (``rdgpu.models.param_field``, drawn with ``seed``).
    dt : float
        The time step (default: `default_dt`).
    backend : str or Backend
        As ``rdgpu.get_backend`` takes it (default: the current default backend).
    dtype : "float32" or "float64"
    seed : int
        Seed of the initial condition (see `initial_state`) and of random
        parameter fields.
    init : dict
        The initial condition (default: `default_init`); ignored if ``fields`` given.
    fields : dict of arrays
        Explicit initial fields, one per species: NumPy arrays, lists, or any library's
        arrays (`rdgpu.interop`: Warp, pyopencl, PyTorch, DLPack), read once on the
        host (in place where the host can; ``Result`` holds NumPy arrays).  Parameter
        fields in ``params`` may be any such array too.
    check_stability : bool
        With ``True`` the model raises `StabilityError` when
        ``dt > model.dt_limit(domain, params)``; with ``False`` it is asked to run anyway.
    options : dict
        Extra keyword arguments of ``model.stepper`` (and of ``model.dt_limit`` where it
        takes them), e.g. ``{"method": "implicit"}``.
    members : int
        Run an ensemble of that many members in one launch per step: every field is
        ``[members, *shape]``; a parameter is a number (all members), an array of shape
        ``(members,)`` (one number each), of the domain's shape (one field for all) or
        ``(members, *shape)`` (one field each); ``seed`` an int (all members) or one per
        member.  Each member is bit for bit the run it would be alone with the same ``dt``
        (default: the smallest of the members' defaults).  A member that diverges is
        reported (``Result.diverged_members``) and frozen at its last good state; the
        others go on.
    bc, noise : dict, optional
        Conditions per species and side over the grid's own, ``{"u": {"x-": ("value",
        "sin(t)")}, "v": ("neumann", 0.5)}`` (docs/boundaries.md); Itô noise, each species'
        variance (``{"u": "0.1*u"}``, docs/noise.md; its numbers keyed by ``seed``).  Kept
        as ``options["bc"]``, ``options["noise"]``.
    """

    def __init__(
        self,
        model: Model | str,
        domain: Domain | Mapping[str, Any],
        params: Mapping[str, Any] | None = None,
        *,
        dt: float | None = None,
        backend: Backend | str | None = None,
        dtype: Any = "float32",
        seed: int = 0,
        init: Mapping[str, Any] | None = None,
        fields: Mapping[str, np.ndarray] | None = None,
        check_stability: bool = True,
        options: Mapping[str, Any] | None = None,
        members: int | None = None,
        bc: Mapping[str, Any] | None = None,
        noise: Any = None,
    ) -> None:
        self.model = lookup_model(model)
        self.domain_source = domain if isinstance(domain, Mapping) else None
        self.domain = build_domain(domain)
        #: the domain's shape (one member's)
        self.shape = self.domain.field_shape
        #: None, or the number of ensemble members
        self.members = None if members is None else whole(members, "members", 1)
        if self.members is not None and not accepts(self.model.stepper, "members"):
            raise ValueError(f"model {self.model.name!r} cannot run as an ensemble (its "
                             "stepper takes no members); run the members one by one")
        #: every field's shape: ``(members, *shape)`` for an ensemble, else `shape`
        self.field_shape = self.shape if self.members is None else (self.members, *self.shape)
        self.species = tuple(self.model.species)
        try:
            self.dtype = np.dtype(dtype)
        except TypeError:
            raise ValueError(f"dtype must be float32 or float64, got {dtype!r}") from None
        if self.dtype not in REAL_DTYPES:
            raise ValueError(f"dtype must be float32 or float64, got {self.dtype}")
        # refused from the shared estimate before anything is made for the members/cells
        check_simulation_memory(self.field_shape, len(self.species), self.dtype.itemsize,
                                self.members)
        if self.members is not None and isinstance(seed, (list, tuple, np.ndarray)):
            self.seed: int | list[int] = [
                whole(k, "seed") for k in member_seeds(seed, self.members)]
        else:
            self.seed = whole(seed, "seed")
        self.options = check_options(self.model, options, bc, noise, self.seed)
        each = self._set_params(params)
        self._set_dt(dt, list({id(p): p for p in each}.values()), check_stability)
        self.backend = get_backend(backend)
        if fields is not None:
            self.init = None
        elif init is not None:
            self.init = init_spec(init)
        else:  # one initial condition, or one per member where the defaults differ
            inits = [default_init(self.model, p, self.domain) for p in each]
            self.init = inits[0] if all(i == inits[0] for i in inits) else inits
        self.preset: Any = None
        kwargs = self._stepper_options()
        if fields is not None:  # checked before the stepper's programs are built
            start = self._check_fields(fields)
        elif self.members is None:
            start = initial_state(self.init, self.domain, self.species, self.seed, self.dtype)
        else:
            start = self._member_states()
        self.stepper = self.model.stepper(self.domain, dict(self.params), dt=self.dt,
                                          backend=self.backend, dtype=self.dtype, **kwargs)
        self.stepper.set_state(start)
        #: ensemble members frozen after diverging: member -> what happened
        self.frozen: dict[int, str] = {}
        self.step = 0
        self._resume_run: dict | None = None
        self._resume_snaps: tuple[dict, list] | None = None

    # ------------------------------------------------------------------ construction
    def _set_params(self, params: Mapping[str, Any] | None) -> list[dict[str, Any]]:
        """Set `params` (a member's own values stacked for an ensemble) and return
        each member's parameters (one dict without members)."""
        if params is not None and not isinstance(params, Mapping):
            raise TypeError(f"params must be a dict of parameter values, got "
                            f"{type(params).__name__} {params!r}")
        if self.members is None:
            self.params = self._merge_params(params or {}, self.seed)
            return [self.params]
        each = resolve_members(self._merge_params, params or {}, self.members,
                               self.shape, self.seed)
        self.params = {k: (np.asarray(v.values) if isinstance(v, PerMember) else v)
                       for k, v in stack_members(each, self.shape).items()}
        return each

    def _set_dt(self, dt: Any, distinct: list[dict[str, Any]], check_stability: bool) -> None:
        """Set `dt` (default: the smallest default of the ``distinct`` parameter
        sets), ``check_stability`` and `dt_limit`."""
        if dt is None:
            dt = min(default_dt(self.model, self.domain, p, self.options) for p in distinct)
        if isinstance(dt, (bool, np.bool_)) or not isinstance(dt, numbers.Real):
            raise TypeError(f"dt must be a positive number, got {type(dt).__name__} {dt!r}")
        self.dt = float(dt)
        if not (math.isfinite(self.dt) and self.dt > 0):
            raise ValueError(f"dt must be a positive number, got {dt}")
        self.check_stability = bool(check_stability)
        self.dt_limit = min(dt_limit(self.model, self.domain, p, self.options)
                            for p in distinct)

    def _stepper_options(self) -> dict[str, Any]:
        """The keyword arguments of ``model.stepper``: the options, ``check_stability``
        when off, ``members`` of an ensemble."""
        kwargs = dict(self.options)
        if not self.check_stability:
            if not accepts(self.model.stepper, "check_stability"):
                raise ValueError(f"model {self.model.name} cannot run with "
                                 "check_stability=False")
            kwargs["check_stability"] = False
        if self.members is not None:
            kwargs["members"] = self.members
        return kwargs

    def _member_states(self) -> dict[str, np.ndarray]:
        """Each member's initial fields (its own init and seed), stacked."""
        seeds = member_seeds(self.seed, self.members)
        inits = self.init if isinstance(self.init, list) else [self.init] * self.members
        out = {s: np.empty(self.field_shape, self.dtype) for s in self.species}
        done: dict[tuple, dict[str, np.ndarray]] = {}
        for m, (init, seed) in enumerate(zip(inits, seeds, strict=True)):
            key = (json.dumps(init, sort_keys=True, default=checkpoints.json_default), seed)
            if key not in done:
                done[key] = initial_state(init, self.domain, self.species, seed, self.dtype)
            for s in self.species:
                out[s][m] = done[key][s]
        return out

    def _merge_params(self, params: Mapping[str, Any], seed: int = 0) -> dict[str, Any]:
        """Defaults updated by ``params``; every value a float or a float64 array of the
        domain's shape (field specs drawn as ``rdgpu.models.resolve_params`` does)."""
        defaults = dict(self.model.defaults)
        unknown = set(params) - set(defaults)
        if unknown:
            raise ValueError(f"unknown parameter(s) {sorted(unknown)} for model "
                             f"{self.model.name}; known: {', '.join(defaults)}")
        defaults.update(domain_defaults(self.model, self.domain, self.options))
        for k, v in params.items():
            if isinstance(v, (complex, np.complexfloating)) or (
                    isinstance(v, np.ndarray) and v.dtype.kind == "c"):
                raise TypeError(f"parameter {k!r} is complex ({v!r:.60}); parameters are real "
                                "numbers or real fields")
        if any(isinstance(v, (Mapping, str)) for v in {**defaults, **params}.values()):
            given = {**domain_defaults(self.model, self.domain, self.options), **params}
            return dict(resolve_params(self.model, self.domain, given, seed=seed))
        out: dict[str, Any] = {}
        for k, v in {**defaults, **params}.items():
            if isinstance(v, (list, tuple)) or interop.is_array(v):
                v = interop.to_numpy(v)  # any library's array: read in place or one copy
            if isinstance(v, np.ndarray) and v.ndim > 0:
                if v.dtype.kind not in "fiub":
                    raise TypeError(f"parameter {k!r} as a field must hold real numbers, "
                                    f"got dtype {v.dtype}")
                if v.shape != self.shape:
                    raise ValueError(f"parameter {k!r} as a field must have shape {self.shape}, "
                                     f"got {v.shape}")
                if not np.isfinite(v).all():
                    raise ValueError(f"parameter field {k!r} contains NaN or Inf")
                out[k] = np.ascontiguousarray(v, dtype=np.float64)
            else:
                if isinstance(v, (bool, np.bool_, bytes)):
                    raise TypeError(f"parameter {k!r} must be a number, a field, a field spec "
                                    f"or an expression string, got {type(v).__name__} {v!r}")
                try:
                    out[k] = float(v)
                except (TypeError, ValueError):
                    raise ValueError(f"parameter {k!r} must be a number or a field, "
                                     f"got {v!r}") from None
                if not math.isfinite(out[k]):
                    raise ValueError(f"parameter {k!r} must be finite, got {v!r}")
        return out

    def _check_fields(self, fields: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        if not isinstance(fields, Mapping):
            raise TypeError(f"fields must be a dict of arrays, one per species "
                            f"{list(self.species)}; got {type(fields).__name__}")
        missing = set(self.species) - set(fields)
        if missing:
            raise ValueError(f"fields missing for species {sorted(missing)}")
        extra = set(fields) - set(self.species)
        if extra:
            raise ValueError(f"fields given for unknown species {sorted(extra)}; the model "
                             f"has {list(self.species)}")
        out = {}
        for s in self.species:
            f = fields[s]  # any library's array (rdgpu.interop): read in place or one copy
            a = interop.to_numpy(f) if interop.is_array(f) else np.asarray(f)
            if a.dtype.kind == "c":
                raise TypeError(f"field {s!r} is complex ({a.dtype}); fields must be real "
                                "(float32 or float64): pass the real part if that is meant")
            if a.dtype.kind not in "fiu":
                raise TypeError(f"field {s!r} must hold real numbers, got dtype {a.dtype}")
            if a.shape != self.field_shape:
                raise ValueError(f"field {s!r} must have shape {self.field_shape}, got "
                                 f"{a.shape}" + (f" ({self.members} members)" if self.members
                                                 else ""))
            with np.errstate(over="ignore"):
                out[s] = np.ascontiguousarray(a, dtype=self.dtype)
            finite = np.isfinite(out[s])
            if not finite.all():
                past = "" if np.isfinite(a).all() else " in the given array"
                raise ValueError(f"field {s!r} has {int(a.size - finite.sum())} NaN or Inf "
                                 f"value(s){past or ' as ' + self.dtype.name}")
        return out

    @classmethod
    def from_preset(
        cls,
        preset: Any,
        *,
        domain: Domain | Mapping[str, Any] | None = None,
        params: Mapping[str, Any] | None = None,
        dt: float | None = None,
        backend: Backend | str | None = None,
        dtype: Any = "float32",
        seed: int | None = None,
        init: Mapping[str, Any] | None = None,
        check_stability: bool = True,
        members: int | None = None,
    ) -> Simulation:
        """A simulation of a preset (a ``rdgpu.models.Preset`` or its name); ``domain``,
        ``params`` (merged over the preset's), ``dt``, ``seed`` and ``init`` override it;
        ``members`` makes it an ensemble (see `Simulation`).
        ``run()`` then defaults to the preset's ``steps`` and ``snapshot_every``.

        Parameters
        ----------
        preset : Preset or str
            A `rdgpu.models.Preset` or a name in ``rdgpu.models.PRESETS`` (else a
            ``TypeError``/``ValueError``).
        domain : Grid, SurfaceMesh or dict, optional
            Replaces the preset's domain (default ``None``: the preset's).
        params : dict, optional
            Parameter values merged over the preset's ``params``.
        dt : float, optional
            The time step in the model's time units (default ``None``: the preset's).
        backend : str or Backend, optional
            As `rdgpu.get_backend` takes it (default: the current default backend).
        dtype : "float32" or "float64"
            The fields' dtype (default ``"float32"``).
        seed : int, optional
            Seed of the initial condition and random parameter fields (default ``None``:
            the preset's ``seed``).
        init : dict, optional
            The initial condition (default ``None``: the preset's ``init``).
        check_stability : bool
            As in `Simulation` (default ``True``).
        members : int, optional
            Run an ensemble of that many members (see `Simulation`).
        """
        p = lookup_preset(preset)
        sim = cls(p.model, p.domain if domain is None else domain,
                  {**(p.params or {}), **(params or {})}, dt=p.dt if dt is None else dt,
                  backend=backend, dtype=dtype, seed=getattr(p, "seed", 0) if seed is None
                  else seed, init=p.init if init is None else init,
                  check_stability=check_stability, options=getattr(p, "options", None),
                  members=members)
        sim.preset = p
        return sim

    time = property(lambda self: self.step * self.dt, doc="The simulated time, step·dt.")

    def state(self) -> dict[str, np.ndarray]:
        """Download the current fields."""
        return self.host_state()

    def host_state(self, history: bool = False) -> dict[str, np.ndarray]:
        """The current fields, downloaded, each of `shape`; ``history``: also what a
        multistep method carries between steps (BDF2's previous level, ``"_prev_<s>"``:
        `rdgpu.integrators.ModelStepper.get_state`), so that ``stepper.set_state`` of it
        goes on bit for bit.

        Parameters
        ----------
        history : bool
            Also return the multistep history (default ``False``: the species only).

        Returns
        -------
        dict of str to numpy.ndarray
            Species name (and ``"_prev_<s>"`` with ``history``) → a host array of the
            simulation's dtype and shape ``field_shape`` (``(members, *shape)`` for an
            ensemble).
        """
        get = self.stepper.get_state
        state = get(history=True) if history and accepts(get, "history") else get()
        return {k: a.reshape(self.field_shape) for k, a in state.items()}

    # ------------------------------------------------------------------ checkpoints
    def save_checkpoint(self, path: str | os.PathLike) -> Path:
        """Write the current state (no run in progress) as a checkpoint, atomically.

        Parameters
        ----------
        path : str or os.PathLike
            The checkpoint file to write (replaced if it exists).

        Returns
        -------
        pathlib.Path
            ``path``.
        """
        run = {"start": self.step, "target": self.step, "snapshot_every": None,
               "check_every": None, "checkpoint_every": None}
        arrays = checkpoints.checkpoint_arrays(self, self.host_state(history=True), run,
                                               {s: [] for s in self.species}, [])
        checkpoints.write_checkpoint(path, arrays)
        return Path(path)

    @staticmethod
    def read_checkpoint(path: str | os.PathLike) -> tuple[dict, dict[str, np.ndarray]]:
        """``(meta, arrays)`` of a checkpoint file; a ``ValueError`` saying what is wrong
        with a file that is missing, empty, truncated, corrupt or not a checkpoint.

        Parameters
        ----------
        path : str or os.PathLike
            The checkpoint file (as `save_checkpoint` or ``run(checkpoint=...)`` wrote it).

        Returns
        -------
        tuple of (dict, dict of str to numpy.ndarray)
            Its metadata (model, parameters, domain, dt, dtype, step, run settings) and
            arrays (fields, parameter fields, snapshots).
        """
        return checkpoints.read_checkpoint(path)

    @classmethod
    def resume(cls, path: str | os.PathLike, *, model: Model | str | None = None,
               backend: Backend | str | None = None,
               check_stability: bool | None = None) -> Simulation:
        """A simulation rebuilt from a checkpoint, at its step.  ``run()`` (no ``steps``)
        then finishes the interrupted run with its settings.  A model defined by equations
        is rebuilt from the equations the checkpoint holds, whatever its name (a built-in's
        too); ``model`` is needed only for a model of Python code not in
        ``rdgpu.models.MODELS``, and one passed must be the checkpoint's (name, species,
        equations, bounds: a ValueError says what differs); ``backend`` defaults to the
        checkpoint's.
        Temporary files of killed writers of the checkpoint are removed
        (`remove_stale_temporaries`).

        Parameters
        ----------
        path : str or os.PathLike
            The checkpoint file.
        model : Model or str, optional
            The checkpoint's model, needed only for a model of Python code that is not in
            ``rdgpu.models.MODELS`` (default ``None``: rebuilt from the checkpoint).
        backend : str or Backend, optional
            Where to run (default ``None``: the checkpoint's backend).
        check_stability : bool, optional
            As in `Simulation` (default ``None``: the checkpoint's setting).

        Returns
        -------
        Simulation
            At the checkpoint's step, its state, frozen members and snapshots restored.

        Raises
        ------
        ValueError
            The file is not a readable checkpoint, or ``model`` is not the checkpoint's.
        """
        remove_stale_temporaries(path)
        meta, arrays = cls.read_checkpoint(path)
        # a model defined by equations is rebuilt from them, whatever its name (a built-in's
        # too); a model passed here must be the checkpoint's
        model = checkpoint_model(meta, None if model is None else lookup_model(model), path)
        model = lookup_model(meta["model"]) if model is None else model
        params = dict(meta["params"])
        for k in meta["param_fields"]:
            params[k] = arrays[f"param__{k}"]
        domain = from_description(meta["domain"], arrays)
        fields = {s: arrays[f"field__{s}"] for s in meta["species"]}
        sim = cls(model, domain, params, dt=meta["dt"],
                  backend=meta["backend"] if backend is None else backend,
                  dtype=meta["dtype"], seed=meta["seed"], fields=fields,
                  check_stability=(meta["check_stability"] if check_stability is None
                                   else check_stability), options=meta.get("options"),
                  members=meta.get("members"))
        sim.init = meta["init"]
        if meta["domain"].get("source"):
            sim.domain_source = meta["domain"]["source"]
        sim._load_run(meta, arrays, path)
        return sim

    def _load_run(self, meta: dict, arrays: dict[str, np.ndarray], path: Any) -> None:
        if tuple(meta["species"]) != self.species:
            raise ValueError(f"checkpoint species {meta['species']} differ from the model's "
                             f"{list(self.species)}")
        fields = self._check_fields({s: arrays[f"field__{s}"] for s in self.species})
        if any(fields[s].dtype != arrays[f"field__{s}"].dtype for s in self.species):
            raise ValueError(f"checkpoint dtype {meta['dtype']} differs from the "
                             f"simulation's {self.dtype}")
        history = {k[len("history__"):]: v for k, v in arrays.items()
                   if k.startswith("history__")}
        restore(self.stepper, {**fields, **history}, int(meta["step"]))
        self.frozen = {int(m): what for m, what in (meta.get("frozen") or {}).items()}
        self.step = int(meta["step"])
        self._resume_run = {**meta["run"], "path": str(path)}
        snaps = {s: list(arrays[f"snap__{s}"]) for s in self.species}
        self._resume_snaps = (snaps, [int(k) for k in arrays["snap_steps"]])

    def _load_checkpoint_into(self, path: str | os.PathLike) -> None:
        remove_stale_temporaries(path)
        meta, arrays = self.read_checkpoint(path)
        checkpoints.check_resumable(self, meta, arrays, path)
        self._load_run(meta, arrays, path)

    # ------------------------------------------------------------------ the time loop
    @property
    def default_steps(self) -> int | None:
        """What ``run()`` does without ``steps``: the preset's steps, else the model's
        ``default_time`` over ``dt`` (see `default_steps`), else ``None``."""
        steps = getattr(self.preset, "steps", None)
        if steps is not None:
            return int(steps)
        return default_steps(self.model, self.dt, self.params)

    def run(
        self,
        steps: int | None = None,
        *,
        snapshot_every: int | None = None,
        check_every: int | None = None,
        checkpoint: str | os.PathLike | None = None,
        checkpoint_every: int | None = None,
        progress: bool = True,
        resume: str | os.PathLike | None = None,
    ) -> Result:
        """Advance ``steps`` steps and return a `Result`.

        ``steps`` (a whole number >= 0) defaults to `default_steps`: the preset's,
        else the model's default run length in its time units over ``dt``.
        ``snapshot_every``: keep a snapshot at every step that is a multiple of it (the
        first at the start of the run if its step is a multiple, and always the last).
        ``check_every`` (default 200, 0 disables): check for NaN/Inf/blow-up at multiples
        of it and at the end; a bad state raises `SimulationDiverged` with the last
        good state in ``exc.result`` and the simulation left at that state.
        ``checkpoint``: path of a checkpoint written atomically at multiples of
        ``checkpoint_every`` (default 1000) and at the end; every state written is checked
        first, so a checkpoint never holds a diverged state; a path that cannot be written
        (`rdgpu.core.files.check_writable`) is refused before the first step, as
        are steps past 2**53 and snapshots that cannot fit in memory.  Temporary files that
        killed writers of that checkpoint left behind are removed (see
        `remove_stale_temporaries`).  ``progress``: a tqdm bar on stderr for runs
        lasting more than a second.

        Ctrl-C: in the main thread, SIGINT is taken at the end of the chunk of steps that
        is running (at most 100 steps; a second Ctrl-C interrupts at once); that state is
        checked, written as a checkpoint if ``checkpoint`` is given, and
        `SimulationInterrupted` (a ``KeyboardInterrupt``) is raised with it in
        ``exc.result``.  Any other ``KeyboardInterrupt`` during the run also becomes
        `SimulationInterrupted`, with the last checked state (the simulation goes
        back to it).

        ``resume=PATH`` repeats an interrupted ``run`` call from its last checkpoint: the
        state, the snapshots so far and (where not given here) the run settings come from
        the checkpoint, ``steps`` counts from the start of the interrupted call (default:
        what that call asked for), and checkpoints go on to PATH unless ``checkpoint`` is
        given.  The simulation must be the checkpoint's: same model, parameters, dt,
        options and domain (grid shape, dx, dy, boundary conditions; mesh vertices and
        faces).  After `resume`, ``run()`` does the same.

        Parameters
        ----------
        steps : int, optional
            Steps to advance, a whole number in ``[0, 2**53]`` (a float with a whole value
            is taken); default ``None`` as above.
        snapshot_every, check_every, checkpoint_every : int, optional
            Steps between snapshots (default: the preset's, else 0: the last state only),
            divergence checks (default 200; 0 disables) and checkpoints (default 1000).
        checkpoint, resume : str or os.PathLike, optional
            The checkpoint file to keep; one of an interrupted call to finish (as above).
        progress : bool
            Show a tqdm progress bar (default ``True``).

        Returns
        -------
        Result
            The snapshots, the final state and the run's metadata.

        Raises
        ------
        SimulationDiverged, SimulationInterrupted
            As above.
        TypeError
            ``checkpoint`` or ``resume`` is not a path, or a step count is not a number.
        ValueError
            A step count out of range, no ``steps`` and no default, a run past step 2**53,
            an unwritable ``checkpoint``, a checkpoint that does not match;
            `rdgpu.ResourceLimitError` where the snapshots cannot fit in memory.
        """
        if steps is not None:
            steps = whole(steps, "steps", 0, MAX_STEPS)
        snapshot_every = None if snapshot_every is None else whole(snapshot_every,
                                                                    "snapshot_every")
        check_every = None if check_every is None else whole(check_every, "check_every")
        checkpoint_every = None if checkpoint_every is None else whole(checkpoint_every,
                                                                        "checkpoint_every")
        if checkpoint is not None and not isinstance(checkpoint, (str, os.PathLike)):
            raise TypeError(f"checkpoint must be a path, got {type(checkpoint).__name__}")
        if checkpoint is not None:  # before any step: a device, a folder, "" are refused
            check_writable(checkpoint, "checkpoint")
        if resume is not None:
            if not isinstance(resume, (str, os.PathLike)):
                raise TypeError(f"resume must be a path, got {type(resume).__name__}")
            self._load_checkpoint_into(resume)
        run0 = self._resume_run
        self._resume_run = None
        snaps, snap_steps = self._resume_snaps or ({s: [] for s in self.species}, [])
        self._resume_snaps = None
        run_info, checkpoint = self._run_settings(run0, steps, snapshot_every, check_every,
                                                  checkpoint_every, checkpoint)
        target = run_info["target"]
        if target > MAX_STEPS:
            raise ValueError(f"steps: a run to step {target} is past the largest step "
                             f"{MAX_STEPS} (2**53)")
        check_run_memory(target - self.step, run_info["snapshot_every"], len(snap_steps),
                         self.field_shape, len(self.species), self.dtype.itemsize)
        if checkpoint is not None:
            check_writable(checkpoint, "checkpoint")
            remove_stale_temporaries(checkpoint)
        with CheckpointLock(checkpoint) if checkpoint is not None else nullcontext():
            return Runner(self, run_info, snaps, snap_steps, checkpoint, progress).go()

    def _run_settings(self, run0: dict | None, steps: int | None, snapshot_every: int | None,
                      check_every: int | None, checkpoint_every: int | None,
                      checkpoint: Any) -> tuple[dict, Any]:
        """``(run, checkpoint)``: the settings of a run (``start``, ``target``,
        ``snapshot_every``, ``check_every``, ``checkpoint_every``) and its checkpoint path,
        from those given, else the interrupted run's (``run0``, after a resume), else the
        defaults (the preset's, the model's, ``DEFAULT_CHECK_EVERY``,
        ``DEFAULT_CHECKPOINT_EVERY`` of `rdgpu.simulation.defaults`)."""
        if run0 is not None:
            start = int(run0["start"])
            target = int(run0["target"]) if steps is None else start + steps
            snapshot_every = run0["snapshot_every"] if snapshot_every is None else snapshot_every
            check_every = run0["check_every"] if check_every is None else check_every
            checkpoint_every = (run0["checkpoint_every"] if checkpoint_every is None
                                else checkpoint_every)
            if checkpoint is None:  # keep checkpointing to the file resumed from
                checkpoint = run0["path"]
            if target < self.step:
                raise ValueError(f"the checkpoint is at step {self.step}, past the end of a "
                                 f"run of {target - start} steps")
        else:
            if steps is None:
                steps = self.default_steps
                if steps is None:
                    raise ValueError("run() needs the number of steps (the model has no "
                                     "default_time)")
            if snapshot_every is None and self.preset is not None:
                snapshot_every = getattr(self.preset, "snapshot_every", None)
            start, target = self.step, self.step + int(steps)
        check_every = DEFAULT_CHECK_EVERY if check_every is None else int(check_every)
        snapshot_every = int(snapshot_every) if snapshot_every else 0
        if checkpoint is not None and not checkpoint_every:
            checkpoint_every = DEFAULT_CHECKPOINT_EVERY
        checkpoint_every = int(checkpoint_every or 0) if checkpoint is not None else 0
        return {"start": start, "target": target, "snapshot_every": snapshot_every,
                "check_every": check_every, "checkpoint_every": checkpoint_every}, checkpoint
