"""Analysis of reaction-diffusion models and their patterns.

* :func:`steady_state` — the homogeneous steady state ``R(x*) = 0`` of a model (Newton /
  Powell hybrid from the model's guess), :func:`jacobian` — ``∂R/∂x`` there, exact to
  round-off by the complex-step derivative (the reaction expressions are rational, so
  evaluating them with complex numbers is legitimate);
* :func:`dispersion` — the growth rate ``Re γ(k)`` of a Fourier mode of wavenumber ``k``:
  the largest real part of the eigenvalues of ``J − k² diag(D)`` (Quillen 2025, eq. 18).  On a
  grid the 5-point stencil's mode ``m`` of ``n`` cells has
  ``k = (2/dx) sin(π m / n)`` (:func:`grid_wavenumber`), not ``2π m/(n dx)``;
* :func:`classify_pattern` — ``"spots"``, ``"inverted-spots"``, ``"stripes"`` or
  ``"uniform"`` from the connected regions of the two phases of a field.

Parameters that are fields are replaced by their mean in the linear analysis.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from .boundary import PERIODIC
from .domains import Grid

__all__ = [
    "classify_pattern",
    "dispersion",
    "grid_wavenumber",
    "jacobian",
    "phase_components",
    "spiral_tips",
    "steady_state",
]


def _scalar_params(model: Any, params: Mapping[str, Any] | None) -> dict[str, float]:
    merged = {**model.defaults, **dict(params or {})}
    out = {}
    for k, v in merged.items():
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
    return out


def _rates(model: Any, x: Sequence[Any], params: dict[str, float], dtype) -> np.ndarray:
    r = model.rates([np.asarray(xi, dtype=dtype) for xi in x], params, dtype)
    return np.array([np.asarray(ri, dtype=dtype) for ri in r])


def jacobian(model: Any, params: Mapping[str, Any] | None, state: Sequence[float]) -> np.ndarray:
    """``J_ij = ∂R_i/∂x_j`` at ``state`` by the complex step (float64, exact to round-off)."""
    p = _scalar_params(model, params)
    x = np.asarray(state, dtype=np.float64)
    n = x.size
    h = 1e-30
    J = np.empty((n, n))
    for j in range(n):
        xc = x.astype(np.complex128)
        xc[j] += 1j * h
        J[:, j] = _rates(model, list(xc), p, np.complex128).imag / h
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


def dispersion(
    model: Any,
    params: Mapping[str, Any] | None,
    k: Any,
    *,
    state: Sequence[float] | None = None,
) -> np.ndarray:
    """Growth rate ``Re γ(k)``: the largest real part of the eigenvalues of
    ``J − k² diag(D)`` at the homogeneous steady state (or at ``state``), for each
    wavenumber in ``k`` (any shape; the result has the same shape)."""
    p = _scalar_params(model, params)
    x = steady_state(model, p) if state is None else np.asarray(state, dtype=np.float64)
    J = jacobian(model, p, x)
    D = np.diag(np.asarray(model.diffusion_coefficients(p), dtype=np.float64))
    k = np.asarray(k, dtype=np.float64)
    k2 = (k * k).reshape(-1, 1, 1)
    eig = np.linalg.eigvals(J[None, :, :] - k2 * D[None, :, :])
    return eig.real.max(axis=-1).reshape(k.shape)


def grid_wavenumber(m: Any, n: int, dx: float = 1.0) -> np.ndarray:
    """Wavenumber of Fourier mode ``m`` on ``n`` periodic cells as the 5-point stencil
    sees it: ``−Δ_h e^{2πimj/n} = k² e^{2πimj/n}`` with ``k = (2/dx)|sin(π m/n)|``."""
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
    threshold: float | None = 0.0,
    *,
    connected: float = 0.9,
    elongated: float = 6.0,
    min_size: int = 1,
    rtol: float = 1e-3,
    atol: float = 1e-12,
) -> str:
    """``"spots"``, ``"inverted-spots"``, ``"stripes"`` or ``"uniform"``.

    The field splits into a high phase (``> threshold``; ``threshold=None``: the midrange)
    and a low phase; their connected regions are found on the domain's graph
    (4-neighbours on a grid, wrapped across periodic boundaries; mesh edges on a
    :class:`~rdgpu.mesh.SurfaceMesh`; ``domain=None``: a non-periodic grid).  Components
    smaller than ``min_size`` points are ignored.  A phase is *connected* when its largest
    component holds at least ``connected`` (0.9) of it; a component is *elongated* when
    its elongation (:func:`phase_components`) exceeds ``elongated`` (6: longer than about
    twice its width; a round island gives 2 to 3.5).

    * ``uniform``: a phase is absent, or (``threshold=None``) the field's range is below
      ``max(rtol · max|field|, atol)``;
    * ``spots``: the high phase is connected and the low phase is not, and most of the low
      phase (by area) lies in compact islands — isolated islands of low values in a sea of
      high ones;
    * ``inverted-spots``: the reverse (compact islands of high values);
    * ``stripes``: everything else with both phases present — both connected (a labyrinth;
      also a single island of each), neither connected (several bands of each phase, e.g.
      parallel stripes on a periodic grid), or islands that are mostly elongated (worms in
      a connected background).
    """
    f = np.asarray(field.numpy() if hasattr(field, "numpy") else field, dtype=np.float64)
    if not np.isfinite(f).all():
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

    def compact(sizes, elong) -> bool:
        return float(sizes[elong <= elongated].sum()) > 0.5 * float(sizes.sum())

    if conn_hi and not conn_lo:
        return "spots" if compact(lo, comps["elongation_low"][keep_lo]) else "stripes"
    if conn_lo and not conn_hi:
        return "inverted-spots" if compact(hi, comps["elongation_high"][keep_hi]) \
            else "stripes"
    return "stripes"


# ---------------------------------------------------------------------------- spirals
def _wrapped(d: np.ndarray) -> np.ndarray:
    return (d + np.pi) % (2.0 * np.pi) - np.pi


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
        if domain is not None:
            theta = theta.reshape(domain.shape)
        px = domain is not None and domain.bcs.x.kind == PERIODIC
        py = domain is not None and domain.bcs.y.kind == PERIODIC
        t = theta
        if px:
            t = np.concatenate([t, t[:, :1]], axis=1)
        if py:
            t = np.concatenate([t, t[:1, :]], axis=0)
        c00, c01, c11, c10 = t[:-1, :-1], t[:-1, 1:], t[1:, 1:], t[1:, :-1]
        w = _wrapped(c01 - c00) + _wrapped(c11 - c01) + _wrapped(c10 - c11) + _wrapped(c00 - c10)
    else:
        f = np.asarray(domain.faces)
        t0, t1, t2 = theta.ravel()[f[:, 0]], theta.ravel()[f[:, 1]], theta.ravel()[f[:, 2]]
        w = _wrapped(t1 - t0) + _wrapped(t2 - t1) + _wrapped(t0 - t2)
    return int(np.count_nonzero(np.abs(w) > np.pi))
