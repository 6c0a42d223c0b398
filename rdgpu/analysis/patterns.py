"""Pattern classification: the connected regions of the two phases of a field
(`phase_components`) and the class they make (`classify_pattern`):
``"spots"``, ``"inverted-spots"``, ``"stripes"`` or ``"uniform"`` (optionally ``"mixed"``,
``"diverged"``), of one field or of each member of a stack."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.analysis.graph import as_array, graph_edges, is_grid

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain

__all__ = ["classify_pattern", "phase_components"]


def phase_components(
    field: Any, domain: Domain | None = None, threshold: float | None = 0.0
) -> dict[str, Any]:
    """Connected regions of the two phases ``high = field > threshold`` and
    ``low = field <= threshold`` (``threshold=None``: the midrange of the field).

    Parameters
    ----------
    field : array
        The field: ``[nx]`` or ``[ny, nx]`` on a grid or a graph surface (any array of
        that many values), one value per vertex on a `SurfaceMesh`; a device array
        (anything with ``numpy()``) is downloaded; read as float64.
    domain : Domain, optional
        The domain whose graph connects the points: a 1- or 2-D `Grid` (4-neighbours,
        wrapped along periodic axes), a graph surface (as its grid) or a `SurfaceMesh`
        (its edges); default None (a non-periodic grid of the field's shape).
    threshold : float or None, optional
        The value splitting the phases; default 0.0; None: ``(min + max)/2`` of the field.

    Returns
    -------
    dict
        ``threshold`` (float, the one used); ``fraction_high`` (float, the share of points
        in the high phase); ``high`` and ``low``: the sizes (points) of each phase's
        components, largest first; ``elongation_high`` / ``elongation_low``: per
        component (same order) ``size / (r + ½)²`` with ``r`` its inradius in graph steps
        (the largest number of edges from one of its points to the other phase, at least
        1; the ½ makes islands a point or two across come out compact): about π (less for
        small ones) for a round island, about 2π for a 2:1 ellipse, ``~4 L / w`` for a
        band of length ``L`` and width ``w``.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components, dijkstra

    f = as_array(field)
    if domain is not None and is_grid(domain):
        f = f.reshape(domain.kernel_shape)
    n = f.size
    if threshold is None:
        threshold = 0.5 * (float(f.min()) + float(f.max()))
    high = (f > threshold).ravel()
    a, b = graph_edges(domain, f.shape)
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
    domain: Domain | None = None,
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
    `SurfaceMesh`; ``domain=None``: a non-periodic grid).  Components
    smaller than ``min_size`` points are ignored.  A phase is *connected* when its largest
    component holds at least ``connected`` (0.9) of it; a component is *elongated* when
    its elongation (`phase_components`) exceeds ``elongated`` (6: longer than about
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

    Parameters
    ----------
    field : array
        The field (or a stack of them, see ``members``): ``[nx]`` or ``[ny, nx]`` on a
        grid or a graph surface (any array of that many values), one value per vertex on
        a `SurfaceMesh`; a device array (anything with ``numpy()``) is downloaded; read
        as float64.
    domain : Domain, optional
        The domain whose graph connects the points: a 1- or 2-D `Grid` (4-neighbours,
        wrapped along periodic axes), a graph surface (as its grid) or a `SurfaceMesh`
        (its edges); default None (a non-periodic grid of the field's shape).
    threshold : float or None, optional
        The value splitting the phases; default None (the midrange).
    connected : float, optional
        The share of a phase its largest component must hold for the phase to be
        connected; default 0.9.
    elongated : float, optional
        The elongation above which a component counts as elongated; default 6.
    min_size : int, optional
        Components with fewer points are ignored; default 1 (none).
    rtol, atol : float, optional
        With ``threshold=None``, a field whose range is at most
        ``max(rtol · max|field|, atol)`` is uniform; defaults ``1e-3`` and ``1e-12``.
    mixed : float or None, optional
        A fraction in (0, 0.5): report ``"mixed"`` when compact and elongated islands
        each hold more than it of the islands' area; default None (never ``"mixed"``).
    nonfinite : {"raise", "diverged"}, optional
        What a field holding NaN or Inf gives; default ``"raise"``.
    members : bool or None, optional
        True: ``field`` is a stack ``[M, *shape]``; False: one field; default None
        (a stack when ``domain`` is given and ``field.shape[1:]`` is its
        ``kernel_shape`` or its ``field_shape``: a 1-D grid's ``[M, 1, nx]`` or
        ``[M, nx]``).
    lone : float, optional
        A connected phase covering less than this share of the points counts as
        islands; default 0.25.

    Returns
    -------
    str or list of str
        The class, or one class per member of a stack.

    Raises
    ------
    ValueError
        ``nonfinite`` not ``"raise"`` or ``"diverged"``, ``mixed`` outside (0, 0.5), a
        field with NaN or Inf under ``nonfinite="raise"``, or ``members=True`` with a
        field of fewer than 2 dimensions.
    """
    if nonfinite not in ("raise", "diverged"):
        raise ValueError(f"nonfinite must be 'raise' or 'diverged', got {nonfinite!r}")
    if mixed is not None and not 0.0 < float(mixed) < 0.5:
        raise ValueError(f"mixed must be None or a fraction in (0, 0.5), got {mixed!r}")
    f = as_array(field)
    if members is None:  # a stack of fields as users or as the kernels hold them
        shapes = () if domain is None else {tuple(domain.kernel_shape),
                                            tuple(domain.field_shape)}
        members = f.shape not in shapes and any(
            f.ndim == len(s) + 1 and f.shape[1:] == s for s in shapes)
    opts = {"connected": connected, "elongated": elongated, "min_size": min_size,
            "rtol": rtol, "atol": atol, "mixed": mixed, "nonfinite": nonfinite, "lone": lone}
    if members:
        if f.ndim < 2:
            raise ValueError(f"members=True needs a stack [M, *shape], got shape {f.shape}")
        return [_classify_one(f[i], domain, threshold, **opts) for i in range(f.shape[0])]
    return _classify_one(f, domain, threshold, **opts)


def _classify_one(f: np.ndarray, domain: Domain | None, threshold: float | None, *,
                  connected: float, elongated: float, min_size: int, rtol: float,
                  atol: float, mixed: float | None, nonfinite: str, lone: float) -> str:
    """`classify_pattern` of one field."""
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

