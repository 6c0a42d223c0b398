"""Level sets driven by reaction-diffusion (seed 003, §4.2).

A model runs on a 2-D grid (through `rdgpu.Simulation`'s stepper, on any backend)
while a front ``φ_t + β|∇φ| = 0`` (equations §5, first-order upwind, ``φ < 0`` inside)
moves with a speed taken from one of the model's fields ``a``:

* ``speed="laplace"``: ``β = beta_scale · Δa`` (the seed's choice, Step 2 of §4.2: the
  gradient-descent direction of the energy ``∫|∇a|²``), ``Δa`` the 5-point Laplacian
  (`rdgpu.laplacian`, the grid's boundary conditions);
* ``speed="offset"``: ``β = beta_scale · (a − a0)``.

Each driver step advances the model by one step ``dt`` and the front by the same time
``dt``, cut into as many equal substeps as the upwind CFL limit
``Δt · max|β| · (1/dx + 1/dy) ≤ 1`` (`rdgpu.levelset_dt_limit`) asks for.  Every
``reinit_every`` steps φ is reinitialised to a signed distance (`rdgpu.reinitialize`'s
scheme, with the subcell fix, on the device).  The region ``φ < 0`` is the pattern (the
seed stops "when we get a stable pattern"; the front settles where ``β = 0``).

`TURING_FRONT` is a default configuration (`turing_front`; seed 003's label,
``seed003_front``, is an alias): the seed's own reaction-diffusion model (Turing's spots,
eq. 2.15, the ``turing-seed003-spots`` preset) with β = Δa of the activator ``a = u``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.core import validation as check
from rdgpu.core.errors import StabilityError
from rdgpu.core.resources import check_fields
from rdgpu.domains.boundary import PERIODIC, GridBC, parse_bc
from rdgpu.domains.grid import Grid
from rdgpu.io.images import save_png
from rdgpu.ops.api import laplacian, levelset_dt_limit
from rdgpu.simulation.driver import Simulation

if TYPE_CHECKING:
    from rdgpu.backends.base import Backend
    from rdgpu.domains.base import Domain
    from rdgpu.models.model import Model

SPEEDS = ("laplace", "offset")

#: A preset-like default reproducing seed 003's Fig. 4.2 set-up as closely as the text
#: allows (its figure's parameters are lost): the seed's Turing model (eq. 2.15) on its
#: 64×64 grid, spots formed first (``warmup`` model steps, the preset's 8000 at dt = 0.5),
#: then the front from a small circle (radius 3 cells) driven by β = Δa of ``a = u`` for
#: ``steps`` more steps.  The front runs out along the valleys of ``a`` (Δa > 0) and stops
#: at the spots' rims (Δa = 0): the region φ < 0 is the sea around ~100 spots.
TURING_FRONT: dict[str, Any] = {
    "preset": "turing-seed003-spots",
    "field": "u",
    "speed": "laplace",
    "beta_scale": 1.0,
    "warmup": 8000,
    "steps": 1000,
    "reinit_every": 20,
    "radius": 3.0,
}
#: seed 003's label for `TURING_FRONT` (an alias)
SEED003_FRONT = TURING_FRONT


@dataclass
class FrontResult:
    """What `front_growth` returns.

    Attributes
    ----------
    phi : numpy.ndarray
        The final level-set function ``[ny, nx]`` (the simulation's dtype), negative inside.
    mask : numpy.ndarray
        The region ``φ < 0`` (bool ``[ny, nx]``): the pattern.
    snapshots, snapshot_steps : list of numpy.ndarray, list of int
        φ every ``snapshot_every`` driver steps, and those steps.
    fields : dict of str to numpy.ndarray
        The model's final fields.
    time : float
        The time the front moved (model time units).
    substeps : int
        Front substeps in all.
    max_speed : float
        The largest ``|β|`` seen.
    """

    phi: np.ndarray
    mask: np.ndarray
    snapshots: list[np.ndarray] = field(default_factory=list)
    snapshot_steps: list[int] = field(default_factory=list)
    fields: dict[str, np.ndarray] = field(default_factory=dict)
    time: float = 0.0
    substeps: int = 0
    max_speed: float = 0.0

    def save_png(self, path: str | Path, *, scale: int = 4) -> Path:
        """Write the pattern (the region ``φ < 0``) as a PNG; see `save_pattern_png`.

        Parameters
        ----------
        path : str or pathlib.Path
            The PNG file to write.
        scale : int
            Pixels per cell along each side (default 4).
        """
        return save_pattern_png(path, self.mask, scale=scale)


def save_pattern_png(path: str | Path, mask: np.ndarray, *, scale: int = 4) -> Path:
    """Write a pattern mask as a black (inside, ``True``) on white PNG, each cell
    ``scale``×``scale`` pixels; returns the path.

    Parameters
    ----------
    path : str or pathlib.Path
        The PNG file, written atomically (a path that is not a regular file is refused).
    mask : array_like
        A 2-D mask ``[ny, nx]`` (else a ValueError); ``True`` (nonzero) is inside.
    scale : int
        Pixels per cell along each side (default 4).
    """
    m = np.asarray(mask)
    if m.ndim != 2:
        raise ValueError(f"a pattern image needs a 2-D mask, got shape {m.shape}")
    return save_png(path, (~m.astype(bool)).astype(np.float64), cmap="gray", vmin=0.0,
                    vmax=1.0, scale=scale)


def circle_phi(grid: Grid, radius: float | None = None) -> np.ndarray:
    """Signed distance to a circle in the middle of ``grid`` (negative inside); the radius
    defaults to a quarter of the shorter side.  Units: lengths of the grid.

    Parameters
    ----------
    grid : Grid
        A 2-D grid: the distance is taken at its cell centres, a float64 ``[ny, nx]``.
    radius : float, optional
        The circle's radius in the grid's length units (default ``None``: a quarter of
        the shorter side).
    """
    y, x = grid.coordinates()
    ly, lx = grid.lengths
    r = min(lx, ly) / 4.0 if radius is None else float(radius)
    return np.sqrt((x - lx / 2.0) ** 2 + (y - ly / 2.0) ** 2) - r


def _front_bc(grid: Grid) -> GridBC:
    """φ's conditions: periodic where the model's axis is, else zero-flux (seed 003 eq.
    4.10a; a model's Dirichlet value means nothing for φ)."""
    kinds = ["periodic" if b.kind == PERIODIC else "neumann" for b in (grid.bcs.y, grid.bcs.x)]
    return parse_bc(tuple(kinds), 2)


class RDFront:
    """A model and a front moved by one of its fields (see the module doc).

    Parameters
    ----------
    sim : rdgpu.Simulation
        A simulation on a 2-D grid (its stepper is advanced in place).
    field : str, optional
        The species giving ``a`` (default: the first).
    speed, a0, beta_scale, reinit_every, reinit_iterations
        As in `front_growth` (``reinit_every=0``: never).
    phi0 : array, optional
        The initial φ (default: `circle_phi` of ``radius``).
    radius : float, optional
        The default circle's radius.
    substep : bool
        False raises `StabilityError` instead of cutting a step that breaks the CFL
        limit.
    """

    def __init__(self, sim: Any, *, field: str | None = None, speed: str = "laplace",
                 a0: float = 0.0, beta_scale: float = 1.0, reinit_every: int = 10,
                 reinit_iterations: int = 8, phi0: np.ndarray | None = None,
                 radius: float | None = None, substep: bool = True) -> None:
        grid = sim.domain
        if grid.kind == "graph-surface":  # its fronts are not flat
            raise ValueError("a reaction-diffusion front moves in the flat plane of a 2-D "
                             "grid; a graph surface (z = h) is not supported: use a "
                             "flat Grid((ny, nx))")
        if grid.kind != "grid" or len(grid.axes) != 2 or sim.members is not None:
            raise ValueError("a reaction-diffusion front runs on a single 2-D grid (ny, nx); "
                             f"got a {grid.label} of shape {grid.field_shape}"
                             + (" as an ensemble" if sim.members is not None else ""))
        species = tuple(sim.species)
        name = species[0] if field is None else field
        if not isinstance(name, str) or name not in species:
            raise ValueError(f"unknown field {name!r}: model {sim.model.name!r} has the "
                             f"species {', '.join(map(repr, species))}")
        if not isinstance(speed, str) or speed not in SPEEDS:
            raise ValueError(f"speed must be one of {SPEEDS} (β = Δa or β = a − a0), "
                             f"got {speed!r}")
        self.sim, self.grid, self.field, self.speed = sim, grid, name, speed
        self.a0 = check.scalar(a0, "a0", minimum=None)
        self.beta_scale = check.scalar(beta_scale, "beta_scale", minimum=None)
        self.reinit_every = check.steps(reinit_every, "reinit_every")
        self.reinit_iterations = check.steps(reinit_iterations, "reinit_iterations")
        self.substep = check.flag(substep, "substep")
        self._bcs = _front_bc(grid)
        if radius is not None:
            radius = check.scalar(radius, "radius", strict=True)
        phi = (circle_phi(grid, radius) if phi0 is None
               else check.as_field(phi0, "phi0", ndim=(2,), backend=sim.stepper.backend))
        if phi.shape != grid.shape:
            raise ValueError(f"phi0 has shape {phi.shape}; the grid's is {grid.shape}")
        be = sim.stepper.backend
        self.backend = be
        self._phi = be.upload(np.ascontiguousarray(phi, dtype=sim.dtype))
        self._tmp = be.empty_like(self._phi)
        self._phi0 = be.empty_like(self._phi)
        self.steps_done = 0
        self.substeps = 0
        self.max_speed = 0.0
        self.time = 0.0

    # ------------------------------------------------------------------ pieces
    def beta(self) -> np.ndarray:
        """The speed field β of the model's current state (host array, the model's dtype)."""
        a = self.sim.stepper.state()[self.field].numpy().reshape(self.grid.shape)
        t = a.dtype.type
        if self.speed == "laplace":
            g = self.grid
            da = laplacian(a, dx=g.dx, dy=g.dy, bc=g.bc, backend=self.backend)
            return da * t(self.beta_scale)
        return (a - t(self.a0)) * t(self.beta_scale)

    def substeps_for(self, max_speed: float) -> int:
        """Front substeps of one model step ``dt`` at ``max|β| = max_speed`` (CFL).

        Parameters
        ----------
        max_speed : float
            ``max|β|`` (grid length per model time unit).

        Raises
        ------
        StabilityError
            ``dt`` breaks the CFL limit and ``substep`` is False.
        """
        limit = levelset_dt_limit(max_speed, self.grid.dx, self.grid.dy)
        dt = self.sim.dt
        if dt <= limit:
            return 1
        if not self.substep:
            raise StabilityError(
                f"the front's step dt={dt:g} exceeds the upwind CFL limit {limit:.6g} = "
                f"1/(max|β| (1/dx + 1/dy)) at max|β| = {max_speed:.6g}; allow substeps "
                "(substep=True), lower beta_scale or the model's dt"
            )
        n = math.ceil(dt / limit)
        return n if dt / n <= limit else n + 1  # n rounded down by one ulp

    def move(self, beta: np.ndarray) -> None:
        """Move the front by one model step ``dt`` with the speed field ``beta``.

        Parameters
        ----------
        beta : numpy.ndarray
            The normal speed β ``[ny, nx]`` (as `beta` returns it), > 0 moving outward.

        Raises
        ------
        FloatingPointError
            ``beta`` is not finite.
        StabilityError
            As in `substeps_for`.
        """
        be, g = self.backend, self.grid
        max_speed = float(np.max(np.abs(beta)))
        if not math.isfinite(max_speed):
            raise FloatingPointError(f"the speed field β of {self.field!r} is not finite (the "
                                     "model diverged?)")
        self.max_speed = max(self.max_speed, max_speed)
        n = self.substeps_for(max_speed)
        d_beta = be.upload(np.ascontiguousarray(beta))
        h = self.sim.dt / n
        for _ in range(n):
            be.levelset_step(self._phi, d_beta, self._tmp, dt=h, dx=g.dx, dy=g.dy,
                             bc=self._bcs)
            self._phi, self._tmp = self._tmp, self._phi
        self.substeps += n
        self.time += self.sim.dt

    def reinit(self) -> None:
        """Reinitialise φ to a signed distance (``reinit_iterations`` pseudo-time steps of
        ``1/(1/dx + 1/dy)``, width dx, subcell fix), on the device."""
        be, g = self.backend, self.grid
        be.copy(self._phi, self._phi0)
        dtau = 1.0 / (1.0 / g.dx + 1.0 / g.dy)
        for _ in range(self.reinit_iterations):
            be.reinit_step(self._phi, self._phi0, self._tmp, dtau=dtau, width=g.dx, dx=g.dx,
                           dy=g.dy, bc=self._bcs, subcell=True)
            self._phi, self._tmp = self._tmp, self._phi

    @property
    def phi(self) -> np.ndarray:
        """The current φ (downloaded)."""
        return self._phi.numpy()

    def step(self) -> None:
        """One driver step: the model one step, then the front the same time."""
        self.sim.stepper.advance(1)
        self.sim.step += 1
        self.move(self.beta())
        self.steps_done += 1
        if self.reinit_every and self.steps_done % self.reinit_every == 0:
            self.reinit()

    def run(self, steps: int, *, snapshot_every: int = 0) -> FrontResult:
        """``steps`` driver steps; φ is kept every ``snapshot_every`` steps (0: none).

        Parameters
        ----------
        steps : int
            Driver steps, >= 0.
        snapshot_every : int
            Steps between the snapshots of φ, >= 0 (default 0: none).
        """
        steps = check.steps(steps)
        every = check.steps(snapshot_every, "snapshot_every")
        if every:  # the snapshots of φ kept: the shared estimate, before the run
            check_fields(f"front_growth with {steps // every:,} snapshots",
                         math.prod(self.grid.shape), 1, np.dtype(self.sim.dtype).itemsize,
                         copies=2, snapshots=steps // every)
        snaps, at = [], []
        for _ in range(steps):
            self.step()
            if every and self.steps_done % every == 0:
                snaps.append(self.phi)
                at.append(self.steps_done)
        phi = self.phi
        return FrontResult(phi=phi, mask=phi < 0, snapshots=snaps, snapshot_steps=at,
                           fields=self.sim.state(), time=self.time, substeps=self.substeps,
                           max_speed=self.max_speed)


def front_growth(
    model: Model | str | None = None,
    domain: Domain | Mapping | None = None,
    params: dict | None = None,
    *,
    preset: Any = None,
    speed: str = "laplace",
    field: str | None = None,
    a0: float = 0.0,
    beta_scale: float = 1.0,
    reinit_every: int = 10,
    reinit_iterations: int = 8,
    steps: int = 1000,
    warmup: int = 0,
    dt: float | None = None,
    backend: Backend | str | None = None,
    dtype: Any = "float64",
    seed: int = 0,
    init: dict | None = None,
    phi0: np.ndarray | None = None,
    radius: float | None = None,
    snapshot_every: int = 0,
    substep: bool = True,
) -> FrontResult:
    """Run ``model`` on the 2-D grid ``domain`` (or a ``preset``) and move a front driven by
    one of its species (seed 003 §4.2).

    ``warmup`` model steps run first (the pattern forms), then ``steps`` driver steps of
    the model and the front together.

    Parameters
    ----------
    model : Model or str, optional
        The reaction-diffusion model (with ``domain``), or give ``preset``.
    domain : Grid or dict, optional
        A 2-D grid or a grid spec.
    params : dict, optional
        The model's parameters, as `rdgpu.Simulation` takes them.
    preset : str, optional
        A preset's name in place of ``model``/``domain`` (`rdgpu.Simulation.from_preset`).
    speed : {"laplace", "offset"}
        The front's normal speed: ``β = beta_scale·Δa`` (``"laplace"``) or
        ``β = beta_scale·(a − a0)`` (``"offset"``).
    field : str, optional
        The species ``a`` (default: the first).
    a0 : float
        The offset of ``"offset"``.
    beta_scale : float
        The factor of β.
    reinit_every, reinit_iterations : int
        φ is reinitialised every ``reinit_every`` steps (0: never) with
        ``reinit_iterations`` iterations.
    steps, warmup : int
        Driver steps with the front moving; model steps before it.
    dt : float, optional
        The model's step, also the front's (cut into substeps when the CFL limit asks).
    backend, dtype, seed, init
        As `rdgpu.Simulation` takes them.
    phi0 : array, optional
        The initial φ ``[ny, nx]``, negative inside (default: a centred circle of
        ``radius``).
    radius : float, optional
        The default circle's radius (default: a quarter of the shorter side).
    snapshot_every : int
        Keep φ every this many steps (0: none).
    substep : bool
        False raises `StabilityError` instead of cutting a step into substeps.

    Returns
    -------
    FrontResult
        The final φ and region, the snapshots and the model's final fields.

    Raises
    ------
    ValueError
        Both or neither of a model and a preset, no domain, or a bad argument.
    """
    check.steps(steps)
    warm = check.steps(warmup, "warmup")
    check.steps(snapshot_every, "snapshot_every")
    if preset is not None:
        if model is not None:
            raise ValueError("give a model or a preset, not both")
        sim = Simulation.from_preset(preset, domain=domain, params=params, dt=dt,
                                     backend=backend, dtype=dtype, seed=seed, init=init)
    else:
        if model is None or domain is None:
            raise ValueError("front_growth needs a model and a domain (or a preset)")
        sim = Simulation(model, domain, params, dt=dt, backend=backend, dtype=dtype,
                         seed=seed, init=init)
    front = RDFront(sim, field=field, speed=speed, a0=a0, beta_scale=beta_scale,
                    reinit_every=reinit_every, reinit_iterations=reinit_iterations,
                    phi0=phi0, radius=radius, substep=substep)
    sim.stepper.advance(warm)
    sim.step += warm
    return front.run(steps, snapshot_every=snapshot_every)


def turing_front(*, backend: Backend | str | None = None, steps: int | None = None,
                 warmup: int | None = None, **overrides: Any) -> FrontResult:
    """`front_growth` with `TURING_FRONT` (overridable by keyword): Turing's
    spots formed first, then a front from a small circle driven by their Laplacian, which
    fills the sea around the spots (seed 003 §4.2; ``seed003_front`` is an alias).

    Parameters
    ----------
    backend : str or Backend, optional
        As `rdgpu.get_backend` takes it (default ``None``: the default backend).
    steps, warmup : int, optional
        Replace `TURING_FRONT`'s ``steps`` (1000) and ``warmup`` (8000) where given.
    **overrides
        Any other `front_growth` keyword, over `TURING_FRONT`.
    """
    cfg = {**TURING_FRONT, **overrides}
    if steps is not None:
        cfg["steps"] = steps
    if warmup is not None:
        cfg["warmup"] = warmup
    return front_growth(backend=backend, **cfg)


#: seed 003's label for `turing_front` (an alias)
seed003_front = turing_front
