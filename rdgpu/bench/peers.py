"""The peers: the tools a user would pick instead of rdgpu, each doing exactly the
problem of `rdgpu.bench.problem` (Gray-Scott, 5-/7-point, periodic, forward Euler, dx = 1)
as a `Contender`.  Installed with ``pip install rdgpu[bench]``; a peer whose package is
missing is listed with the reason and not run.

* ``numba``: a hand-written ``@njit(parallel=True)`` kernel (rows shared among the cores
  with ``prange``), the reference's operation order, float32 or float64;
* ``py-pde``: ``pde.PDE`` with the same expressions on a periodic ``CartesianGrid``,
  ``EulerSolver`` (numba backend, fixed step); float64 only (py-pde computes in float64).

* ``pystencils``: the same assignments as symbolic field accesses, compiled to C with
  OpenMP; periodic through one ghost layer its data handling synchronises each step;
  float32 or float64.
* ``devito``: the same equations on ``TimeFunction`` s (``u.laplace``, space order 2, a
  grid of spacing 1), an OpenMP ``Operator``; Devito has no periodic boundaries, so the
  grid holds one ghost layer per side, the update runs on ``grid.interior`` and equations
  in the same operator copy the far cells into the new level's ghosts: one ``apply`` runs
  any number of steps; float32 or float64.
* ``taichi``: a hand-written ``@ti.kernel`` (one ``for`` over the field, which Taichi
  parallelises over the cores; periodic neighbours by selects, which Taichi runs faster
  than ``%``), its scalars in the field's dtype, the CPU backend with one thread per core;
  float32 or float64.
"""

from __future__ import annotations

import functools
import sys
import warnings
from importlib import metadata

import numpy as np

from rdgpu.bench.contenders import Contender
from rdgpu.bench.problem import PARAMS, Runner, dt_for

__all__ = ["PEERS", "peer_contenders", "peer_status"]

#: peer name -> the distribution providing it
PEERS = {"numba": "numba", "py-pde": "py-pde", "pystencils": "pystencils",
         "devito": "devito", "taichi": "taichi"}
_IMPLEMENTED = ("numba", "py-pde", "pystencils", "devito", "taichi")


def _version(dist: str) -> str | None:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return None


def peer_status(name: str) -> str | None:
    """None when peer ``name`` can run here, else why not."""
    if _version(PEERS[name]) is None:
        return f"not installed (pip install {PEERS[name]}, or rdgpu[bench])"
    if name not in _IMPLEMENTED:
        return "not implemented in rdgpu bench yet"
    return None


@functools.cache
def _numba_kernels():
    import numba

    @numba.njit(parallel=True)
    def step2(u, v, uo, vo, du, dv, f, fk, dt, one, two):  # pragma: no cover - compiled
        ny, nx = u.shape
        for i in numba.prange(ny):
            n, s = (i + 1) % ny, (i - 1 + ny) % ny
            for j in range(nx):
                e, w = (j + 1) % nx, (j - 1 + nx) % nx
                uc, vc = u[i, j], v[i, j]
                lu = (u[i, e] + u[i, w] - two * uc) + (u[n, j] + u[s, j] - two * uc)
                lv = (v[i, e] + v[i, w] - two * vc) + (v[n, j] + v[s, j] - two * vc)
                uvv = uc * vc * vc
                uo[i, j] = uc + dt * (du * lu - uvv + f * (one - uc))
                vo[i, j] = vc + dt * (dv * lv + uvv - fk * vc)

    @numba.njit(parallel=True)
    def step3(u, v, uo, vo, du, dv, f, fk, dt, one, two):  # pragma: no cover - compiled
        nz, ny, nx = u.shape
        for p in numba.prange(nz):
            a, b = (p + 1) % nz, (p - 1 + nz) % nz
            for i in range(ny):
                n, s = (i + 1) % ny, (i - 1 + ny) % ny
                for j in range(nx):
                    e, w = (j + 1) % nx, (j - 1 + nx) % nx
                    uc, vc = u[p, i, j], v[p, i, j]
                    lu = ((u[p, i, e] + u[p, i, w] - two * uc)
                          + (u[p, n, j] + u[p, s, j] - two * uc)
                          + (u[a, i, j] + u[b, i, j] - two * uc))
                    lv = ((v[p, i, e] + v[p, i, w] - two * vc)
                          + (v[p, n, j] + v[p, s, j] - two * vc)
                          + (v[a, i, j] + v[b, i, j] - two * vc))
                    uvv = uc * vc * vc
                    uo[p, i, j] = uc + dt * (du * lu - uvv + f * (one - uc))
                    vo[p, i, j] = vc + dt * (dv * lv + uvv - fk * vc)

    return step2, step3


def _numba_make(u: np.ndarray, v: np.ndarray) -> Runner:
    step = _numba_kernels()[u.ndim - 2]
    t = u.dtype.type
    p = PARAMS
    args = (t(p["Du"]), t(p["Dv"]), t(p["F"]), t(p["F"] + p["k"]), t(dt_for(u.ndim)), t(1),
            t(2))
    bufs = [u, v, np.empty_like(u), np.empty_like(v)]

    def advance(n):
        for _ in range(n):
            step(*bufs, *args)
            bufs[:] = [bufs[2], bufs[3], bufs[0], bufs[1]]

    return Runner(advance, lambda: (bufs[0].copy(), bufs[1].copy()))


def _pypde_make(u: np.ndarray, v: np.ndarray) -> Runner:
    import pde

    p = PARAMS
    grid = pde.CartesianGrid([[0, n] for n in u.shape], list(u.shape), periodic=True)
    eq = pde.PDE({"u": f"{p['Du']}*laplace(u) - u*v**2 + {p['F']}*(1 - u)",
                  "v": f"{p['Dv']}*laplace(v) + u*v**2 - ({p['F']} + {p['k']})*v"})
    state = pde.FieldCollection([pde.ScalarField(grid, u), pde.ScalarField(grid, v)])
    dt = dt_for(u.ndim)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        solver_class = getattr(pde, "EulerSolver", None) or pde.ExplicitSolver
        solver = solver_class(eq, backend="numba", adaptive=False)
        stepper = solver.make_stepper(state, dt=dt)
    t = [0.0]

    def advance(n):
        t[0] = stepper(state, t[0], t[0] + n * dt)

    return Runner(advance, lambda: (state[0].data.copy(), state[1].data.copy()))


def _laplacian(f, dims: int):
    """The 5-/7-point Laplacian (dx = 1) of pystencils field ``f``, axis by axis."""
    c, total = f.center, 0
    for axis in range(dims):
        ahead, behind = [0] * dims, [0] * dims
        ahead[axis], behind[axis] = 1, -1
        total = total + (f[tuple(ahead)] + f[tuple(behind)] - 2 * c)
    return total


def _pystencils_make(u0: np.ndarray, v0: np.ndarray) -> Runner:
    import pystencils as ps

    dims, dtype, p = u0.ndim, str(u0.dtype), PARAMS
    dh = ps.create_data_handling(u0.shape, periodicity=True, default_target=ps.Target.CPU)
    for name in ("u", "v", "u2", "v2"):
        dh.add_array(name, values_per_cell=1, dtype=dtype)
    u, v, u2, v2 = (dh.fields[n] for n in ("u", "v", "u2", "v2"))
    dt, uvv = dt_for(dims), u.center * v.center * v.center
    step = [ps.Assignment(u2.center, u.center + dt * (p["Du"] * _laplacian(u, dims) - uvv
                                                      + p["F"] * (1 - u.center))),
            ps.Assignment(v2.center, v.center + dt * (p["Dv"] * _laplacian(v, dims) + uvv
                                                      - (p["F"] + p["k"]) * v.center))]
    config = ps.CreateKernelConfig(target=ps.Target.CPU, default_dtype=dtype)
    config.cpu.openmp.enable = True
    kernel = ps.create_kernel(step, config).compile()
    inner = (slice(1, -1),) * dims
    dh.cpu_arrays["u"][inner], dh.cpu_arrays["v"][inner] = u0, v0
    sync = dh.synchronization_function(["u", "v"])

    def advance(n):
        for _ in range(n):
            sync()
            dh.run_kernel(kernel)
            dh.swap("u", "u2")
            dh.swap("v", "v2")

    return Runner(advance, lambda: (dh.cpu_arrays["u"][inner].copy(),
                                    dh.cpu_arrays["v"][inner].copy()))


def _default_fp_env() -> None:
    """Put this thread's floating-point environment back to the default (glibc's
    ``fesetenv(FE_DFL_ENV)``).  A library built with ``-ffast-math`` (GCC then links
    ``crtfastmath.o``) turns on flush-to-zero and denormals-are-zero in the thread that
    loads it: every later computation of the process would flush subnormals (NumPy's,
    hypothesis's...)."""
    if not sys.platform.startswith("linux"):
        return
    import ctypes
    import ctypes.util

    name = ctypes.util.find_library("m")
    if name:
        ctypes.CDLL(name).fesetenv(ctypes.c_void_p(-1))  # FE_DFL_ENV is (fenv_t *) -1


def _devito_make(u0: np.ndarray, v0: np.ndarray) -> Runner:
    import os

    os.environ.setdefault("DEVITO_LOGGING", "ERROR")
    import devito

    devito.configuration["language"] = "openmp"
    dims, p, dt = u0.ndim, PARAMS, dt_for(u0.ndim)
    # the cells plus one ghost layer per side, as points of the grid (spacing 1)
    shape = tuple(n + 2 for n in u0.shape)
    grid = devito.Grid(shape=shape, extent=tuple(float(n - 1) for n in shape),
                       dtype=u0.dtype.type)
    u, v = (devito.TimeFunction(name=n, grid=grid, space_order=2) for n in ("u", "v"))
    inner = (slice(1, -1),) * dims
    uvv = u * v * v
    eqs = [devito.Eq(u.forward, u + dt * (p["Du"] * u.laplace - uvv + p["F"] * (1 - u)),
                     subdomain=grid.interior),
           devito.Eq(v.forward, v + dt * (p["Dv"] * v.laplace + uvv - (p["F"] + p["k"]) * v),
                     subdomain=grid.interior)]
    space, level = grid.dimensions, grid.stepping_dim + 1
    for f in (u, v):  # periodic: each ghost plane of the new level copies the far cells
        f.data[0][inner] = u0 if f is u else v0
        for axis, n in enumerate(u0.shape):
            def at(i, axis=axis):
                return tuple(i if k == axis else d for k, d in enumerate(space))
            eqs += [devito.Eq(f[(level, *at(0))], f[(level, *at(n))]),
                    devito.Eq(f[(level, *at(n + 1))], f[(level, *at(1))])]
            first = f.data[0]
            first[tuple(0 if k == axis else slice(None) for k in range(dims))] = \
                first[tuple(n if k == axis else slice(None) for k in range(dims))]
            first[tuple(n + 1 if k == axis else slice(None) for k in range(dims))] = \
                first[tuple(1 if k == axis else slice(None) for k in range(dims))]
    op = devito.Operator(eqs)
    done = [0]

    def advance(n):
        op.apply(time_m=done[0], time_M=done[0] + n - 1)
        done[0] += n

    return Runner(advance, lambda: (u.data[done[0] % 2][inner].copy(),
                                    v.data[done[0] % 2][inner].copy()))


@functools.cache
def _taichi_kernels(dtype: str):
    import os

    import taichi as ti

    if not getattr(ti.lang.impl.get_runtime(), "prog", None):  # once per process
        ti.init(arch=ti.cpu, cpu_max_num_threads=os.cpu_count() or 1, offline_cache=False,
                log_level=ti.ERROR)
    real = ti.f32 if dtype == "float32" else ti.f64
    # Taichi reads the annotations as objects (this module's are strings: PEP 563)
    types = {**{k: ti.template() for k in ("u", "v", "uo", "vo")},
             **{k: real for k in ("du", "dv", "f", "fk", "dt")}}

    def kernel(fn):
        fn.__annotations__ = dict(types)
        return ti.kernel(fn)

    @kernel
    def step2(u, v, uo, vo, du, dv, f, fk, dt):  # pragma: no cover - compiled
        ny, nx = u.shape
        for i, j in u:
            n = i + 1 if i + 1 < ny else 0  # selects: faster than % in Taichi
            s = i - 1 if i > 0 else ny - 1
            e = j + 1 if j + 1 < nx else 0
            w = j - 1 if j > 0 else nx - 1
            uc, vc = u[i, j], v[i, j]
            lu = (u[i, e] + u[i, w] - 2 * uc) + (u[n, j] + u[s, j] - 2 * uc)
            lv = (v[i, e] + v[i, w] - 2 * vc) + (v[n, j] + v[s, j] - 2 * vc)
            uvv = uc * vc * vc
            uo[i, j] = uc + dt * (du * lu - uvv + f * (1 - uc))
            vo[i, j] = vc + dt * (dv * lv + uvv - fk * vc)

    @kernel
    def step3(u, v, uo, vo, du, dv, f, fk, dt):  # pragma: no cover - compiled
        nz, ny, nx = u.shape
        for q, i, j in u:
            a = q + 1 if q + 1 < nz else 0
            b = q - 1 if q > 0 else nz - 1
            n = i + 1 if i + 1 < ny else 0
            s = i - 1 if i > 0 else ny - 1
            e = j + 1 if j + 1 < nx else 0
            w = j - 1 if j > 0 else nx - 1
            uc, vc = u[q, i, j], v[q, i, j]
            lu = ((u[q, i, e] + u[q, i, w] - 2 * uc) + (u[q, n, j] + u[q, s, j] - 2 * uc)
                  + (u[a, i, j] + u[b, i, j] - 2 * uc))
            lv = ((v[q, i, e] + v[q, i, w] - 2 * vc) + (v[q, n, j] + v[q, s, j] - 2 * vc)
                  + (v[a, i, j] + v[b, i, j] - 2 * vc))
            uvv = uc * vc * vc
            uo[q, i, j] = uc + dt * (du * lu - uvv + f * (1 - uc))
            vo[q, i, j] = vc + dt * (dv * lv + uvv - fk * vc)

    return ti, real, step2, step3


def _taichi_make(u0: np.ndarray, v0: np.ndarray) -> Runner:
    ti, real, step2, step3 = _taichi_kernels(str(u0.dtype))
    step = step2 if u0.ndim == 2 else step3
    fields = [ti.field(real, shape=u0.shape) for _ in range(4)]
    fields[0].from_numpy(u0)
    fields[1].from_numpy(v0)
    p = PARAMS
    args = (p["Du"], p["Dv"], p["F"], p["F"] + p["k"], dt_for(u0.ndim))

    def advance(n):
        for _ in range(n):
            step(*fields, *args)
            fields[:] = [fields[2], fields[3], fields[0], fields[1]]
        ti.sync()

    return Runner(advance, lambda: (fields[0].to_numpy(), fields[1].to_numpy()))


def peer_contenders(names: list[str]) -> tuple[list[Contender], dict[str, str]]:
    """The runnable peers among ``names`` and ``{name: why not}`` for the others."""
    makers = {"numba": (_numba_make, lambda d, t: None),
              "pystencils": (_pystencils_make, lambda d, t: None),
              "devito": (_devito_make, lambda d, t: None),
              "taichi": (_taichi_make, lambda d, t: None),
              "py-pde": (_pypde_make,
                         lambda d, t: None if t == "float64" else "float64 only")}
    out, skipped = [], {}
    for name in names:
        why = peer_status(name)
        if why is not None:
            skipped[name] = why
            continue
        make, lacks = makers[name]
        out.append(Contender(name, "peer", _version(PEERS[name]), _fp_kept(make), lacks))
    return out, skipped


def _fp_kept(make):
    """``make`` and its runner's ``advance`` followed by `_default_fp_env`: Devito's and
    pystencils' ``-ffast-math`` libraries and Taichi's runtime turn on flush-to-zero in
    the calling thread (measured: a later ``1e-310 * 1.0`` gave 0)."""
    def kept(u, v):
        runner = make(u, v)
        _default_fp_env()

        def advance(n):
            runner.advance(n)
            _default_fp_env()

        return Runner(advance, runner.state)

    return kept
