"""The functional API: arrays of any library in, the same kind out, any backend.

Every function checks its input, uploads it once, runs all its steps on the device and
downloads once.  Arrays of any kind are accepted (`rdgpu.interop`: NumPy, lists,
Warp, pyopencl, PyTorch, DLPack); one already in the backend's memory is used in place
(no copy), and the result comes back as the kind of the input (a list gives a NumPy
array).  ``out=`` takes an array of the result's shape and dtype (any writable kind)
that receives the result and is returned, so a loop can reuse it.

Inputs are never modified; results keep the input dtype (float32 or float64).  Grid
arrays are ``u[ny, nx]`` (row index is y); a 1-D array ``u[nx]`` is a 1-D problem:
``bc`` is its one condition, ``dy`` does not apply, and the stability limits are the 1-D
ones (the kernels run it as one row with no y axis, see `rdgpu.domains.Grid`).
See docs/equations.md for every scheme.  The SOR solvers are in `rdgpu.ops.solvers`,
the level sets in `rdgpu.ops.levelsets`, the shared result handling in
`rdgpu.ops.results`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.backends import interop
from rdgpu.backends.registry import get_backend
from rdgpu.core import validation as check
from rdgpu.core.csr import checked_csr
from rdgpu.core.errors import StabilityError
from rdgpu.domains.boundary import PERIODIC
from rdgpu.domains.graph_surface import GraphSurface
from rdgpu.domains.grid import Grid
from rdgpu.ir.schemes import get_scheme
from rdgpu.ops.implicit import ImplicitDiffusion, operator_matrix
from rdgpu.ops.inputs import (  # the input checks (kind, size, then values) of every function here
    given_shape,
    grid_or_mesh,
    grid_problem,
    host_field,
    mesh_field,
    no_grid_args,
    on_backend,
    param_value,
)
from rdgpu.ops.results import (
    BackendSpec,
    ProgressBar,
    advance,
    expect_out,
    fresh,
    give,
    give_host,
    upload_optional,
)

if TYPE_CHECKING:
    from rdgpu.domains.mesh.surface_mesh import SurfaceMesh


# ---------------------------------------------------------------------------- stability
def _explicit_limit_formula(grid: Grid, d: str) -> str:
    """The forward-Euler diffusion limit of ``grid`` as text, for error messages."""
    if grid.ndim == 1:
        return f"dx²/(2 {d}) (1-D)"
    return f"1/(2 {d} (1/dx² + 1/dy²))"


def gray_scott_dt_limit(Du: float, Dv: float, dx: float, dy: float) -> float:
    """The forward-Euler time-step limit of Gray-Scott's 5-point diffusion.

    Parameters
    ----------
    Du, Dv : float
        Diffusion coefficients (length²/time).
    dx, dy : float
        Grid spacings (length); ``dy = inf`` for a 1-D grid.

    Returns
    -------
    float
        ``1 / (2 max(Du, Dv) (1/dx² + 1/dy²))`` (time; ``dx²/(2 max(Du, Dv))`` in 1-D,
        ``inf`` when both coefficients are 0).
    """
    Du, Dv = check.scalar(Du, "Du"), check.scalar(Dv, "Dv")
    dx = check.scalar(dx, "dx", strict=True)
    dy = math.inf if dy == math.inf else check.scalar(dy, "dy", strict=True)
    d = max(Du, Dv)
    return math.inf if d == 0 else 1.0 / (2.0 * d * (1.0 / dx**2 + 1.0 / dy**2))


def levelset_dt_limit(max_speed: float, dx: float, dy: float, dz: float = math.inf) -> float:
    """The upwind CFL limit of a level-set step: ``Δt · max|F| · (1/dx + 1/dy (+ 1/dz)) ≤ 1``.

    Parameters
    ----------
    max_speed : float
        The largest normal speed ``max|F|`` (length/time).
    dx, dy, dz : float
        Grid spacings (length); ``dz`` only for a 3-D grid, ``dy = inf`` for a 1-D one.

    Returns
    -------
    float
        The largest stable ``Δt`` (``inf`` for a speed of 0).
    """
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
    mesh: SurfaceMesh | None = None,
    height: Any = None,
    backend: BackendSpec = None,
    out: Any = None,
) -> Any:
    """The discrete Laplacian ``Δu``: 5-point or isotropic 9-point stencil on a grid
    (equations §1), cotangent operator on a triangle mesh (§6), or Laplace-Beltrami
    operator on the graph surface ``z = h(x, y)``.

    Parameters
    ----------
    u : array
        ``u[nx]`` (1-D) or ``u[ny, nx]`` (row index y), float32 or float64, of any array
        library; on a mesh one value per vertex.
    dx, dy : float
        Grid spacings (length); ``dy`` defaults to ``dx``.
    bc : str, tuple or pair of them
        One condition or a pair ``(y_bc, x_bc)``: ``"periodic"``, ``"neumann"`` (zero
        flux) or ``("dirichlet", g)``.
    stencil : {5, 9}
        The 9-point stencil needs ``dx == dy``.
    mesh : SurfaceMesh, optional
        The result is then ``L u`` with the cotangent operator ``L = A⁻¹W``
        (``mesh.laplacian``; open boundaries are zero-flux); ``dx``, ``dy``, ``bc`` and
        ``stencil`` must stay at their defaults.
    height : array, optional
        ``h[ny, nx]`` at the cell centres (in the units of ``dx``): the result is the
        Laplace-Beltrami operator ``Δ_Γ u = (1/√g) ∂_i(√g g^{ij} ∂_j u)`` of the surface
        ``z = h(x, y)`` over the parameter grid of a 2-D ``u`` (the conservative 9-point
        form of `rdgpu.GraphSurface`; ``h = 0`` gives the 5-point Laplacian to
        round-off). The surface is periodic: ``bc`` must be ``"periodic"``; ``stencil``
        does not apply and ``mesh`` cannot be given too.
    backend : str or Backend, optional
        As `rdgpu.get_backend` takes it (default: the current default backend).
    out : array, optional
        An array of u's shape and dtype that receives the result and is returned.

    Returns
    -------
    array
        ``Δu`` (units ``[u]/length²``), the same kind of array as ``u``.
    """
    if height is not None:
        return _surface_laplacian(u, height, dx, dy, bc, stencil, mesh, backend, out)
    be = get_backend(backend)
    if mesh is not None:
        no_grid_args(dx, dy, bc, stencil)
        field = mesh_field(u, mesh, "u", be)
        expect_out(out, u, field.dtype)
        d_u = on_backend(be, u, field)
        res = fresh(be, out, d_u)
        be.spmv(be.upload_csr(mesh.laplacian, field.dtype), d_u, res)
        return give(res, u, out, "laplacian")
    if isinstance(stencil, bool) or stencil not in (5, 9):
        raise ValueError(f"stencil must be 5 or 9, got {stencil!r}")
    field, grid = grid_problem(u, "u", dx, dy, bc, be)
    if grid.ndim == 1:
        stencil = 5  # both stencils are the 3-point (E + W − 2u)/dx² in 1-D
    elif stencil == 9 and grid.dx != grid.dy:
        raise ValueError(f"the 9-point stencil needs dx == dy, got dx={grid.dx}, dy={grid.dy}")
    expect_out(out, u, field.dtype)
    d_u = on_backend(be, u, field)
    res = fresh(be, out, d_u)
    be.laplacian(d_u, res, dx=grid.dx, dy=grid.dy, bc=grid.bcs, stencil=stencil)
    return give(res, u, out, "laplacian")


def _surface_laplacian(u: Any, height: Any, dx: Any, dy: Any, bc: Any, stencil: Any,
                       mesh: SurfaceMesh | None, backend: BackendSpec, out: Any) -> Any:
    """``rdgpu.laplacian(u, height=h, ...)``: ``Δ_Γ u`` on the periodic graph surface of h."""
    if mesh is not None:
        raise ValueError("height= and mesh= given together: height makes the graph surface "
                         "z = h(x, y) over the grid of u, a mesh is a surface of its own; "
                         "give one of them")
    if stencil != 5 or isinstance(stencil, bool):
        raise ValueError(f"stencil={stencil!r} given with height=: the surface operator has "
                         "its own 9-point form (rdgpu.GraphSurface); leave stencil at its default")
    shape_u = given_shape(u)
    if len(shape_u) != 2:
        raise ValueError(f"with height= u must be a 2-D array [ny, nx] on the surface's "
                         f"parameter grid, got a {len(shape_u)}-D array of shape {shape_u}")
    be = get_backend(backend)
    field, grid = grid_problem(u, "u", dx, dy, bc, be)
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
    expect_out(out, u, field.dtype)
    d_u = on_backend(be, u, field)
    res = fresh(be, out, d_u)
    be.metric_laplacian(d_u, be.upload_metric(surface, field.dtype), res)
    return give(res, u, out, "laplacian")


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
    """The exact solution of ``u_t = (u − u³)/ε²`` after a time ``tau``, pointwise
    (equations §2): Allen-Cahn's reaction substep.

    Parameters
    ----------
    u : array
        Any shape (grid cells or mesh vertices), float32 or float64.
    tau : float
        The time advanced (time units).
    eps : float
        The interface width ε (length), > 0.
    backend : str or Backend, optional
        As `rdgpu.get_backend` takes it.
    out : array, optional
        Receives the result (u's shape and dtype) and is returned.

    Returns
    -------
    array
        ``u`` after ``tau``, the same kind of array as ``u``.
    """
    be = get_backend(backend)
    field = host_field(u, "u", tuple(range(1, 8)), be)
    tau = check.scalar(tau, "tau")
    eps = check.scalar(eps, "eps", strict=True)
    decay = bernoulli_decay(tau, eps, field.dtype)
    expect_out(out, u, field.dtype)
    d_u = on_backend(be, u, field)
    res = fresh(be, out, d_u)
    be.bernoulli(d_u, res, decay=decay)
    return give(res, u, out, "bernoulli_substep")


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
    mesh: SurfaceMesh | None = None,
    check_stability: bool = True,
    progress: bool = False,
    backend: BackendSpec = None,
    out: tuple[Any, Any] | None = None,
) -> tuple[Any, Any]:
    """Advance Gray-Scott by ``steps`` forward-Euler steps of ``dt`` (equations §3), one
    fused kernel per step:
    ``u_t = Du Δu − u v² + F (1 − u)``, ``v_t = Dv Δv + u v² − (F + k) v``.

    Parameters
    ----------
    u, v : array
        ``[nx]`` or ``[ny, nx]`` (row index y), float32 or float64, the same shape; on a
        mesh one value per vertex. Never modified.
    Du, Dv : float
        Diffusion coefficients (length²/time).
    F, k : float or array
        Feed and kill rates (1/time), numbers or per-cell (per-vertex) arrays.
    dt : float
        The time step (time units).
    steps : int
        Steps to take; all run on the device between one upload and one download.
    dx, dy, bc
        Grid spacings and boundary conditions, as `laplacian` takes them.
    mesh : SurfaceMesh, optional
        In place of ``dx``/``dy``/``bc``: ``Δ`` is the cotangent operator (equations §6).
    check_stability : bool
        Raise `rdgpu.StabilityError` when ``dt`` passes the limit: on a grid
        ``1 / (2 max(Du, Dv)(1/dx² + 1/dy²))`` (`gray_scott_dt_limit`), on a mesh
        ``mesh.max_stable_dt(max(Du, Dv)) = 2/(max(Du, Dv) λ_max(−L))``.
    progress : bool
        Show a progress bar (tqdm) on stderr.
    backend : str or Backend, optional
        As `rdgpu.get_backend` takes it.
    out : pair of arrays, optional
        ``(u_out, v_out)`` that receive the result and are returned.

    Returns
    -------
    tuple of array
        ``(u, v)`` after ``steps`` steps, the same kind of arrays as the inputs.
    """
    be = get_backend(backend)
    check_stability, progress = (check.flag(check_stability, "check_stability"),
                                 check.flag(progress, "progress"))
    if mesh is not None:
        no_grid_args(dx, dy, bc)
        gu, gv = mesh_field(u, mesh, "u", be), mesh_field(v, mesh, "v", be)
    else:
        gu, grid = grid_problem(u, "u", dx, dy, bc, be)
        gv, _ = grid_problem(v, "v", dx, dy, bc, be)
        shape_u, shape_v = given_shape(u), given_shape(v)
        if shape_u != shape_v:  # as given: a 1-D u and a 1-row v differ
            raise ValueError(f"v has shape {shape_v} but u has shape {shape_u}; they must "
                             "match")
    check.same_dtype(gu, gv, "u", "v")
    if out is not None:
        if not isinstance(out, (tuple, list)) or len(out) != 2:
            raise TypeError(f"out must be a pair (u_out, v_out) of arrays, got "
                            f"{type(out).__name__}")
        expect_out(out[0], u, gu.dtype)
        expect_out(out[1], v, gv.dtype)
        if out[0] is out[1]:
            raise ValueError("out holds one array twice; u_out and v_out must be two arrays")
    outs = (None, None) if out is None else tuple(out)
    Du, Dv = check.scalar(Du, "Du"), check.scalar(Dv, "Dv")
    dt = check.scalar(dt, "dt")
    n = check.steps(steps)
    F_ = param_value(F, "F", gu)
    k_ = param_value(k, "k", gu)
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
    d_F, d_k = upload_optional(be, F_), upload_optional(be, k_)
    start = (on_backend(be, u, gu), on_backend(be, v, gv))
    with ProgressBar(n, "gray-scott", progress) as bar:
        done = [0]

        def step(cur, nxt):
            kernel(cur, nxt)
            done[0] += 1
            bar.tick(done[0])
        res_u, res_v = advance(be, start, n, step, outs)
    gs = {"stepping": True, "check_stability": check_stability}
    return (give(res_u, u, outs[0], "gray_scott", **gs),
            give(res_v, v, outs[1], "gray_scott", **gs))


# ---------------------------------------------------------------------------- SpMV
def spmv(csr: Any, x: Any, backend: BackendSpec = None, *, out: Any = None) -> Any:
    """``y = A x`` on a backend: a drop-in for ``A @ x`` with a 1-D ``x``.

    Parameters
    ----------
    csr : scipy.sparse matrix or array
        ``A``, any format, square or not; cast to x's dtype, its indices checked first.
    x : array
        1-D, float32 or float64, any array kind.
    backend : str or Backend, optional
        As `rdgpu.get_backend` takes it.
    out : array, optional
        Shape ``(n_rows,)`` and x's dtype; receives ``y`` and is returned.

    Returns
    -------
    array
        ``y`` in x's dtype, each row summed in index order in that dtype.

    Notes
    -----
    ``A`` is uploaded on every call: to apply one operator many times, upload it once with
    ``backend.upload_csr`` and call ``backend.spmv``. Neither input is modified.
    """
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
        return give_host(np.zeros(n_rows, dtype=dtype_x), xa, out)
    be = get_backend(backend)
    field = host_field(xa, "x", (1,), be)
    expect_out(out, xa, field.dtype, (n_rows,))
    A = be.upload_csr(m, field.dtype, name="csr")  # refuses values the dtype cannot hold
    y = be.empty((n_rows,), field.dtype)
    be.spmv(A, on_backend(be, xa, field), y)
    return give(y, xa, out, "spmv", shape=(n_rows,))


# ---------------------------------------------------------------------------- diffusion
#: diffusion_step's methods and the scheme of `rdgpu.ir.schemes.SCHEMES` each is for
#: ``u_t = D Δu + source``: forward Euler, and the IMEX θ-schemes (with nothing explicit
#: but the source) whose θ the implicit solve takes
DIFFUSION_METHODS = {"explicit": "euler", "backward-euler": "imex", "crank-nicolson": "imex-cn"}


def diffusion_step(
    u: np.ndarray,
    *,
    D: float,
    dt: float,
    steps: int = 1,
    method: str = "explicit",
    source: float | np.ndarray = 0.0,
    mesh: SurfaceMesh | None = None,
    dx: float = 1.0,
    dy: float | None = None,
    bc: Any = "periodic",
    tol: float | None = None,
    check_stability: bool = True,
    backend: BackendSpec = None,
    out: Any = None,
) -> Any:
    """Advance ``u_t = D Δu + source`` by ``steps`` steps of ``dt`` on a grid or a mesh.

    Parameters
    ----------
    u : array
        ``[nx]`` or ``[ny, nx]`` on a grid, one value per vertex on a mesh.
    D : float
        The diffusion coefficient (length²/time).
    dt : float
        The time step (time units).
    steps : int
        Steps to take.
    method : {"explicit", "backward-euler", "implicit", "crank-nicolson"}
        ``"explicit"``: forward Euler ``u + dt (D Δu + source)``. ``"backward-euler"``
        (alias ``"implicit"``) and ``"crank-nicolson"``: the θ-scheme
        ``(I − θ dt D L) u' = u + (1 − θ) dt D L u + dt source``, stable at any ``dt``
        (`rdgpu.ImplicitDiffusion`): on a grid solved directly by fast transforms
        (`rdgpu.ops.transforms`), on a mesh by multicolour SOR on the device to ``tol``.
    source : float or array
        A number or a field of u's shape ([u]/time).
    mesh : SurfaceMesh, optional
        Run on the mesh; the grid arguments must stay at their defaults.
    dx, dy, bc
        As `laplacian` takes them (5-point stencil, Dirichlet ghosts included).
    tol : float, optional
        The SOR solve's tolerance (default 1e-8 in float64, 1e-5 in float32); the
        transforms are exact to round-off.
    check_stability : bool
        ``"explicit"`` raises `rdgpu.StabilityError` above ``1/(2D(1/dx² + 1/dy²))`` on a
        grid, ``mesh.max_stable_dt(D)`` on a mesh, unless ``False``.
    backend : str or Backend, optional
        As `rdgpu.get_backend` takes it.
    out : array, optional
        Receives the result and is returned.

    Returns
    -------
    array
        ``u`` after ``steps`` steps. On a closed mesh (or a periodic/Neumann grid) every
        method keeps ``Σ A_i u_i`` (``Σ u``) up to ``dt Σ A_i source_i`` per step.
    """
    method = "backward-euler" if method == "implicit" else method
    if method not in DIFFUSION_METHODS:
        raise ValueError(f"method must be one of {tuple(DIFFUSION_METHODS)} (or 'implicit'), "
                         f"got {method!r}")
    be = get_backend(backend)
    field, domain = grid_or_mesh(u, mesh, dx, dy, bc, be=be)
    D = check.scalar(D, "D")
    dt = check.scalar(dt, "dt", strict=True)
    n = check.steps(steps)
    check_stability = check.flag(check_stability, "check_stability")
    if tol is not None and method == "explicit":
        raise ValueError(f"tol={tol!r} given with method='explicit', which solves nothing; "
                         "tol applies to 'backward-euler' and 'crank-nicolson'")
    tol = None if tol is None else check.scalar(tol, "tol", strict=True)
    src = param_value(source, "source", field)
    expect_out(out, u, field.dtype)
    start = (on_backend(be, u, field),)
    scheme = get_scheme(DIFFUSION_METHODS[method])
    if not scheme.implicit:
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
        d_src = upload_optional(be, src)

        def step(cur, nxt):
            be.mesh_diffusion(L, cur[0], nxt[0], D=D, dt=dt, source=d_src)
    else:
        solver = ImplicitDiffusion(domain, D=D, dt=dt, theta=scheme.theta, backend=be,
                                   dtype=field.dtype, tol=tol)
        d_src = upload_optional(be, src)

        def step(cur, nxt):
            solver.step(cur[0], nxt[0], source=d_src)
    (res,) = advance(be, start, n, step, (out,))
    return give(res, u, out, "diffusion_step", stepping=True,
                 check_stability=check_stability)
