"""Analysis of reaction-diffusion models and their patterns.

* :func:`steady_state` — the homogeneous steady state ``R(x*) = 0`` of a model (Newton /
  Powell hybrid from the model's guess), :func:`jacobian` — ``∂R/∂x`` there, exact to
  round-off by the complex-step derivative (the functions of the equation language are
  analytic, so evaluating them with complex numbers is legitimate, except ``abs``, which
  is evaluated as ``sqrt(a*a)`` there, and ``min``/``max``, which select an argument);
* :func:`dispersion` — the growth rate ``Re γ(k)`` of a Fourier mode of wavenumber ``k``:
  the largest real part of the eigenvalues of ``J − k² D + k⁴ B`` (:func:`dispersion_matrix`;
  Quillen 2025, eq. 18, with cross-diffusion and fourth order), ``D`` and ``B`` the
  matrices of the coefficients of ``laplace`` and ``laplace(laplace(·))``
  (:meth:`rdgpu.models.Model.linear_operators`: ``D[s, r]`` multiplies ``laplace(r)`` in
  the equation of ``s``), since the symbol of ``laplace`` is ``−k²`` and that of the
  bilaplacian ``+k⁴``.  On a grid the 3-point (per axis) stencil's mode ``m`` of ``n``
  cells has ``k = (2/dx) sin(π m / n)`` (:func:`grid_wavenumber`), not ``2π m/(n dx)``;
  the generated bilaplacian is that stencil applied twice, so its symbol is exactly the
  square; ``dispersion(..., dx=h)`` maps continuous wavenumbers to the grid's;
* :func:`classify_pattern` — ``"spots"``, ``"inverted-spots"``, ``"stripes"`` or
  ``"uniform"`` (optionally ``"mixed"``, ``"diverged"``) from the connected regions of the
  two phases of a field, or of each member of a stack;
* :func:`fractal_dimension` — the mass-radius or box-counting dimension of a cluster
  (a boolean mask), the log-log slope over a stated fit range;
* :func:`spiral_tips` — how many phase singularities a pair of fields has,
  :func:`phase_defects` — where the vortices of ``u + iv`` are and their charges ±1.
* :func:`spot_statistics` — the spots of a 2-D field on a grid or a graph surface: count,
  surface areas, their spread and the spots' elongation; :func:`stripe_orientation` —
  the stripes' mean direction and coherence from the structure tensor.

Parameters that are fields are replaced by their mean in the linear analysis; parameters
given as expressions must be constants (no ``x, y, z, t``).
"""

from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from rdgpu.domains.boundary import PERIODIC
from rdgpu.domains.grid import Grid

__all__ = [
    "classify_pattern",
    "dispersion",
    "dispersion_matrix",
    "fractal_dimension",
    "grid_wavenumber",
    "jacobian",
    "phase_components",
    "phase_defects",
    "SpotStatistics",
    "spiral_tips",
    "spot_statistics",
    "steady_state",
    "stripe_orientation",
]


def _scalar_params(model: Any, params: Mapping[str, Any] | None) -> dict[str, float]:
    merged = {**model.defaults, **dict(params or {})}
    out: dict[str, float] = {}
    texts: dict[str, str] = {}
    for k, v in merged.items():
        if isinstance(v, str):  # an expression of the other parameters: evaluated below
            texts[k] = v
            continue
        if isinstance(v, Mapping):  # a field spec: its mean value
            kind = v.get("kind")
            if kind == "random":
                v = 0.5 * (float(v["low"]) + float(v["high"]))
            elif kind == "sine":
                v = float(v["mean"])
            elif kind == "linear":
                v = 0.5 * (float(v["start"]) + float(v["stop"]))
            else:
                raise ValueError(f"unknown parameter field spec {v!r}")
        out[k] = float(np.mean(v))
    for k, text in texts.items():
        out[k] = _constant_expression(k, text, out)
    return out


def _constant_expression(name: str, text: str, scalars: Mapping[str, float]) -> float:
    """A parameter given as text: its value from the (numeric) parameters, or a
    ``ValueError`` if it varies in space or time."""
    from rdgpu.ir import equations as eq

    tree = eq.parse(text, params=list(scalars), what=f"parameter {name!r}", laplace=False)
    varying = sorted(eq.names(tree, "coord") | eq.names(tree, "time")
                     | eq.names(tree, "length"))
    if varying:
        raise ValueError(
            f"parameter {name!r} = {text!r} depends on {', '.join(varying)}: the linear "
            "analysis needs a homogeneous medium; pass a number for it"
        )
    return float(eq.evaluate(tree, dict(scalars)))


def _rates(model: Any, x: Sequence[Any], params: dict[str, float], dtype) -> np.ndarray:
    r = model.rates([np.asarray(xi, dtype=dtype) for xi in x], params, dtype)
    return np.array([np.asarray(ri, dtype=dtype) for ri in r])


def _analytic(model: Any) -> Any:
    """The model for the complex step: ``abs(a)`` (not analytic: NumPy's complex ``abs`` is
    the modulus, whose imaginary part is 0) becomes ``sqrt(a*a)``, equal to ``|a|`` for
    real ``a`` and carrying ``sign(a)·h`` in the imaginary part."""
    trees = getattr(model, "trees", None)
    if not isinstance(trees, Mapping):
        return model
    from rdgpu.ir import equations as eq

    def fix(node):
        if isinstance(node, eq.Call) and node.fn == "abs":
            a = eq.substitute(node.args[0], fix)
            return eq.Call("sqrt", (eq.Bin("*", a, a),))
        return None

    uses_abs = any(isinstance(n, eq.Call) and n.fn == "abs"
                   for t in trees.values() for n in eq.walk(t))
    if not uses_abs:
        return model
    shadow = copy.copy(model)
    shadow.trees = {s: eq.substitute(t, fix) for s, t in trees.items()}
    return shadow


def jacobian(model: Any, params: Mapping[str, Any] | None, state: Sequence[float]) -> np.ndarray:
    """``J_ij = ∂R_i/∂x_j`` at ``state`` by the complex step (float64, exact to round-off;
    ``min``/``max`` take the derivative of the selected argument, ``abs`` that of ``±a``)."""
    p = _scalar_params(model, params)
    x = np.asarray(state, dtype=np.float64)
    n = x.size
    h = 1e-30
    J = np.empty((n, n))
    m = _analytic(model)
    for j in range(n):
        xc = x.astype(np.complex128)
        xc[j] += 1j * h
        J[:, j] = _rates(m, list(xc), p, np.complex128).imag / h
    return J


def steady_state(
    model: Any,
    params: Mapping[str, Any] | None = None,
    guess: Sequence[float] | None = None,
    *,
    tol: float = 1e-10,
) -> np.ndarray:
    """A homogeneous steady state ``R(x*) = 0`` near ``guess`` (default: the model's
    ``steady_guess``, else 1 for every species).  Raises ``RuntimeError`` if the solver
    does not converge to ``max|R| < tol (1 + max|x*|)``."""
    from scipy.optimize import root

    p = _scalar_params(model, params)
    if guess is None:
        g = model.steady_guess(p) if hasattr(model, "steady_guess") else None
        guess = g if g is not None else [1.0] * len(model.species)
    x0 = np.asarray(guess, dtype=np.float64)

    def fun(x):
        return _rates(model, list(x), p, np.float64)

    sol = root(fun, x0, jac=lambda x: jacobian(model, p, x), method="hybr", tol=1e-14)
    x = np.asarray(sol.x, dtype=np.float64)
    res = float(np.max(np.abs(fun(x))))
    if not np.isfinite(res) or res > tol * (1.0 + float(np.max(np.abs(x)))):
        raise RuntimeError(
            f"no steady state of {model.name!r} found near {list(x0)}: residual {res:.3g} "
            f"({sol.message}); pass a better guess"
        )
    return x


def _spatial_operators(model: Any, params: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """``(D, B)``: the coefficients of ``laplace(r)`` and ``laplace(laplace(r))`` in the
    equation of each species (rows) — :meth:`Model.linear_operators`, or the diagonal of
    ``diffusion_coefficients`` for a model object without it."""
    n = len(model.species)
    if hasattr(model, "linear_operators"):
        ops = model.linear_operators(params)
        if ops is None:
            linear = getattr(model, "linear", {})
            which = [s for s in model.species if linear.get(s, 0) is None]
            where = f" (the equation of {', '.join(map(repr, which))})" if which else ""
            raise ValueError(
                f"model {model.name!r} has a Laplacian with a state-dependent coefficient"
                f"{where}, such as u*laplace(u): the dispersion relation needs every "
                "laplace(s) and laplace(laplace(s)) multiplied by numbers and parameters "
                "only"
            )
        D, B = (np.asarray(a, dtype=np.float64) for a in ops)
    else:
        D = np.diag(np.asarray(model.diffusion_coefficients(params), dtype=np.float64))
        B = np.zeros((n, n))
    for name, a in (("laplace", D), ("laplace(laplace)", B)):
        if not np.isfinite(a).all():
            raise ValueError(f"model {model.name!r}: a coefficient of {name} is not finite "
                             f"with these parameters:\n{a}")
    return D, B


def dispersion_matrix(
    model: Any,
    params: Mapping[str, Any] | None,
    k: Any,
    *,
    state: Sequence[float] | None = None,
    dx: float | None = None,
) -> np.ndarray:
    """The linearisation ``J − k² D + k⁴ B`` about the homogeneous steady state (or
    ``state``) acting on a Fourier mode ``e^{ik·x}`` of every species: shape ``k.shape +
    (n, n)``, ``n`` the number of species; ``J`` the reaction Jacobian (:func:`jacobian`),
    ``D[s, r]`` / ``B[s, r]`` the coefficients of ``laplace(r)`` / ``laplace(laplace(r))``
    in the equation of ``s``.  ``dx``: the grid's symbol instead, ``k² → (4/dx²)
    sin²(k dx/2)`` (the 3-point stencil along one axis; for a mode of several axes pass
    ``sqrt`` of the sum of the axes' ``grid_wavenumber²``).  ``ValueError`` if a Laplacian
    has a state-dependent coefficient."""
    p = _scalar_params(model, params)
    D, B = _spatial_operators(model, p)
    x = steady_state(model, p) if state is None else np.asarray(state, dtype=np.float64)
    if x.shape != (len(model.species),):
        raise ValueError(f"state must hold one value per species {model.species}, got "
                         f"{list(np.ravel(x))}")
    J = jacobian(model, p, x)
    k = np.asarray(k, dtype=np.float64)
    if dx is not None:
        k = 2.0 / float(dx) * np.abs(np.sin(0.5 * k * float(dx)))
    k2 = (k * k)[..., None, None]
    return J - k2 * D + (k2 * k2) * B


def dispersion(
    model: Any,
    params: Mapping[str, Any] | None,
    k: Any,
    *,
    state: Sequence[float] | None = None,
    dx: float | None = None,
) -> np.ndarray:
    """Growth rate ``Re γ(k)``: the largest real part of the eigenvalues of
    ``J − k² D + k⁴ B`` (:func:`dispersion_matrix`: cross-diffusion and bilaplacians
    included) at the homogeneous steady state (or at ``state``), for each wavenumber in
    ``k`` (any shape; the result has the same shape).  ``dx``: with the grid's symbol
    (:func:`dispersion_matrix`); equivalently pass ``k = grid_wavenumber(m, n, dx)``."""
    A = dispersion_matrix(model, params, k, state=state, dx=dx)
    return np.asarray(np.linalg.eigvals(A).real.max(axis=-1))


def grid_wavenumber(m: Any, n: int, dx: float = 1.0) -> np.ndarray:
    """Wavenumber of Fourier mode ``m`` on ``n`` periodic cells as the 3-point stencil
    (one axis of the 5- and 7-point ones) sees it: ``−Δ_h e^{2πimj/n} = k² e^{2πimj/n}``
    with ``k = (2/dx)|sin(π m/n)|``; the bilaplacian (the stencil twice) sees ``k⁴``.  On
    ``n`` Neumann cells the mode ``cos(π m (j + ½)/n)`` has ``grid_wavenumber(m, 2n, dx)``."""
    return (2.0 / dx) * np.abs(np.sin(np.pi * np.asarray(m, dtype=np.float64) / n))


# ---------------------------------------------------------------------------- patterns
def _graph_edges(domain: Any, shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Neighbour pairs of the domain's graph: 4-neighbours on a grid (wrapped along
    periodic axes), the edges of a mesh."""
    if isinstance(domain, Grid) or domain is None:
        if len(shape) == 1:
            shape = (1, shape[0])
        ny, nx = shape
        idx = np.arange(ny * nx).reshape(ny, nx)
        px = domain is not None and domain.bcs.x.kind == PERIODIC
        py = domain is not None and domain.bcs.y.kind == PERIODIC
        a = [idx[:, :-1].ravel(), idx[:-1, :].ravel()]
        b = [idx[:, 1:].ravel(), idx[1:, :].ravel()]
        if px and nx > 2:
            a.append(idx[:, -1])
            b.append(idx[:, 0])
        if py and ny > 2:
            a.append(idx[-1, :])
            b.append(idx[0, :])
        return np.concatenate(a), np.concatenate(b)
    edges = np.asarray(domain.edges)
    return edges[:, 0], edges[:, 1]


def phase_components(
    field: Any, domain: Any = None, threshold: float | None = 0.0
) -> dict[str, Any]:
    """Connected regions of the two phases ``high = field > threshold`` and
    ``low = field <= threshold`` (``threshold=None``: the midrange of the field).

    Returns ``threshold``; ``fraction_high``; ``high`` and ``low``: the sizes (points) of
    each phase's components, largest first; ``elongation_high`` / ``elongation_low``: per
    component (same order) ``size / (r + ½)²`` with ``r`` its inradius in graph steps (the
    largest number of edges from one of its points to the other phase; the ½ makes islands
    a point or two across come out compact): about π (less for small ones) for a round
    island, about 2π for a 2:1 ellipse, ``~4 L / w`` for a band of length ``L`` and width
    ``w``."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components, dijkstra

    f = np.asarray(field.numpy() if hasattr(field, "numpy") else field, dtype=np.float64)
    if domain is not None and isinstance(domain, Grid):
        f = f.reshape(domain.shape)
    n = f.size
    if threshold is None:
        threshold = 0.5 * (float(f.min()) + float(f.max()))
    high = (f > threshold).ravel()
    a, b = _graph_edges(domain, f.shape)
    keep = high[a] == high[b]
    same = coo_matrix((np.ones(int(keep.sum()), dtype=np.int8), (a[keep], b[keep])), shape=(n, n))
    _, labels = connected_components(same, directed=False)
    sizes = np.bincount(labels, minlength=1)
    label_high = np.zeros(sizes.size, dtype=bool)
    label_high[labels[high]] = True
    # inradius of every component: graph distance of each point to the other phase
    full = coo_matrix((np.ones(a.size), (a, b)), shape=(n, n)).tocsr()
    depth = np.zeros(n)
    for phase in (high, ~high):
        other = np.flatnonzero(~phase)
        if other.size and phase.any():
            d = dijkstra(full, directed=False, indices=other, unweighted=True, min_only=True)
            depth[phase] = d[phase]
    inradius = np.zeros(sizes.size)
    np.maximum.at(inradius, labels, depth)
    inradius[~np.isfinite(inradius)] = np.inf  # a phase alone: no boundary

    out: dict[str, Any] = {"threshold": float(threshold),
                           "fraction_high": float(high.mean()) if n else 0.0}
    for name, mask in (("high", label_high), ("low", ~label_high & (sizes > 0))):
        ids = np.flatnonzero(mask)
        order = ids[np.argsort(-sizes[ids], kind="stable")]
        out[name] = sizes[order]
        with np.errstate(divide="ignore"):
            out[f"elongation_{name}"] = sizes[order] / (np.maximum(inradius[order], 1.0) + 0.5) ** 2
    return out


def classify_pattern(
    field: Any,
    domain: Any = None,
    threshold: float | None = None,
    *,
    connected: float = 0.9,
    elongated: float = 6.0,
    min_size: int = 1,
    rtol: float = 1e-3,
    atol: float = 1e-12,
    mixed: float | None = None,
    nonfinite: str = "raise",
    members: bool | None = None,
    lone: float = 0.25,
) -> Any:
    """``"spots"``, ``"inverted-spots"``, ``"stripes"`` or ``"uniform"`` (and, when asked
    for, ``"mixed"`` and ``"diverged"``).

    The field splits into a high phase (``> threshold``; ``threshold=None``, the default:
    the midrange ``(min + max)/2``, which splits any pattern whatever its offset -- a
    Gray-Scott ``u`` lies in (0, 1], an Allen-Cahn ``u`` around 0; give ``threshold=0.0``
    for a field whose phases are its signs) and a low phase; their connected regions are
    found on the domain's graph
    (4-neighbours on a grid, wrapped across periodic boundaries; mesh edges on a
    :class:`~rdgpu.domains.mesh.SurfaceMesh`; ``domain=None``: a non-periodic grid).  Components
    smaller than ``min_size`` points are ignored.  A phase is *connected* when its largest
    component holds at least ``connected`` (0.9) of it; a component is *elongated* when
    its elongation (:func:`phase_components`) exceeds ``elongated`` (6: longer than about
    twice its width; a round island gives 2 to 3.5).

    * ``uniform``: a phase is absent, or (``threshold=None``) the field's range is below
      ``max(rtol · max|field|, atol)`` (round-off of a uniform field is ~1e-7 of it in
      float32, far below ``rtol = 1e-3``; the midrange would split round-off into phases);
    * ``spots``: the high phase is connected and the low phase is not, and most of the low
      phase (by area) lies in compact islands — isolated islands of low values in a sea of
      high ones;
    * ``inverted-spots``: the reverse (compact islands of high values: "holes" of the low
      phase seen the other way round);
    * ``mixed`` (only with ``mixed=q``, e.g. 0.25): islands in a connected sea of which
      compact ones and elongated ones (worms) each hold more than ``q`` of the islands'
      area;
    * a phase that is connected but covers less than ``lone`` (0.25) of the domain is
      taken as islands (one spot, or a few with one much larger than the rest, in a sea);
    * ``stripes``: everything else with both phases present — both connected (a labyrinth;
      also a single band of each), neither connected (several bands of each phase, e.g.
      parallel stripes on a periodic grid), or islands that are mostly elongated (worms in
      a connected background);
    * ``diverged``: the field holds NaN or Inf and ``nonfinite="diverged"``; with the
      default ``nonfinite="raise"`` that is a ``ValueError``.

    A stack of fields ``[M, *shape]`` (``members=True``, or ``members=None`` with a domain
    whose shape is ``shape``) gives a list of ``M`` classes, one per member.
    """
    if nonfinite not in ("raise", "diverged"):
        raise ValueError(f"nonfinite must be 'raise' or 'diverged', got {nonfinite!r}")
    if mixed is not None and not 0.0 < float(mixed) < 0.5:
        raise ValueError(f"mixed must be None or a fraction in (0, 0.5), got {mixed!r}")
    f = np.asarray(field.numpy() if hasattr(field, "numpy") else field, dtype=np.float64)
    if members is None:
        shape = tuple(domain.shape) if isinstance(domain, Grid) else None
        if shape is None and domain is not None and hasattr(domain, "n_vertices"):
            shape = (int(domain.n_vertices),)
        members = shape is not None and f.ndim == len(shape) + 1 and f.shape[1:] == shape
    opts = {"connected": connected, "elongated": elongated, "min_size": min_size,
            "rtol": rtol, "atol": atol, "mixed": mixed, "nonfinite": nonfinite, "lone": lone}
    if members:
        if f.ndim < 2:
            raise ValueError(f"members=True needs a stack [M, *shape], got shape {f.shape}")
        return [_classify_one(f[i], domain, threshold, **opts) for i in range(f.shape[0])]
    return _classify_one(f, domain, threshold, **opts)


def _classify_one(f: np.ndarray, domain: Any, threshold: float | None, *, connected: float,
                  elongated: float, min_size: int, rtol: float, atol: float,
                  mixed: float | None, nonfinite: str, lone: float) -> str:
    """:func:`classify_pattern` of one field."""
    if not np.isfinite(f).all():
        if nonfinite == "diverged":
            return "diverged"
        raise ValueError("classify_pattern: the field contains NaN or Inf")
    if threshold is None and float(np.ptp(f)) <= max(rtol * float(np.abs(f).max()), atol):
        return "uniform"
    comps = phase_components(f, domain, threshold)
    keep_hi = comps["high"] >= min_size
    keep_lo = comps["low"] >= min_size
    hi, lo = comps["high"][keep_hi], comps["low"][keep_lo]
    if hi.size == 0 or lo.size == 0:
        return "uniform"
    conn_hi = hi[0] >= connected * hi.sum()
    conn_lo = lo[0] >= connected * lo.sum()

    def islands(sizes, elong, name: str) -> str:
        share = float(sizes[elong <= elongated].sum()) / float(sizes.sum())
        if mixed is not None and mixed < share < 1.0 - mixed:
            return "mixed"
        return name if share > 0.5 else "stripes"

    if conn_hi and conn_lo:  # one island in a sea (spots) or a band/labyrinth of each
        frac_hi = float(hi.sum()) / float(hi.sum() + lo.sum())
        if frac_hi < lone:
            conn_hi = False
        elif 1.0 - frac_hi < lone:
            conn_lo = False
    if conn_hi and not conn_lo:
        return islands(lo, comps["elongation_low"][keep_lo], "spots")
    if conn_lo and not conn_hi:
        return islands(hi, comps["elongation_high"][keep_hi], "inverted-spots")
    return "stripes"


# ---------------------------------------------------------------------------- spirals
def _wrapped(d: np.ndarray) -> np.ndarray:
    return (d + np.pi) % (2.0 * np.pi) - np.pi


def _grid_winding(theta: np.ndarray, domain: Any) -> np.ndarray:
    """Winding of the phase ``theta`` (radians) around every plaquette of four neighbouring
    cells of a 2-D grid, corners ``(i, j) → (i, j+1) → (i+1, j+1) → (i+1, j)``: ``w[i, j]``
    is ``2π`` times the winding number of the plaquette whose lower corner is cell
    ``(i, j)``.  Plaquettes across a periodic side are included (the array is then
    ``ny`` or ``nx`` long along that axis, else one shorter)."""
    if domain is not None:
        theta = theta.reshape(domain.shape)
    if theta.ndim != 2:
        raise ValueError(f"phase windings need a 2-D grid field, got shape {theta.shape}")
    t = theta
    if domain is not None and domain.bcs.x.kind == PERIODIC:
        t = np.concatenate([t, t[:, :1]], axis=1)
    if domain is not None and domain.bcs.y.kind == PERIODIC:
        t = np.concatenate([t, t[:1, :]], axis=0)
    c00, c01, c11, c10 = t[:-1, :-1], t[:-1, 1:], t[1:, 1:], t[1:, :-1]
    return _wrapped(c01 - c00) + _wrapped(c11 - c01) + _wrapped(c10 - c11) + _wrapped(c00 - c10)


def spiral_tips(
    u: Any,
    v: Any,
    domain: Any = None,
    center: Sequence[float] | None = None,
) -> int:
    """Number of phase singularities (spiral tips) of the pair ``(u, v)``.

    The phase ``θ = atan2(v − v_c, u − u_c)`` around ``center = (u_c, v_c)`` (default: the
    fields' means) winds by ±2π around each spiral tip; the tips are the elementary loops
    with a nonzero winding number: the plaquettes of four neighbouring cells on a grid
    (wrapped across periodic sides), the faces of a mesh.  A rotating spiral keeps its tips;
    target waves, stripes and spots have none."""
    a = np.asarray(u, dtype=np.float64)
    b = np.asarray(v, dtype=np.float64)
    uc, vc = (float(a.mean()), float(b.mean())) if center is None else map(float, center)
    theta = np.arctan2(b - vc, a - uc)
    if domain is None or isinstance(domain, Grid):
        w = _grid_winding(theta, domain)
    else:
        f = np.asarray(domain.faces)
        t0, t1, t2 = theta.ravel()[f[:, 0]], theta.ravel()[f[:, 1]], theta.ravel()[f[:, 2]]
        w = _wrapped(t1 - t0) + _wrapped(t2 - t1) + _wrapped(t0 - t2)
    return int(np.count_nonzero(np.abs(w) > np.pi))


def phase_defects(
    u: Any,
    v: Any,
    domain: Any = None,
    center: Sequence[float] = (0.0, 0.0),
) -> tuple[np.ndarray, np.ndarray]:
    """The phase defects (vortices) of the complex field ``A = u + iv`` on a 2-D grid:
    ``(positions, charges)``.

    The phase ``θ = arg(A − (u_c + i v_c))`` (``center = (u_c, v_c)``, default 0: the
    complex Ginzburg-Landau field) is followed around every plaquette of four neighbouring
    cells (wrapped across periodic sides; ``domain=None``: no periodic side), each step's
    change taken in ``[−π, π)``; the sum is ``2π q`` with ``q`` an integer, the charge.
    ``positions``: ``(n, 2)`` floats, the ``(row, column)`` of each plaquette with
    ``q ≠ 0`` in cell units, ``i + ½, j + ½`` for the plaquette whose corners are cells
    ``i..i+1``, ``j..j+1`` (``ny − ½`` or ``nx − ½`` across a periodic side);
    ``charges``: ``(n,)`` ints, ``+1`` where the phase increases counterclockwise in the
    ``(x, y) = (column, row)`` plane (``A ∝ (x − x₀) + i(y − y₀)``), ``−1`` for the other
    sense.  On a fully periodic grid the charges sum to 0 (the phase is single-valued on
    the torus); on a bounded grid they need not."""
    a = np.asarray(u.numpy() if hasattr(u, "numpy") else u, dtype=np.float64)
    b = np.asarray(v.numpy() if hasattr(v, "numpy") else v, dtype=np.float64)
    if a.shape != b.shape:
        raise ValueError(f"u and v must have the same shape, got {a.shape} and {b.shape}")
    if domain is not None and (not isinstance(domain, Grid) or domain.ndim != 2):
        raise ValueError("phase_defects works on 2-D grids (rdgpu.domains.Grid((ny, nx)))")
    uc, vc = (float(c) for c in center)
    w = _grid_winding(np.arctan2(b - vc, a - uc), domain)
    q = np.rint(w / (2.0 * np.pi)).astype(np.int64)
    rows, cols = np.nonzero(q)
    positions = np.column_stack([rows + 0.5, cols + 0.5]).astype(np.float64)
    return positions, q[rows, cols]


# ---------------------------------------------------------------------------- fractals
@dataclass
class FractalDimension:
    """A fitted dimension: ``dimension`` is the least-squares slope of ``log counts`` on
    ``log scales`` over the points with ``fit[0] <= scale <= fit[1]``.  Mass-radius:
    ``scales`` are radii ``r`` (cells) and ``counts`` the object cells within ``r`` of
    ``center``; box counting: ``scales`` are box sides ``s`` and ``counts`` the boxes
    holding object cells, fitted as ``counts ∝ s^-D`` (the slope's sign is flipped)."""

    dimension: float
    method: str
    fit: tuple[float, float]
    scales: np.ndarray
    counts: np.ndarray
    used: np.ndarray
    center: tuple[float, float] | None = None


def _fit_slope(scales: np.ndarray, counts: np.ndarray, lo: float, hi: float, what: str):
    used = (scales >= lo) & (scales <= hi) & (counts > 0)
    if np.count_nonzero(used) < 2:
        raise ValueError(f"fractal_dimension: the fit range {lo:g}..{hi:g} holds "
                         f"{int(np.count_nonzero(used))} {what}; at least 2 are needed (widen "
                         "fit, or grow a larger cluster)")
    slope = np.polyfit(np.log(scales[used]), np.log(counts[used]), 1)[0]
    return float(slope), used


def fractal_dimension(
    mask: Any,
    method: str = "mass-radius",
    center: tuple[float, float] | None = None,
    fit: tuple[float, float] | None = None,
) -> FractalDimension:
    """The fractal dimension of the object ``mask`` (2-D, non-zero = object).

    ``"mass-radius"``: ``N(r)`` = object cells whose centre lies within ``r`` of
    ``center`` (default: the object's centroid; pass the seed, e.g. ``result.center`` of
    :func:`rdgpu.dla`) at 24 log-spaced radii from 1 to the cluster radius ``R`` (the
    farthest object cell); ``D`` is the slope of ``log N`` on ``log r`` over
    ``fit = (rmin, rmax)``, default ``(2, R/3)``: below 2 cells the lattice dominates,
    beyond ``R/3`` the still-growing outer branches are not yet filled in.
    ``"box"``: the object's bounding box padded to a square of side ``L`` (a power of
    2), covered by boxes of side ``s = 1, 2, 4, …, L``; ``N(s)`` boxes hold object cells and
    ``D`` is minus the slope of ``log N`` on ``log s`` over ``fit = (smin, smax)``,
    default ``(2, L/8)``: boxes of 1 cell see one-cell-thin branches as lines, and the
    largest boxes (fewer than 64 cover the square) see only the cluster's outline.  On
    clusters of a few thousand cells box counting reads lower than mass-radius (an Eden
    cluster of 2700 cells: 1.8 against 2.0); prefer mass-radius there."""
    m = np.asarray(mask)
    if m.ndim != 2 or m.size == 0:
        raise ValueError(f"mask must be a non-empty 2-D array, got shape {m.shape}")
    m = m != 0
    if not m.any():
        raise ValueError("mask holds no object cell; a dimension needs a non-empty object")
    ii, jj = np.nonzero(m)
    if method == "mass-radius":
        if center is None:
            center = (float(ii.mean()), float(jj.mean()))
        ci, cj = (float(x) for x in center)
        d = np.hypot(ii - ci, jj - cj)
        radius = float(d.max())
        if radius < 2:
            raise ValueError(f"the object reaches only {radius:.3g} cells from its centre; "
                             "a mass-radius fit needs a larger object")
        radii = np.unique(np.geomspace(1.0, radius, 24))
        counts = np.searchsorted(np.sort(d), radii, side="right").astype(np.float64)
        lo, hi = (2.0, radius / 3.0) if fit is None else (float(fit[0]), float(fit[1]))
        slope, used = _fit_slope(radii, counts, lo, hi, "radii")
        return FractalDimension(slope, method, (lo, hi), radii, counts, used, (ci, cj))
    if method == "box":
        box = m[ii.min():ii.max() + 1, jj.min():jj.max() + 1]
        side = 1 << int(max(box.shape) - 1).bit_length()
        grid = np.zeros((side, side), bool)
        grid[:box.shape[0], :box.shape[1]] = box
        sizes, counts = [], []
        s = 1
        while s <= side:
            n = side // s
            counts.append(int(grid.reshape(n, s, n, s).any(axis=(1, 3)).sum()))
            sizes.append(s)
            s *= 2
        sizes_a = np.asarray(sizes, np.float64)
        counts_a = np.asarray(counts, np.float64)
        lo, hi = (2.0, side / 8.0) if fit is None else (float(fit[0]), float(fit[1]))
        slope, used = _fit_slope(sizes_a, counts_a, lo, hi, "box sizes")
        return FractalDimension(-slope, method, (lo, hi), sizes_a, counts_a, used)
    raise ValueError(f"unknown method {method!r}; allowed: 'mass-radius', 'box'")


# ---------------------------------------------------------------------------- spot measures
@dataclass
class SpotStatistics:
    """The spots of a field (:func:`spot_statistics`), largest first.

    ``count``: how many spots; ``areas``: each spot's area (surface area on a
    :class:`~rdgpu.GraphSurface`, ``cells · dx · dy`` on a flat grid; units of
    ``dx²``); ``size_spread``: the coefficient of variation ``std/mean`` of ``areas``
    (population std; 0 for one spot, NaN for none); ``elongations``: each spot's ratio
    ``a/b ≥ 1`` of its principal axes; ``elongation``: their mean (NaN for no spot);
    ``centroids``: each spot's centre ``(x, y)`` in ``[0, Lx) × [0, Ly)``;
    ``threshold``: the level that separated spots from background; ``high``: whether spots
    were the values above it."""

    count: int
    areas: np.ndarray
    size_spread: float
    elongations: np.ndarray
    elongation: float
    centroids: np.ndarray
    threshold: float
    high: bool


def _unwrap_axis(c: np.ndarray, period: float, wrap: bool) -> np.ndarray:
    """Coordinates ``c`` of one periodic component made contiguous: the circle is cut at
    the widest gap between the occupied coordinates, and the ones past the cut move back
    by one period (a component wrapping all the way round keeps its coordinates)."""
    if not wrap or c.size == 0:
        return c
    u = np.unique(c)
    gaps = np.diff(np.append(u, u[0] + period))
    k = int(np.argmax(gaps))
    if k == u.size - 1:  # the widest gap is across the seam: nothing straddles it
        return c
    return np.where(c > u[k], c - period, c)


def _surface_frame(domain: Any, shape: tuple[int, int]) -> tuple[np.ndarray, float, float,
                                                                 bool, bool, np.ndarray | None]:
    """Cell areas, spacings, periodicity per axis and heights (or None) of a 2-D domain."""
    if domain is None:
        return np.ones(shape), 1.0, 1.0, False, False, None
    if not isinstance(domain, Grid) or domain.ndim != 2:
        raise ValueError(f"spot and stripe measures need a 2-D Grid or GraphSurface (or None), "
                         f"got {domain!r}")
    if tuple(domain.shape) != shape:
        raise ValueError(f"the field has shape {shape}; the domain's shape is {domain.shape}")
    weights = getattr(domain, "area_weights", None)
    area = np.asarray(weights, np.float64) if weights is not None else \
        np.full(shape, domain.dx * domain.dy)
    height = getattr(domain, "height", None)
    return (area, float(domain.dx), float(domain.dy), domain.bcs.x.kind == PERIODIC,
            domain.bcs.y.kind == PERIODIC, None if height is None else np.asarray(height))


def _field_2d(field: Any) -> np.ndarray:
    f = np.asarray(field.numpy() if hasattr(field, "numpy") else field, dtype=np.float64)
    if f.ndim != 2 or f.size == 0:
        raise ValueError(f"the field must be a non-empty 2-D array [ny, nx], got shape {f.shape}")
    if not np.isfinite(f).all():
        raise ValueError("the field contains NaN or Inf; measures need finite values")
    return f


def spot_statistics(
    field: Any,
    domain: Any = None,
    *,
    threshold: float | None = None,
    high: bool | None = None,
    min_cells: int = 1,
) -> SpotStatistics:
    """Count and measure the spots of a 2-D field on a :class:`~rdgpu.domains.Grid` or a
    :class:`~rdgpu.GraphSurface` (``domain=None``: a non-periodic grid, ``dx = 1``).

    A spot is a connected region (4-neighbours, wrapped across periodic boundaries) of the
    cells above ``threshold`` (``high=True``) or at/below it (``high=False``).
    ``threshold=None``: the midrange ``(min + max)/2``.  ``high=None``: spots are the phase
    that covers less of the domain (spots are the minority phase; the rest is the sea).
    Regions of fewer than ``min_cells`` cells are ignored.

    Areas sum ``area_weights`` (``√g dx dy``) on a surface, ``dx dy`` per cell on a grid.
    The elongation of a spot is ``√(λ1/λ2)``, the ratio of the principal axes of its
    area-weighted second moment about its centroid: of the positions ``(x, y)`` (unwrapped
    across periodic seams), and on a surface of ``(x, y, h)``, its two largest eigenvalues.
    Each cell counts as a uniform ``dx × dy`` square (adding ``dx²/12``, ``dy²/12``), so a
    one-cell spot on a square grid and a disc both give 1, an ellipse its axis ratio."""
    f = _field_2d(field)
    area, dx, dy, px, py, height = _surface_frame(domain, f.shape)
    if int(min_cells) < 1:
        raise ValueError(f"min_cells must be >= 1, got {min_cells!r}")
    if threshold is None:
        threshold = 0.5 * (float(f.min()) + float(f.max()))
    above = f > float(threshold)
    if high is None:
        high = bool(np.count_nonzero(above) <= f.size / 2)
    mask = (above if high else ~above).ravel()

    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    a, b = _graph_edges(domain, f.shape)
    keep = mask[a] & mask[b]
    n = f.size
    graph = coo_matrix((np.ones(int(keep.sum()), np.int8), (a[keep], b[keep])), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    cells = np.flatnonzero(mask)
    ids, inverse, ncells = np.unique(labels[cells], return_inverse=True, return_counts=True)
    ny, nx = f.shape
    rows, cols = np.divmod(cells, nx)
    x, y = (cols + 0.5) * dx, (rows + 0.5) * dy
    w_all = area.ravel()[cells]
    z = height.ravel()[cells] if height is not None else None
    spots = []
    for k in np.flatnonzero(ncells >= int(min_cells)):
        sel = inverse == k
        w = w_all[sel]
        pts = [_unwrap_axis(x[sel], nx * dx, px), _unwrap_axis(y[sel], ny * dy, py)]
        if z is not None:
            pts.append(z[sel])
        p = np.stack(pts)
        mean = p @ w / w.sum()
        d = p - mean[:, None]
        cov = (d * w) @ d.T / w.sum()
        cov[0, 0] += dx * dx / 12.0
        cov[1, 1] += dy * dy / 12.0
        lam = np.sort(np.linalg.eigvalsh(cov))[::-1]
        ratio = float(np.sqrt(lam[0] / lam[1])) if lam[1] > 0 else np.inf
        centre = (mean[0] % (nx * dx), mean[1] % (ny * dy))
        spots.append((float(w.sum()), ratio, centre))
    spots.sort(key=lambda s: -s[0])
    areas = np.array([s[0] for s in spots], np.float64)
    ratios = np.array([s[1] for s in spots], np.float64)
    centroids = np.array([s[2] for s in spots], np.float64).reshape(-1, 2)
    spread = float(areas.std() / areas.mean()) if areas.size else float("nan")
    return SpotStatistics(
        count=int(areas.size), areas=areas, size_spread=spread, elongations=ratios,
        elongation=float(ratios.mean()) if ratios.size else float("nan"),
        centroids=centroids, threshold=float(threshold), high=bool(high))


def _periodic_gradients(f: np.ndarray, dx: float, dy: float, px: bool,
                        py: bool) -> tuple[np.ndarray, np.ndarray]:
    """Centred differences ``(∂f/∂x, ∂f/∂y)``: wrapped on periodic axes, one-sided at the
    edges of the others."""
    if px:
        gx = (np.roll(f, -1, axis=1) - np.roll(f, 1, axis=1)) / (2.0 * dx)
    else:
        gx = np.gradient(f, dx, axis=1)
    if py:
        gy = (np.roll(f, -1, axis=0) - np.roll(f, 1, axis=0)) / (2.0 * dy)
    else:
        gy = np.gradient(f, dy, axis=0)
    return gx, gy


def stripe_orientation(field: Any, domain: Any = None) -> tuple[float, float]:
    """The stripes' direction and how well they share it: ``(angle, coherence)``.

    From the area-weighted mean structure tensor ``J = ⟨∇f ∇fᵀ⟩`` over the domain, with
    ``∇f`` by centred differences in the parameter coordinates ``(x, y)`` (wrapped on
    periodic axes; on a :class:`~rdgpu.GraphSurface` the cells are weighted by
    their surface area).  Its leading eigenvector is the mean stripe normal; ``angle`` is
    the stripes' direction (normal + π/2) in radians from the x axis towards y, in
    ``[0, π)``; ``coherence = (λ1 − λ2)/(λ1 + λ2)`` in ``[0, 1]``: 1 for perfectly parallel
    stripes, near 0 for isotropic fields (spots on a square lattice, labyrinths, noise).
    A constant field has no direction: ``(nan, 0.0)``."""
    f = _field_2d(field)
    area, dx, dy, px, py, _ = _surface_frame(domain, f.shape)
    gx, gy = _periodic_gradients(f, dx, dy, px, py)
    w = area / area.sum()
    jxx, jyy, jxy = float((w * gx * gx).sum()), float((w * gy * gy).sum()), \
        float((w * gx * gy).sum())
    trace = jxx + jyy
    if trace <= 0.0:
        return float("nan"), 0.0
    coherence = float(np.hypot(jxx - jyy, 2.0 * jxy) / trace)
    normal = 0.5 * np.arctan2(2.0 * jxy, jxx - jyy)
    return float((normal + 0.5 * np.pi) % np.pi), min(coherence, 1.0)
