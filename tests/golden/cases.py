"""The golden cases: every kernel family through the functional API, every built-in model
(its default method and every implicit method it offers) through ``Simulation``, a user
model, 1-D/2-D/3-D grids, a mesh, a graph surface, temporal blocking, ensembles, level-set
fronts driven by a model, DLA and random walkers, the noise family's normal numbers, on every
available backend in both dtypes.

Sizes are small and odd, grids non-square, so that every case runs in well under a second
once the backends' kernels are compiled (Warp and PoCL cache them on disk).  Inputs come
from ``numpy.random.default_rng`` seeded per case, so a case's result does not depend on
which other cases ran before it.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from functools import cache
from typing import Any

import numpy as np

import rdgpu

from .harness import Case

DTYPES = ("float32", "float64")
SHAPE2 = (13, 17)   # (ny, nx): odd, non-square
SHAPE1 = (23,)
SHAPE3 = (5, 7, 9)  # (nz, ny, nx)
STEPS = 5
IMPLICIT = ("imex", "imex-cn", "bdf2", "implicit", "crank-nicolson")
#: cases that only some backends offer (others refuse them with a clear error)
ONLY_ON = {"model gray-scott block_steps=3": ("opencl",)}  # the blocked kernel is OpenCL's


def _rng(seed: int) -> np.random.Generator:
    return np.random.default_rng(seed)


@cache
def _sphere() -> Any:
    return rdgpu.SurfaceMesh.icosphere(2)  # 162 vertices


def _height() -> np.ndarray:
    """A smooth periodic height over SHAPE2 (cell centres, dx = 1)."""
    ny, nx = SHAPE2
    y, x = np.meshgrid((np.arange(ny) + 0.5) / ny, (np.arange(nx) + 0.5) / nx, indexing="ij")
    return 0.8 * np.sin(2 * np.pi * x) * np.cos(2 * np.pi * y)


def _result(r: Any) -> dict[str, Any]:
    """What a ``Simulation`` run's :class:`Result` holds that a restructuring must keep."""
    return {"fields": dict(r.fields), "snapshots": dict(r.snapshots), "times": r.times,
            "snapshot_steps": r.snapshot_steps, "step": r.step, "time": r.time, "dt": r.dt,
            "diverged": r.diverged,
            "diverged_members": {str(k): v for k, v in r.diverged_members.items()}}


# ----------------------------------------------------------------- the functional API

def _laplacian(stencil: int, bc: Any, shape: tuple[int, ...] = SHAPE2,
               dx: float = 0.7, dy: float | None = 0.9) -> Callable:
    def run(be: str, dt: str) -> dict:
        u = _rng(1).standard_normal(shape).astype(dt)
        return {"lap": rdgpu.laplacian(u, dx=dx, dy=dy, bc=bc, stencil=stencil, backend=be)}
    return run


def _laplacian_mesh(be: str, dt: str) -> dict:
    u = _rng(2).standard_normal(_sphere().n_vertices).astype(dt)
    return {"lap": rdgpu.laplacian(u, mesh=_sphere(), backend=be)}


def _laplacian_height(be: str, dt: str) -> dict:
    u = _rng(3).standard_normal(SHAPE2).astype(dt)
    return {"lap": rdgpu.laplacian(u, height=_height(), backend=be)}


def _bernoulli(be: str, dt: str) -> dict:
    u = _rng(4).uniform(-1.5, 1.5, SHAPE2).astype(dt)
    return {"u": rdgpu.bernoulli_substep(u, tau=0.3, eps=0.8, backend=be)}


def _allen_cahn(method: str, mesh: bool = False) -> Callable:
    def run(be: str, dt: str) -> dict:
        if mesh:
            u = _rng(5).uniform(-1, 1, _sphere().n_vertices).astype(dt)
            out = rdgpu.allen_cahn(u, eps=0.3, dt=1e-4, b=0.05, steps=STEPS, method=method,
                                   mesh=_sphere(), backend=be)
        else:
            u = _rng(5).uniform(-1, 1, SHAPE2).astype(dt)
            b = _rng(6).uniform(-0.1, 0.1, SHAPE2).astype(dt)
            out = rdgpu.allen_cahn(u, eps=1.2, dt=0.1, b=b, steps=STEPS, method=method,
                                   dx=1.0, dy=1.1, bc="neumann", backend=be)
        return {"u": out}
    return run


def _gray_scott(bc: Any, mesh: bool = False) -> Callable:
    def run(be: str, dt: str) -> dict:
        if mesh:
            n = _sphere().n_vertices
            u, v = (_rng(7).uniform(0, 1, (2, n))).astype(dt)
            U, V = rdgpu.gray_scott(u, v, Du=2e-4, Dv=1e-4, F=0.035, k=0.06, dt=0.5,
                                    steps=STEPS, mesh=_sphere(), backend=be)
        else:
            u, v = (_rng(7).uniform(0, 1, (2, *SHAPE2))).astype(dt)
            F = _rng(8).uniform(0.02, 0.05, SHAPE2).astype(dt)
            U, V = rdgpu.gray_scott(u, v, Du=0.16, Dv=0.08, F=F, k=0.06, dt=1.0,
                                    steps=STEPS, bc=bc, backend=be)
        return {"u": U, "v": V}
    return run


def _spmv(be: str, dt: str) -> dict:
    import scipy.sparse as sp

    A = sp.random(19, 23, density=0.3, random_state=9, format="csr")
    x = _rng(10).standard_normal(23).astype(dt)
    return {"y": rdgpu.spmv(A, x, backend=be)}


def _diffusion(method: str, mesh: bool = False) -> Callable:
    def run(be: str, dt: str) -> dict:
        if mesh:
            u = _rng(11).standard_normal(_sphere().n_vertices).astype(dt)
            out = rdgpu.diffusion_step(u, D=0.5, dt=1e-3, steps=STEPS, method=method,
                                       mesh=_sphere(), backend=be)
        else:
            u = _rng(11).standard_normal(SHAPE2).astype(dt)
            src = _rng(12).standard_normal(SHAPE2).astype(dt)
            out = rdgpu.diffusion_step(u, D=0.5, dt=0.2, steps=STEPS, method=method,
                                       source=src, dx=1.0, dy=1.2,
                                       bc=("neumann", ("dirichlet", 0.25)), backend=be)
        return {"u": out}
    return run


def _fixed_mask() -> np.ndarray:
    fixed = np.zeros(SHAPE2, bool)
    fixed[6, 8] = True
    fixed[0, :] = True
    return fixed


def _sor_sweep(be: str, dt: str) -> dict:
    c = _rng(13).uniform(0, 1, SHAPE2).astype(dt)
    fixed = _fixed_mask()
    c[fixed] = 0.0
    c[0, :] = 1.0
    return {"c": rdgpu.sor_sweep(c, fixed, omega=1.5, dx=1.0, dy=1.0, backend=be)}


def _sor_solve(be: str, dt: str) -> dict:
    c = np.zeros(SHAPE2, dt)
    fixed = _fixed_mask()
    c[0, :] = 1.0
    rhs = _rng(14).uniform(-0.1, 0.1, SHAPE2).astype(dt)
    out, sweeps, residual = rdgpu.sor_solve(c, fixed, rhs=rhs, tol=1e-5, backend=be)
    return {"c": out, "sweeps": sweeps, "residual": residual}


def _phi(shape: tuple[int, ...], dt: str) -> np.ndarray:
    axes = np.meshgrid(*[np.arange(n) - (n - 1) / 2 for n in shape], indexing="ij")
    r = np.sqrt(sum((a * (1.0 + 0.1 * i)) ** 2 for i, a in enumerate(axes)))
    return (r - min(shape) / 3.0).astype(dt)


def _levelset(shape: tuple[int, ...]) -> Callable:
    def run(be: str, dt: str) -> dict:
        phi = _phi(shape, dt)
        speed = _rng(15).uniform(0.2, 1.0, shape).astype(dt)
        return {"phi": rdgpu.levelset_advance(phi, speed, dt=0.2, steps=STEPS, backend=be)}
    return run


def _reinit(shape: tuple[int, ...]) -> Callable:
    def run(be: str, dt: str) -> dict:
        phi = _phi(shape, dt) * 2.5
        return {"phi": rdgpu.reinitialize(phi, iterations=7, backend=be)}
    return run


FUNCTIONAL: dict[str, Callable] = {
    "laplacian 5-point periodic": _laplacian(5, "periodic"),
    "laplacian 5-point neumann/dirichlet": _laplacian(5, ("neumann", ("dirichlet", 0.5))),
    "laplacian 9-point periodic": _laplacian(9, "periodic", dx=1.0, dy=None),
    "laplacian 9-point neumann": _laplacian(9, "neumann", dx=0.8, dy=None),
    "laplacian 1-D": _laplacian(5, "neumann", SHAPE1, dx=0.7, dy=None),
    "laplacian mesh": _laplacian_mesh,
    "laplacian graph surface": _laplacian_height,
    "bernoulli_substep": _bernoulli,
    **{f"allen_cahn {m}": _allen_cahn(m) for m in ("explicit", "implicit", "crank-nicolson")},
    "allen_cahn mesh": _allen_cahn("explicit", mesh=True),
    "gray_scott periodic": _gray_scott("periodic"),
    "gray_scott neumann": _gray_scott("neumann"),
    "gray_scott mesh": _gray_scott("periodic", mesh=True),
    "spmv": _spmv,
    **{f"diffusion_step {m}": _diffusion(m)
       for m in ("explicit", "backward-euler", "crank-nicolson")},
    "diffusion_step mesh explicit": _diffusion("explicit", mesh=True),
    "diffusion_step mesh backward-euler": _diffusion("backward-euler", mesh=True),
    "sor_sweep": _sor_sweep,
    "sor_solve": _sor_solve,
    "levelset_advance 2-D": _levelset(SHAPE2),
    "levelset_advance 3-D": _levelset(SHAPE3),
    "reinitialize 2-D": _reinit(SHAPE2),
    "reinitialize 3-D": _reinit(SHAPE3),
}


# ----------------------------------------------------------------- Simulation

def _sim(model: Any, domain: Any, params: Mapping | None = None, steps: int = STEPS,
         **kw: Any) -> Callable:
    def run(be: str, dt: str) -> dict:
        from rdgpu.simulation.driver import Simulation

        d = domain() if callable(domain) else domain
        sim = Simulation(model, d, dict(params or {}), backend=be, dtype=dt, seed=3, **kw)
        return _result(sim.run(steps, snapshot_every=2, progress=False))
    return run


def _user_model() -> Any:
    return rdgpu.define_model(
        "golden-cross-diffusion",
        {"u": "Du*laplace(u) - 0.5*laplace(v) + u - u**3 - v*exp(-u**2)",
         "v": "Dv*laplace(v) + eps*(u - a*v)"},
        {"Du": 1.0, "Dv": 4.0, "eps": 0.1, "a": 0.5},
    )


def _simulation_cases() -> dict[str, Callable]:
    from rdgpu.domains.grid import Grid
    from rdgpu.models import MODELS

    grid = Grid(SHAPE2, dx=1.0, dy=1.1, bc="periodic")
    out: dict[str, Callable] = {}
    for name, model in MODELS.items():
        default = model.default_method
        out[f"model {name} {default}"] = _sim(name, grid)
        for m in model.methods:
            if m != default and m in IMPLICIT:
                out[f"model {name} {m}"] = _sim(name, grid, options={"method": m})
    for m in ("heun", "rk3"):
        out[f"model gray-scott {m}"] = _sim("gray-scott", grid, options={"method": m})
    out["model gray-scott 1-D"] = _sim("gray-scott", Grid(SHAPE1, bc="neumann"))
    out["model gray-scott 3-D"] = _sim("gray-scott", Grid(SHAPE3, bc="periodic"))
    out["model gray-scott 3-D imex"] = _sim("gray-scott", Grid(SHAPE3, bc="neumann"),
                                            options={"method": "imex"})
    out["model gray-scott dirichlet"] = _sim(
        "gray-scott", Grid(SHAPE2, bc=(("dirichlet", 1.0), "neumann")))
    out["model gray-scott block_steps=3"] = _sim("gray-scott", grid, steps=7,
                                                 options={"block_steps": 3})
    out["model gray-scott field parameter"] = _sim(
        "gray-scott", grid, {"F": "0.03 + 0.01*sin(2*pi*x/Lx)"})
    out["model gray-scott mesh"] = _sim("gray-scott", _sphere)
    out["model allen-cahn mesh"] = _sim("allen-cahn", _sphere)
    out["model allen-cahn mesh implicit"] = _sim("allen-cahn", _sphere,
                                                 options={"method": "implicit"})
    out["model gray-scott mesh imex"] = _sim("gray-scott", _sphere, options={"method": "imex"})
    out["model gray-scott graph surface"] = _sim(
        "gray-scott", lambda: rdgpu.GraphSurface(SHAPE2, height=_height()))
    out["model gray-scott ensemble"] = _sim(
        "gray-scott", grid, {"F": np.linspace(0.02, 0.05, 3)}, members=3)
    out["model gray-scott ensemble imex"] = _sim(
        "gray-scott", grid, {"F": np.linspace(0.02, 0.05, 3)}, members=3,
        options={"method": "imex"})
    out["model user (define_model)"] = _sim(
        _user_model(), grid, {"a": "0.5 + 0.1*sin(2*pi*x/Lx)"}, dt=0.05)
    out["model user (define_model) imex"] = _sim(
        _user_model(), grid, dt=0.05, options={"method": "imex"})
    return out


# ----------------------------------------------------------------- growth

def _dla(be: str, dt: str) -> dict:
    r = rdgpu.dla((21, 25), eta=1.0, steps=6, geometry="radial", seed=2, backend=be, dtype=dt)
    return {"mask": r.mask, "arrival": r.arrival, "c": r.c, "sweeps": r.sweeps,
            "stopped": r.stopped, "steps_done": r.steps_done, "center": r.center}


def _front(be: str, dt: str) -> dict:
    from rdgpu.domains.grid import Grid

    r = rdgpu.front_growth("gray-scott", Grid((21, 19), dx=0.5, bc="neumann"), dt=0.2,
                           speed="laplace", field="v", beta_scale=2.0, radius=3.0, steps=6,
                           reinit_every=3, snapshot_every=3, seed=1, backend=be, dtype=dt)
    return {"phi": r.phi, "mask": r.mask, "snapshots": r.snapshots,
            "snapshot_steps": r.snapshot_steps, "fields": r.fields, "time": r.time,
            "substeps": r.substeps, "max_speed": r.max_speed}


def _walkers(be: str, dt: str) -> dict:
    r = rdgpu.random_walk_dla((31, 27), particles=12, sticking=0.7, seed=4, backend=be,
                              walkers=8)
    return {"mask": r.mask, "arrival": r.arrival, "particles_added": r.particles_added,
            "walker_steps": r.walker_steps, "steps": r.steps, "stopped": r.stopped}


# ------------------------------------------------- kernel families without a functional API

def _normal_fill(be: str, dt: str) -> dict:
    """The noise family's normal numbers (rdgpu/families/noise) of a (7, 11) array."""
    backend = rdgpu.get_backend(be)
    out = backend.empty((7, 11), np.dtype(dt))
    backend.kernel("noise", "normal_fill")(out, seed=2**40 + 9, step=2**33 + 3, stream=1)
    return {"out": backend.download(out)}


# ----------------------------------------------------------------- all of them

def _backends() -> tuple[list[str], list[str]]:
    names, notes = [], []
    for info in rdgpu.available_backends():
        if info.available:
            names.append(info.name)
        else:
            notes.append(f"backend {info.name} skipped: {info.reason}")
    return names, notes


def all_cases(only: Iterable[str] | None = None) -> tuple[list[Case], list[str]]:
    """Every case on every available backend (notes name those left out); ``only``:
    keep the cases whose key contains one of these strings."""
    names, notes = _backends()
    per_dtype = {**FUNCTIONAL, **_simulation_cases(), "dla": _dla, "front_growth": _front,
                 "normal_fill": _normal_fill}
    cases = []
    for be in names:
        for name, run in per_dtype.items():
            if be not in ONLY_ON.get(name, (be,)):
                continue
            for dt in DTYPES:
                cases.append(Case(name, be, dt, run))
        cases.append(Case("random_walk_dla", be, "-", _walkers))
    if only:
        only = list(only)
        cases = [c for c in cases if any(s in c.key for s in only)]
    return cases, notes
