"""The functional API: arrays of any library in, the same kind out, any backend.

Every function checks its input, uploads it once, runs all its steps on the device and
downloads once.  Arrays of any kind are accepted (:mod:`rdgpu.interop`: NumPy, lists,
Warp, pyopencl, PyTorch, DLPack); one already in the backend's memory is used in place
(no copy), and the result comes back as the kind of the input (a list gives a NumPy
array).  ``out=`` takes an array of the result's shape and dtype (any writable kind)
that receives the result and is returned, so a loop can reuse it.

Inputs are never modified; results keep the input dtype (float32 or float64).  Grid
arrays are ``u[ny, nx]`` (row index is y); a 1-D array ``u[nx]`` is a 1-D problem:
``bc`` is its one condition, ``dy`` does not apply, and the stability limits are the 1-D
ones (the kernels run it as one row with no y axis, see :class:`rdgpu.domains.Grid`).
See docs/equations.md for every scheme.
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np

from rdgpu.backends import interop
from rdgpu.backends.base import Backend, DeviceArray
from rdgpu.backends.registry import get_backend
from rdgpu.core import validation as check
from rdgpu.core.errors import StabilityError
from rdgpu.domains.boundary import PERIODIC
from rdgpu.domains.grid import Grid
from rdgpu.ops.inputs import (  # the input checks (kind, size, then values) of every function here
    _given_shape,
    _grid_or_mesh,
    _grid_problem,
    _host_field,
    _levelset_problem,
    _mesh_field,
    _no_grid_args,
    _on,
    _param,
    _sor_inputs,
)

BackendSpec = str | Backend | None


def _finite(out: np.ndarray | DeviceArray, what: str, *, stepping: bool = False,
            check_stability: bool = True) -> np.ndarray | DeviceArray:
    """``out``, unless finite inputs produced NaN or Inf (an overflow of the dtype, or a run
    that diverged): that is an error, never a silent result (not checked when the caller
    turned the stability check off).  A DeviceArray (a result that stays on its device) is
    checked by one reduction there."""
    if not check_stability:
        return out
    if isinstance(out, DeviceArray):
        if math.isfinite(out.backend.max_abs(out)):
            return out
        bad = "NaN/Inf value(s)"
    elif np.isfinite(out).all():
        return out
    else:
        bad = f"{int(np.count_nonzero(~np.isfinite(out)))} NaN/Inf value(s)"
    cause = ("the run diverged (the reaction or the time step is too large for these "
             "values); reduce dt, or pass check_stability=False to get the raw result"
             if stepping else
             f"the values overflow {out.dtype} (largest {np.finfo(out.dtype).max:.3g}); "
             + ("use float64 or rescale the input" if out.dtype == np.float32
                else "rescale the input"))
    raise FloatingPointError(f"{what} produced {bad} from finite inputs: {cause}")


def _upload_optional(backend: Backend, x: float | np.ndarray) -> float | DeviceArray:
    return backend.upload(x) if isinstance(x, np.ndarray) else x


def _out_for(out: Any, given: Any, dtype: np.dtype, shape: Any = None) -> None:
    """Check ``out`` (if given) against the result: ``given``'s shape (or ``shape``)."""
    if out is not None:
        interop.check_out(out, _given_shape(given) if shape is None else shape,
                          dtype)


def _give(d: DeviceArray, given: Any, out: Any, what: str, shape: Any = None,
          **finite: Any) -> Any:
    """The result ``d`` (a buffer of the call's own) as the kind of ``given``, in
    ``given``'s shape (or ``shape``), or written into ``out``; checked by :func:`_finite`
    wherever the host sees it."""
    shape = _given_shape(given) if shape is None else tuple(shape)
    return interop.deliver(d, given, shape, out,
                           check=lambda host: _finite(host, what, **finite))


def _give_host(result: np.ndarray, given: Any, out: Any) -> Any:
    """A host result as the kind of ``given``, or written into ``out``."""
    if out is None:
        return interop.from_numpy(result, given)
    interop.fill(out, result)
    return out


def _target(be: Backend, out: Any, like: DeviceArray,
            reads: tuple[DeviceArray, ...] = ()) -> DeviceArray | None:
    """``out`` (checked) as a device array of ``like``'s shape a kernel can write directly:
    where it lives on ``be`` and is none of the arrays the call ``reads``; else None."""
    if out is None or not interop.resident(out, be):
        return None
    d = interop.wrap(out, be, like.shape)
    return None if any(interop.overlaps(d, r) for r in reads) else d


def _fresh(be: Backend, out: Any, like: DeviceArray) -> DeviceArray:
    """The result buffer of a one-kernel call: ``out`` itself where a kernel can write it
    (:func:`_target`), else a new array."""
    return _target(be, out, like, (like,)) or be.empty_like(like)


def _advance(be: Backend, start: tuple[DeviceArray, ...], n: int, step: Any,
             outs: tuple[Any, ...] | None = None) -> tuple[DeviceArray, ...]:
    """``n`` calls of ``step(cur, nxt)`` (tuples of device arrays) from ``start``, which is
    only read (it may be the caller's memory), ping-ponging between buffers of the call's
    own; the last step writes the caller's ``outs`` directly where a kernel can (see
    :func:`_target`).  The result is never ``start`` (a copy of it when ``n == 0``)."""
    final = None
    if outs is not None and n > 0:
        final = tuple(_target(be, o, d, start) for o, d in zip(outs, start, strict=True))
        final = None if None in final else final
    if n == 0:
        copies = tuple(be.empty_like(d) for d in start)
        for src, dst in zip(start, copies, strict=True):
            be.copy(src, dst)
        return copies
    own = n if final is None else n - 1  # the steps that write buffers of the call's own
    bufs = [tuple(be.empty_like(d) for d in start) for _ in range(min(own, 2))]
    cur = start
    for i in range(n):
        nxt = final if (final is not None and i == n - 1) else bufs[i % 2]
        step(cur, nxt)
        cur = nxt
    return cur


class _progress_bar:
    """A tqdm bar over ``total`` steps, refreshed at most ~200 times; a no-op when off."""

    def __init__(self, total: int, desc: str, enabled: bool):
        self.bar = None
        self.every = max(1, total // 200)
        if enabled:
            from tqdm.auto import tqdm

            self.bar = tqdm(total=total, desc=desc, unit="step", leave=True)

    def tick(self, done: int) -> None:
        if self.bar is not None and (done % self.every == 0 or done == self.bar.total):
            self.bar.update(done - self.bar.n)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.close()


# ---------------------------------------------------------------------------- stability
def _explicit_limit_formula(grid: Grid, d: str) -> str:
    """The forward-Euler diffusion limit of ``grid`` as text, for error messages."""
    if grid.ndim == 1:
        return f"dx²/(2 {d}) (1-D)"
    return f"1/(2 {d} (1/dx² + 1/dy²))"


def gray_scott_dt_limit(Du: float, Dv: float, dx: float, dy: float) -> float:
    """Forward-Euler limit of the 5-point diffusion: ``1 / (2 max(Du, Dv) (1/dx² + 1/dy²))``
    (``dy = inf`` for a 1-D grid: ``dx²/(2 max(Du, Dv))``)."""
    Du, Dv = check.scalar(Du, "Du"), check.scalar(Dv, "Dv")
    dx = check.scalar(dx, "dx", strict=True)
    dy = math.inf if dy == math.inf else check.scalar(dy, "dy", strict=True)
    d = max(Du, Dv)
    return math.inf if d == 0 else 1.0 / (2.0 * d * (1.0 / dx**2 + 1.0 / dy**2))


def levelset_dt_limit(max_speed: float, dx: float, dy: float, dz: float = math.inf) -> float:
    """Upwind CFL limit: ``Δt · max|F| · (1/dx + 1/dy (+ 1/dz)) ≤ 1`` (``dz`` for a 3-D
    grid; ``dy = inf`` for a 1-D one)."""
    max_speed = check.scalar(max_speed, "max_speed")
    dx = check.scalar(dx, "dx", strict=True)
    dy = math.inf if dy == math.inf else check.scalar(dy, "dy", strict=True)
    dz = math.inf if dz == math.inf else check.scalar(dz, "dz", strict=True)
    rate = 1.0 / dx + 1.0 / dy + 1.0 / dz
    return math.inf if max_speed == 0 else 1.0 / (max_speed * rate)


# ---------------------------------------------------------------------------- Laplacian
def laplacian(
    u: np.ndarray,
    *,
    dx: float = 1.0,
    dy: float | None = None,
    bc: Any = "periodic",
    stencil: int = 5,
    mesh: Any = None,
    height: Any = None,
    backend: BackendSpec = None,
    out: Any = None,
) -> Any:
    """Discrete Laplacian ``Δu`` with the 5-point or isotropic 9-point stencil (equations §1),
    on a triangle mesh (equations §6), or on the graph surface ``z = h(x, y)`` (``height``).

    ``bc`` is one condition or a pair ``(y_bc, x_bc)``: ``"periodic"``, ``"neumann"`` or
    ``("dirichlet", g)``.  The 9-point stencil needs ``dx == dy``.  Units: ``[u]/length²``.

    ``mesh``: a :class:`rdgpu.SurfaceMesh`; ``u`` is then one value per vertex (1-D, length
    ``n_vertices``) and the result is ``L u`` with the cotangent operator ``L = A⁻¹W``
    (``mesh.laplacian``; open boundaries are zero-flux).  ``dx``, ``dy``, ``bc`` and
    ``stencil`` do not apply to a mesh and must be left at their defaults.

    ``height``: ``h[ny, nx]`` at the cell centres (in the units of ``dx``); the result is
    then the Laplace-Beltrami operator ``Δ_Γ u = (1/√g) ∂_i(√g g^{ij} ∂_j u)`` of the
    surface ``z = h(x, y)`` over the parameter grid of ``u[ny, nx]`` (the conservative
    9-point form of :class:`rdgpu.domains.graph_surface.GraphSurface`; ``h = 0`` gives the 5-point
    Laplacian to round-off).  The surface is periodic: ``bc`` must be ``"periodic"`` on both
    axes; ``stencil`` does not apply and ``mesh`` cannot be given too.  ``u`` must be 2-D.

    ``out``: an array of u's shape and dtype that receives the result (module doc).
    """
    if height is not None:
        return _surface_laplacian(u, height, dx, dy, bc, stencil, mesh, backend, out)
    be = get_backend(backend)
    if mesh is not None:
        _no_grid_args(dx, dy, bc, stencil)
        field = _mesh_field(u, mesh, "u", be)
        _out_for(out, u, field.dtype)
        d_u = _on(be, u, field)
        res = _fresh(be, out, d_u)
        be.spmv(be.upload_csr(mesh.laplacian, field.dtype), d_u, res)
        return _give(res, u, out, "laplacian")
    if isinstance(stencil, bool) or stencil not in (5, 9):
        raise ValueError(f"stencil must be 5 or 9, got {stencil!r}")
    field, grid = _grid_problem(u, "u", dx, dy, bc, be)
    if grid.ndim == 1:
        stencil = 5  # both stencils are the 3-point (E + W − 2u)/dx² in 1-D
    elif stencil == 9 and grid.dx != grid.dy:
        raise ValueError(f"the 9-point stencil needs dx == dy, got dx={grid.dx}, dy={grid.dy}")
    _out_for(out, u, field.dtype)
    d_u = _on(be, u, field)
    res = _fresh(be, out, d_u)
    be.laplacian(d_u, res, dx=grid.dx, dy=grid.dy, bc=grid.bcs, stencil=stencil)
    return _give(res, u, out, "laplacian")


def _surface_laplacian(u: Any, height: Any, dx: Any, dy: Any, bc: Any, stencil: Any,
                       mesh: Any, backend: BackendSpec, out: Any) -> Any:
    """``rdgpu.laplacian(u, height=h, ...)``: ``Δ_Γ u`` on the periodic graph surface of h."""
    from rdgpu.domains.graph_surface import GraphSurface

    if mesh is not None:
        raise ValueError("height= and mesh= given together: height makes the graph surface "
                         "z = h(x, y) over the grid of u, a mesh is a surface of its own; "
                         "give one of them")
    if stencil != 5 or isinstance(stencil, bool):
        raise ValueError(f"stencil={stencil!r} given with height=: the surface operator has "
                         "its own 9-point form (rdgpu.GraphSurface); leave stencil at its default")
    shape_u = _given_shape(u)
    if len(shape_u) != 2:
        raise ValueError(f"with height= u must be a 2-D array [ny, nx] on the surface's "
                         f"parameter grid, got a {len(shape_u)}-D array of shape {shape_u}")
    be = get_backend(backend)
    field, grid = _grid_problem(u, "u", dx, dy, bc, be)
    if grid.bcs.x.kind != PERIODIC or grid.bcs.y.kind != PERIODIC:
        raise ValueError(f"a graph surface (height=) is periodic on both axes; got bc={bc!r}, "
                         "allowed: 'periodic'")
    h = check.real_array(interop.to_numpy(height) if interop.is_array(height) else height,
                         "height").astype(np.float64, copy=False)  # no text, bool, complex
    if h.shape != field.shape:
        raise ValueError(f"height has shape {h.shape}; it must have u's shape {field.shape} "
                         "(one height per cell)")
    if not np.isfinite(h).all():
        bad = int(np.count_nonzero(~np.isfinite(h)))
        raise ValueError(f"height contains {bad} NaN or Inf value(s); all values must be "
                         "finite")
    surface = GraphSurface(field.shape, dx=grid.dx, dy=grid.dy, height=h)
    _out_for(out, u, field.dtype)
    d_u = _on(be, u, field)
    res = _fresh(be, out, d_u)
    be.metric_laplacian(d_u, be.upload_metric(surface, field.dtype), res)
    return _give(res, u, out, "laplacian")


# ---------------------------------------------------------------------------- Bernoulli
def bernoulli_decay(tau: float, eps: float, dtype: Any) -> float:
    """``e^{−2τ/ε²}`` of the Bernoulli substep, never below ``dtype``'s smallest normal
    number: an exact 0 (``τ/ε²`` past ~745, or ε² underflowing) would make ``u = 0`` a
    0/0, and a subnormal would be flushed to 0 on the device.  For every ``|u|`` above
    ~1e-150 (float64) / ~1e-19 (float32) the result is the same as with the exact value."""
    decay = math.exp(-2.0 * ((tau / eps) / eps))
    return max(decay, float(np.finfo(np.dtype(dtype)).tiny))


def bernoulli_substep(
    u: Any, *, tau: float, eps: float, backend: BackendSpec = None, out: Any = None
) -> Any:
    """Exact solution of ``u_t = (u − u³)/ε²`` after a time ``tau`` (equations §2), pointwise.

    Works on arrays of any shape (grid cells or mesh vertices).  ``out``: module doc."""
    be = get_backend(backend)
    field = _host_field(u, "u", tuple(range(1, 8)), be)
    tau = check.scalar(tau, "tau")
    eps = check.scalar(eps, "eps", strict=True)
    decay = bernoulli_decay(tau, eps, field.dtype)
    _out_for(out, u, field.dtype)
    d_u = _on(be, u, field)
    res = _fresh(be, out, d_u)
    be.bernoulli(d_u, res, decay=decay)
    return _give(res, u, out, "bernoulli_substep")


# ---------------------------------------------------------------------------- Gray-Scott
def gray_scott(
    u: np.ndarray,
    v: np.ndarray,
    *,
    Du: float,
    Dv: float,
    F: float | np.ndarray,
    k: float | np.ndarray,
    dt: float,
    steps: int = 1,
    dx: float = 1.0,
    dy: float | None = None,
    bc: Any = "periodic",
    mesh: Any = None,
    check_stability: bool = True,
    progress: bool = False,
    backend: BackendSpec = None,
    out: tuple[Any, Any] | None = None,
) -> tuple[Any, Any]:
    """Advance Gray-Scott ``steps`` forward-Euler steps of ``dt`` (equations §3).

    ``u_t = Du Δu − u v² + F (1 − u)``, ``v_t = Dv Δv + u v² − (F + k) v``.  ``F`` and ``k``
    are scalars or per-cell arrays.  Raises :class:`StabilityError` when
    ``dt > 1 / (2 max(Du, Dv)(1/dx² + 1/dy²))`` unless ``check_stability=False``.
    ``progress=True`` shows a progress bar (tqdm) on stderr.

    ``mesh``: a :class:`rdgpu.SurfaceMesh` in place of ``dx``/``dy``/``bc``: ``u``, ``v``
    (and field ``F``, ``k``) hold one value per vertex and ``Δ`` is the cotangent operator
    (equations §6), one fused kernel per step; the limit is then
    ``mesh.max_stable_dt(max(Du, Dv)) = 2/(max(Du, Dv) λ_max(−L))``.

    ``out``: a pair ``(u_out, v_out)`` that receives the result (module doc).
    """
    be = get_backend(backend)
    check_stability, progress = (check.flag(check_stability, "check_stability"),
                                 check.flag(progress, "progress"))
    if mesh is not None:
        _no_grid_args(dx, dy, bc)
        gu, gv = _mesh_field(u, mesh, "u", be), _mesh_field(v, mesh, "v", be)
    else:
        gu, grid = _grid_problem(u, "u", dx, dy, bc, be)
        gv, _ = _grid_problem(v, "v", dx, dy, bc, be)
        shape_u, shape_v = _given_shape(u), _given_shape(v)
        if shape_u != shape_v:  # as given: a 1-D u and a 1-row v differ
            raise ValueError(f"v has shape {shape_v} but u has shape {shape_u}; they must "
                             "match")
    check.same_dtype(gu, gv, "u", "v")
    if out is not None:
        if not isinstance(out, (tuple, list)) or len(out) != 2:
            raise TypeError(f"out must be a pair (u_out, v_out) of arrays, got "
                            f"{type(out).__name__}")
        _out_for(out[0], u, gu.dtype)
        _out_for(out[1], v, gv.dtype)
        if out[0] is out[1]:
            raise ValueError("out holds one array twice; u_out and v_out must be two arrays")
    outs = (None, None) if out is None else tuple(out)
    Du, Dv = check.scalar(Du, "Du"), check.scalar(Dv, "Dv")
    dt = check.scalar(dt, "dt")
    n = check.steps(steps)
    F_ = _param(F, "F", gu)
    k_ = _param(k, "k", gu)
    if mesh is not None:
        d = max(Du, Dv)
        limit = mesh.max_stable_dt(d) if d > 0 else math.inf
        if check_stability and dt > limit:
            raise StabilityError(
                f"dt={dt} exceeds the forward-Euler diffusion limit {limit:.6g} = "
                "mesh.max_stable_dt(max(Du, Dv)) = 2/(max(Du, Dv) λ_max(−L)); reduce dt or "
                "pass check_stability=False"
            )
        L = be.upload_csr(mesh.laplacian, gu.dtype)

        def kernel(cur, nxt):
            be.mesh_gray_scott(L, *cur, *nxt, Du=Du, Dv=Dv, F=d_F, k=d_k, dt=dt)
    else:
        limit = gray_scott_dt_limit(Du, Dv, grid.dx, grid.dy)
        if check_stability and dt > limit:
            raise StabilityError(
                f"dt={dt} exceeds the forward-Euler diffusion limit {limit:.6g} = "
                f"{_explicit_limit_formula(grid, 'max(Du, Dv)')}; reduce dt or pass "
                "check_stability=False"
            )

        def kernel(cur, nxt):
            be.gray_scott(*cur, *nxt, Du=Du, Dv=Dv, F=d_F, k=d_k, dt=dt, dx=grid.dx,
                          dy=grid.dy, bc=grid.bcs)
    d_F, d_k = _upload_optional(be, F_), _upload_optional(be, k_)
    start = (_on(be, u, gu), _on(be, v, gv))
    with _progress_bar(n, "gray-scott", progress) as bar:
        done = [0]

        def step(cur, nxt):
            kernel(cur, nxt)
            done[0] += 1
            bar.tick(done[0])
        res_u, res_v = _advance(be, start, n, step, outs)
    gs = {"stepping": True, "check_stability": check_stability}
    return (_give(res_u, u, outs[0], "gray_scott", **gs),
            _give(res_v, v, outs[1], "gray_scott", **gs))


# ---------------------------------------------------------------------------- SpMV
def spmv(csr: Any, x: Any, backend: BackendSpec = None, *, out: Any = None) -> Any:
    """``y = A x`` on a backend for any ``scipy.sparse`` matrix or array ``A`` (any format,
    square or not): a drop-in for ``A @ x`` with a 1-D ``x``.

    The result has ``x``'s dtype (float32 or float64); ``A`` is cast to it.  Each row is
    summed in index order in that dtype.  ``A`` is uploaded on every call: to apply one
    operator many times, upload it once with ``backend.upload_csr`` and call
    ``backend.spmv``.  Neither input is modified.  ``x``: any array kind; ``out``: an
    array of shape ``(n_rows,)`` and x's dtype that receives ``y`` (module doc)."""
    from rdgpu.core.csr import checked_csr

    m = checked_csr(csr, "csr")  # type, real finite values, structure (indices in range)
    n_rows, n_cols = m.shape
    xa = np.asarray(x) if isinstance(x, (list, tuple)) else x
    try:
        shape_x, dtype_x = interop.shape_dtype(xa)
    except (TypeError, AttributeError):
        raise TypeError(f"x must be a NumPy array (or any array kind: rdgpu.interop), got "
                        f"{type(x).__name__}") from None
    if len(shape_x) != 1 or shape_x[0] != n_cols:
        raise ValueError(
            f"x has shape {shape_x}; the matrix of shape {m.shape} needs a 1-D x of length "
            f"{n_cols}"
        )
    if n_cols == 0 or n_rows == 0:
        if dtype_x not in check.DTYPES:
            raise TypeError(f"x has unsupported dtype {dtype_x}; allowed: float32, float64")
        return _give_host(np.zeros(n_rows, dtype=dtype_x), xa, out)
    be = get_backend(backend)
    field = _host_field(xa, "x", (1,), be)
    _out_for(out, xa, field.dtype, (n_rows,))
    A = be.upload_csr(m, field.dtype, name="csr")  # refuses values the dtype cannot hold
    y = be.empty((n_rows,), field.dtype)
    be.spmv(A, _on(be, xa, field), y)
    return _give(y, xa, out, "spmv", shape=(n_rows,))


# ---------------------------------------------------------------------------- diffusion
DIFFUSION_METHODS = ("explicit", "backward-euler", "crank-nicolson")


def diffusion_step(
    u: np.ndarray,
    *,
    D: float,
    dt: float,
    steps: int = 1,
    method: str = "explicit",
    source: float | np.ndarray = 0.0,
    mesh: Any = None,
    dx: float = 1.0,
    dy: float | None = None,
    bc: Any = "periodic",
    tol: float | None = None,
    check_stability: bool = True,
    backend: BackendSpec = None,
    out: Any = None,
) -> Any:
    """Advance ``u_t = D Δu + source`` by ``steps`` steps of ``dt`` on a grid or a mesh.

    ``method``: ``"explicit"`` (forward Euler ``u + dt (D Δu + source)``; raises
    :class:`StabilityError` above ``1/(2D(1/dx² + 1/dy²))`` on a grid,
    ``mesh.max_stable_dt(D)`` on a mesh, unless ``check_stability=False``),
    ``"backward-euler"`` (alias ``"implicit"``) or ``"crank-nicolson"``: the θ-scheme
    ``(I − θ dt D L) u' = u + (1 − θ) dt D L u + dt source``, solved by multicolour SOR on
    the device to ``tol`` (default 1e-8 in float64, 1e-5 in float32; see
    :class:`rdgpu.ops.implicit.ImplicitDiffusion`), stable at any ``dt``.

    ``source`` is a number or a field of u's shape.  Grid: ``dx``, ``dy``, ``bc`` as in
    :func:`laplacian` (5-point stencil, Dirichlet ghosts included).  ``mesh``: a
    :class:`rdgpu.SurfaceMesh`; ``u`` has one value per vertex; the grid arguments must stay
    at their defaults.  On a closed mesh (or a periodic/Neumann grid) every method keeps
    ``Σ A_i u_i`` (``Σ u``) up to ``dt Σ A_i source_i`` per step.  ``out``: module doc."""
    from rdgpu.ops.implicit import ImplicitDiffusion, operator_matrix

    method = "backward-euler" if method == "implicit" else method
    if method not in DIFFUSION_METHODS:
        raise ValueError(f"method must be one of {DIFFUSION_METHODS} (or 'implicit'), got "
                         f"{method!r}")
    be = get_backend(backend)
    field, domain = _grid_or_mesh(u, mesh, dx, dy, bc, be=be)
    D = check.scalar(D, "D")
    dt = check.scalar(dt, "dt", strict=True)
    n = check.steps(steps)
    check_stability = check.flag(check_stability, "check_stability")
    if tol is not None and method == "explicit":
        raise ValueError(f"tol={tol!r} given with method='explicit', which solves nothing; "
                         "tol applies to 'backward-euler' and 'crank-nicolson'")
    tol = None if tol is None else check.scalar(tol, "tol", strict=True)
    src = _param(source, "source", field)
    _out_for(out, u, field.dtype)
    start = (_on(be, u, field),)
    if method == "explicit":
        if mesh is not None:
            limit = mesh.max_stable_dt(D) if D > 0 else math.inf
            what = "mesh.max_stable_dt(D) = 2/(D λ_max(−L))"
        else:
            limit = gray_scott_dt_limit(D, D, domain.dx, domain.dy)
            what = _explicit_limit_formula(domain, "D")
        if check_stability and dt > limit:
            raise StabilityError(
                f"dt={dt} exceeds the forward-Euler diffusion limit {limit:.6g} = {what}; "
                "reduce dt, use method='backward-euler' or 'crank-nicolson', or pass "
                "check_stability=False"
            )
        M, b = operator_matrix(domain)
        if D != 0.0 and np.any(b != 0.0):  # Dirichlet ghosts: L u = M u + b
            src = np.ascontiguousarray((np.asarray(src, dtype=np.float64)
                                        + D * b.reshape(field.shape)).astype(field.dtype))
        L = be.upload_csr(M, field.dtype)
        d_src = _upload_optional(be, src)

        def step(cur, nxt):
            be.mesh_diffusion(L, cur[0], nxt[0], D=D, dt=dt, source=d_src)
    else:
        theta = 1.0 if method == "backward-euler" else 0.5
        solver = ImplicitDiffusion(domain, D=D, dt=dt, theta=theta, backend=be,
                                   dtype=field.dtype, tol=tol)
        d_src = _upload_optional(be, src)

        def step(cur, nxt):
            solver.step(cur[0], nxt[0], source=d_src)
    (res,) = _advance(be, start, n, step, (out,))
    return _give(res, u, out, "diffusion_step", stepping=True,
                 check_stability=check_stability)


def allen_cahn(
    u: np.ndarray,
    *,
    eps: float,
    dt: float,
    b: float | np.ndarray = 0.0,
    steps: int = 1,
    method: str = "explicit",
    mesh: Any = None,
    dx: float = 1.0,
    dy: float | None = None,
    bc: Any = "periodic",
    check_stability: bool = True,
    backend: BackendSpec = None,
    out: Any = None,
) -> Any:
    """Advance the modified Allen-Cahn equation ``u_t = Δu − (u³ − u + b)/ε²`` (Dascal et al.,
    equations §2) by ``steps`` Strang-split steps: Bernoulli ``dt/2`` → diffusion with the
    source ``−b/ε²`` for ``dt`` → Bernoulli ``dt/2`` (the stepper of
    :class:`rdgpu.models.AllenCahn`).

    ``method``: ``"explicit"`` (limit ``1/(2(1/dx² + 1/dy²))`` on a grid,
    ``mesh.max_stable_dt(1)`` on a mesh; :class:`StabilityError` above it unless
    ``check_stability=False``), ``"implicit"`` (backward Euler) or ``"crank-nicolson"``
    (multicolour SOR on the device; any ``dt``).  ``b`` is a number or a field of u's
    shape.  ``mesh``: a :class:`rdgpu.SurfaceMesh` in place of ``dx``/``dy``/``bc``.
    ``out``: module doc (the state crosses the host once each way: the stepper's own)."""
    from rdgpu.models import AllenCahn

    field, domain = _grid_or_mesh(u, mesh, dx, dy, bc, be=get_backend(backend))
    eps = check.scalar(eps, "eps", strict=True)
    check_stability = check.flag(check_stability, "check_stability")
    if not 1.0 / (eps * eps) < float(np.finfo(field.dtype).max) if eps * eps > 0 else True:
        raise ValueError(
            f"eps={eps:g} is too small for {field.dtype}: the reaction term (u³ − u + b)/eps² "
            f"overflows; allowed: eps > {1 / math.sqrt(float(np.finfo(field.dtype).max)):.3g}"
        )
    dt = check.scalar(dt, "dt", strict=True)
    n = check.steps(steps)
    b_ = _param(b, "b", field)
    _out_for(out, u, field.dtype)
    if method not in AllenCahn.methods:
        raise ValueError(f"method must be one of {AllenCahn.methods}, got {method!r}")
    stepper = AllenCahn().stepper(
        domain, {"eps": eps, "b": b_}, dt=dt, backend=get_backend(backend), dtype=field.dtype,
        check_stability=check_stability, method=method,
    )
    stepper.set_state({"u": field})
    stepper.advance(n)
    res = _finite(stepper.get_state()["u"], "allen_cahn", stepping=True,
                  check_stability=check_stability)
    return _give_host(res.reshape(_given_shape(u)), u, out)


# ---------------------------------------------------------------------------- SOR
def optimal_omega(shape: tuple[int, ...]) -> float:
    """``2 / (1 + sin(π/N))`` with ``N`` the larger side: the optimal ω of the model problem."""
    if isinstance(shape, (int, np.integer)) and not isinstance(shape, bool):
        shape = (shape,)
    try:
        sizes = [int(n) for n in shape if not isinstance(n, bool) and int(n) == n]
    except (TypeError, ValueError):
        sizes = []
    if not sizes or len(sizes) != len(tuple(shape)) or min(sizes) < 1:
        raise ValueError(f"shape must be a non-empty tuple of positive integers (a grid's "
                         f"shape), got {shape!r}")
    n = max(max(sizes), 2)
    return 2.0 / (1.0 + math.sin(math.pi / n))


class _SOR:
    """Device state of one SOR problem."""

    def __init__(self, be: Backend, given, grid, mask, f):
        self.be = be
        self.c = be.empty(grid.shape, grid.dtype)  # updated in place: never the caller's
        be.copy(_on(be, given, grid), self.c)
        self.fixed = be.upload(mask)
        self.rhs = None if f is None else be.upload(f)
        self.change = be.empty((grid.shape[0],), grid.dtype)

    def sweep(self, omega, dx, dy, bcs) -> None:
        for color in (0, 1):
            self.be.sor_half_sweep(
                self.c, self.fixed, self.rhs, self.change,
                color=color, omega=omega, dx=dx, dy=dy, bc=bcs,
            )

    def max_change(self) -> float:
        return float(self.change.numpy().max())


def sor_sweep(
    c: np.ndarray,
    fixed: np.ndarray,
    *,
    omega: float,
    rhs: np.ndarray | None = None,
    dx: float = 1.0,
    dy: float | None = None,
    bc: Any = "neumann",
    backend: BackendSpec = None,
    out: Any = None,
) -> Any:
    """One red-black SOR sweep for ``Δc = rhs`` (red ``(i + j)`` even, then black; equations §4).

    ``fixed`` is a boolean mask of Dirichlet cells that keep their value.  ``out``: module
    doc."""
    be = get_backend(backend)
    grid, mask, omega, f, dx, dy, bcs = _sor_inputs(c, fixed, omega, rhs, dx, dy, bc, be)
    _out_for(out, c, grid.dtype)
    state = _SOR(be, c, grid, mask, f)
    state.sweep(omega, dx, dy, bcs)
    return interop.deliver(state.c, c, _given_shape(c), out)


def sor_solve(
    c: np.ndarray,
    fixed: np.ndarray,
    *,
    omega: float | None = None,
    rhs: np.ndarray | None = None,
    tol: float = 1e-6,
    max_sweeps: int | None = None,
    dx: float = 1.0,
    dy: float | None = None,
    bc: Any = "neumann",
    backend: BackendSpec = None,
    out: Any = None,
) -> tuple[Any, int, float]:
    """Solve ``Δc = rhs`` by red-black SOR from the initial guess ``c`` (equations §4).

    Stops after the first sweep whose max change is below ``tol``; returns
    ``(c, sweeps, residual)`` where ``residual`` is that last max change.  ``omega``
    defaults to :func:`optimal_omega`; ``max_sweeps`` to ``max(1000, 50 N)``.

    Round-off floor: the changes cannot fall below a few ``eps·max|c|`` (in float32 at
    256² they wander around ``13 eps``).  When they stop falling there -- no halving of
    the max change over ``3/(1 − ρ)`` sweeps, ``ρ`` Young's contraction at this ``omega``
    for the Jacobi radius ``cos(π/N)``, while it is ``<= 64 eps max|c|`` -- the solve
    stops with a ``RuntimeWarning`` that names the floor reached (``tol`` is below what the
    dtype resolves; the result is as accurate as it can be).  If ``max_sweeps`` ends the
    solve otherwise, :class:`rdgpu.core.errors.ConvergenceError` is raised.  ``out``: an array
    that receives ``c`` (module doc)."""
    from rdgpu.core.errors import ConvergenceError

    be = get_backend(backend)
    grid, mask, omega_, f, dx, dy, bcs = _sor_inputs(c, fixed, 1.0 if omega is None else omega,
                                                     rhs, dx, dy, bc, be)
    _out_for(out, c, grid.dtype)
    omega = optimal_omega(grid.shape) if omega is None else omega_
    tol = check.scalar(tol, "tol", strict=True)
    if max_sweeps is None:
        max_sweeps = max(1000, 50 * max(grid.shape))
    max_sweeps = check.steps(max_sweeps, "max_sweeps")
    state = _SOR(be, c, grid, mask, f)
    eps = float(np.finfo(grid.dtype).eps)
    # Young: the model problem's Jacobi radius cos(π/N) and the contraction at this omega
    rho_j = math.cos(math.pi / max(max(grid.shape), 2))
    if omega >= optimal_omega(grid.shape):
        rate = omega - 1.0
    else:
        disc = max(0.0, (omega * rho_j) ** 2 - 4.0 * (omega - 1.0))
        rate = ((omega * rho_j + math.sqrt(disc)) / 2.0) ** 2
    window = max(8, math.ceil(3.0 / max(1.0 - rate, 1e-12)))
    sweeps, residual = 0, math.inf
    anchor, anchor_at, looked_at, low = math.inf, 0, -window, math.inf
    floor = None
    while sweeps < max_sweeps:
        state.sweep(omega, dx, dy, bcs)
        sweeps += 1
        residual = state.max_change()
        if residual < tol:
            break
        if not math.isfinite(residual):
            raise FloatingPointError(f"sor_solve: the max change is {residual} after "
                                     f"{sweeps} sweeps (non-finite input or overflow)")
        low = min(low, residual)
        if residual <= 0.5 * anchor:
            anchor, anchor_at = residual, sweeps
        elif sweeps - anchor_at >= window and sweeps - looked_at >= window:
            looked_at = sweeps  # stalled: at the round-off floor?
            scale = float(np.max(np.abs(state.c.numpy())))
            if low <= 64.0 * eps * scale:
                floor = (low, scale)
                break
    else:
        if max_sweeps > 0:
            raise ConvergenceError(
                f"sor_solve did not converge: max change {residual:.3g} >= tol={tol:.3g} "
                f"after max_sweeps={max_sweeps} sweeps (omega={omega:.4f}); raise "
                "max_sweeps, raise tol, or check omega (default: optimal_omega)",
                sweeps=sweeps, reached=residual, tol=tol,
            )
    if floor is not None:
        low, scale = floor
        wider = ", or float64" if grid.dtype == np.float32 else ""
        warnings.warn(
            f"sor_solve: tol={tol:.3g} is below the {grid.dtype} round-off floor of this "
            f"problem: the max change stalled at {low:.3g} (= {low / (eps * scale):.0f} "
            f"eps·max|c|) after {sweeps} sweeps; the result is as accurate as {grid.dtype} "
            f"allows (use tol >= {2 * low:.2g}{wider})",
            RuntimeWarning,
            stacklevel=2,
        )
    return interop.deliver(state.c, c, _given_shape(c), out), sweeps, residual


# ---------------------------------------------------------------------------- level sets
def _grid_formula(domain: Grid) -> tuple[str, float]:
    """``(text, value)`` of ``1/(1/dx + 1/dy (+ 1/dz))`` for ``domain``."""
    if domain.ndim == 1:
        return "dx (1-D)", domain.dx
    if domain.ndim == 3:
        return ("1/(1/dx + 1/dy + 1/dz)",
                1.0 / (1.0 / domain.dx + 1.0 / domain.dy + 1.0 / domain.dz))
    return "1/(1/dx + 1/dy)", 1.0 / (1.0 / domain.dx + 1.0 / domain.dy)


def levelset_advance(
    phi: np.ndarray,
    speed: float | np.ndarray,
    *,
    dt: float,
    steps: int = 1,
    dx: float = 1.0,
    dy: float | None = None,
    dz: float | None = None,
    bc: Any = "neumann",
    check_stability: bool = True,
    backend: BackendSpec = None,
    out: Any = None,
) -> Any:
    """Advance ``φ_t + F|∇φ| = 0`` by first-order upwinding (equations §5).

    ``φ < 0`` is inside; ``F > 0`` moves the front outward.  ``speed`` is a scalar or a
    per-cell field.  ``phi`` is ``[nx]``, ``[ny, nx]`` or ``[nz, ny, nx]`` (3-D, seed 003
    eq. 3.11: plane spacing ``dz``, default ``dx``; ``bc`` one condition or a triple
    ``(z_bc, y_bc, x_bc)``).  Raises :class:`StabilityError` if
    ``dt · max|F| · (1/dx + 1/dy (+ 1/dz)) > 1``.  ``out``: module doc."""
    be = get_backend(backend)
    grid, domain = _levelset_problem(phi, dx, dy, dz, bc, be)
    F = _param(speed, "speed", grid)
    dt = check.scalar(dt, "dt")
    n = check.steps(steps)
    check_stability = check.flag(check_stability, "check_stability")
    dx, dy, bcs = domain.dx, domain.dy, domain.bcs
    limit = levelset_dt_limit(float(np.max(np.abs(F))), dx, dy, domain.dz)
    if check_stability and dt > limit:
        formula = {1: "dx/max|F| (1-D)", 2: "1/(max|F| (1/dx + 1/dy))",
                   3: "1/(max|F| (1/dx + 1/dy + 1/dz))"}[domain.ndim]
        raise StabilityError(
            f"dt={dt} exceeds the upwind CFL limit {limit:.6g} = {formula}; "
            "reduce dt or pass check_stability=False"
        )
    kw = {"dz": domain.dz} if domain.ndim == 3 else {}
    _out_for(out, phi, grid.dtype)
    d_F = _upload_optional(be, F)

    def step(cur, nxt):
        be.levelset_step(cur[0], d_F, nxt[0], dt=dt, dx=dx, dy=dy, bc=bcs, **kw)
    (res,) = _advance(be, (_on(be, phi, grid),), n, step, (out,))
    return _give(res, phi, out, "levelset_advance", stepping=True,
                 check_stability=check_stability)


def reinitialize(
    phi: np.ndarray,
    *,
    dx: float = 1.0,
    dy: float | None = None,
    dz: float | None = None,
    iterations: int | None = None,
    dtau: float | None = None,
    bc: Any = "neumann",
    subcell_fix: bool = True,
    backend: BackendSpec = None,
    out: Any = None,
) -> Any:
    """Make ``φ`` a signed distance function without moving its zero level set (equations §5).

    Iterates ``φ_τ + S(φ₀)(|∇φ| − 1) = 0`` with ``S = φ₀/sqrt(φ₀² + dx²)`` and pseudo-time
    step ``dtau`` (default and maximum ``1/(1/dx + 1/dy)``, i.e. ``dx/2`` on a square
    grid; ``1/(1/dx + 1/dy + 1/dz)`` on a 3-D ``[nz, ny, nx]`` grid, ``dx/3`` on a cubic
    one).  Distance information travels about half (3-D: a third of) a cell per
    iteration: the default ``iterations = max(shape)`` makes ``φ`` a distance out to about
    ``N/2`` (``N/3``) cells.  ``subcell_fix`` (Russo & Smereka 2000) anchors the cells next
    to the front to φ₀'s own distance estimate, so the front does not drift however many
    iterations run; without it the plain Godunov scheme moves the front by a fraction of
    a cell per ~100 steps.  ``out``: module doc."""
    be = get_backend(backend)
    grid, domain = _levelset_problem(phi, dx, dy, dz, bc, be)
    dx, dy, bcs = domain.dx, domain.dy, domain.bcs
    formula, limit = _grid_formula(domain)
    dtau = limit if dtau is None else check.scalar(dtau, "dtau", strict=True)
    if dtau > limit:
        raise StabilityError(f"dtau={dtau} exceeds the CFL limit {limit:.6g} = {formula}")
    n = max(grid.shape) if iterations is None else check.steps(iterations, "iterations")
    subcell_fix = check.flag(subcell_fix, "subcell_fix")
    kw = {"dz": domain.dz} if domain.ndim == 3 else {}
    _out_for(out, phi, grid.dtype)
    phi0 = _on(be, phi, grid)

    def step(cur, nxt):
        be.reinit_step(cur[0], phi0, nxt[0], dtau=dtau, width=dx, dx=dx, dy=dy, bc=bcs,
                       subcell=subcell_fix, **kw)
    (res,) = _advance(be, (phi0,), n, step, (out,))
    return interop.deliver(res, phi, _given_shape(phi), out)
