"""Initial conditions: `initial_state` draws a run's first fields from an ``init``
spec (``uniform``, ``square``, ``spots``, ``patch``, ``halves``) on any domain.

Grids place seeds by cell index (periodic sides wrapped); unstructured domains
(`Domain.unstructured <rdgpu.domains.base.Domain.unstructured>`, a mesh) by vertex
position.  Random numbers come from ``numpy.random.default_rng(seed)`` in float64 on the
host, so the same seed gives the same fields on every backend.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.domains.base import is_domain
from rdgpu.domains.boundary import PERIODIC
from rdgpu.simulation.checks import init_spec, real, spots_count, unit_fractions

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain
    from rdgpu.domains.grid import Grid

__all__ = ["INIT_KINDS", "INIT_KEYS", "initial_state", "per_species"]

INIT_KINDS = ("uniform", "square", "spots", "patch", "halves")
INIT_KEYS = {
    "uniform": {"values", "noise"},
    "square": {"values", "inside", "size", "center", "noise"},
    "spots": {"values", "inside", "count", "radius", "noise"},
    "patch": {"values", "patch", "radius", "noise"},
    "halves": {"values", "x_low", "y_low", "z_low", "center", "noise"},
}



# ------------------------------------------------------------------------ initial state
def per_species(value: Any, species: tuple[str, ...], what: str, default: float) -> dict:
    if value is None:
        return dict.fromkeys(species, default)
    if isinstance(value, Mapping):
        unknown = set(value) - set(species)
        if unknown:
            raise ValueError(f"init {what!r} names unknown species {sorted(unknown)}; "
                             f"the model has {list(species)}")
        return {s: value.get(s, default) for s in species}
    return dict.fromkeys(species, value)


def _number(x: Any, what: str) -> float:
    return real(x, f"init {what}")


def _extent(domain: Domain) -> float:
    """The largest side of a grid (physical units) or of a mesh's bounding box."""
    if not domain.unstructured:
        return max(domain.lengths)
    V = np.asarray(domain.vertices)
    return float((V.max(axis=0) - V.min(axis=0)).max())


def _grid_axes(grid: Grid) -> list[tuple[int, float, Any]]:
    """``(cells, spacing, AxisBC)`` per axis of the kernels' shape: ``(y, x)`` or
    ``(z, y, x)``; the absent y axis of a 1-D grid has spacing 0 (it adds no distance)."""
    b = grid.bcs
    axes = [(grid.shape[-2], 0.0 if grid.ndim == 1 else grid.dy, b.y),
            (grid.shape[-1], grid.dx, b.x)]
    if grid.ndim == 3:
        axes.insert(0, (grid.shape[0], grid.dz, b.z))
    return axes


def _grid_distance(grid: Grid, centre: tuple[float, ...], *, cells: bool) -> np.ndarray:
    """Distance from ``centre`` (cell indices, one per axis of ``grid.shape``: ``(i, j)`` or
    ``(k, i, j)``) to every cell, wrapping periodic axes; in cells (``cells=True``) or in
    physical units."""
    d2: Any = 0.0
    for along, ((n, h, axis), c) in enumerate(zip(_grid_axes(grid), centre, strict=True)):
        k = np.abs(np.arange(n) - c)
        if axis.kind == PERIODIC:
            k = np.minimum(k, n - k)
        s = (1.0 if h else 0.0) if cells else h
        shape = [1] * len(grid.shape)
        shape[along] = -1
        d2 = d2 + ((k * s) ** 2).reshape(shape)
    return np.sqrt(d2)


def _centre(center: Any, n: int, what: str) -> tuple[float, ...]:
    """``center`` as ``n`` fractions of the sides: ``(y, x)`` (``n = 2``), or ``(z, y, x)``
    (``n = 3``, a 3-D grid), where a pair ``(y, x)`` puts z in the middle (so 2-D initial
    conditions carry over to 3-D grids); ``None`` is the middle of every side."""
    form = "(z, y, x) or (y, x)" if n == 3 else "(y, x)"
    if center is None:
        return (0.5,) * n
    try:
        values = [_number(c, "center") for c in center]
    except TypeError:
        raise ValueError(f"init {what} center is {form} fractions, got {center!r}") from None
    if n == 3 and len(values) == 2:
        values.insert(0, 0.5)
    if len(values) != n:
        raise ValueError(f"init {what} center is {form} fractions, got {center!r}")
    return tuple(values)


def _square_mask(domain: Domain, size: float, center: Any) -> np.ndarray:
    """A box of ``size`` times each side (a square in 2-D, a cube on a cubic 3-D grid)
    around ``center`` (fractions of the sides; mesh: a point, default the bounding-box
    centre)."""
    if not 0 < size <= 1:
        raise ValueError(f"init square size is a fraction of each side in (0, 1], got {size}")
    if not domain.unstructured:
        mask = np.zeros(domain.kernel_shape, dtype=bool)
        box = []
        fractions = _centre(center, len(domain.kernel_shape), "square")
        unit_fractions(fractions, "init square center")
        for n, c in zip(domain.kernel_shape, fractions, strict=True):
            half, mid = max(1, round(size * n / 2)), int(c * n)
            box.append(slice(max(mid - half, 0), mid + half))
        mask[tuple(box)] = True
        return mask
    V = np.asarray(domain.vertices)
    lo, hi = V.min(axis=0), V.max(axis=0)
    target = (lo + hi) / 2 if center is None else np.asarray(center, dtype=np.float64)
    c = V[int(np.argmin(((V - target) ** 2).sum(axis=1)))]
    half = size / 2 * (hi - lo)
    return (np.abs(V - c) <= half + 1e-12 * (hi - lo).max()).all(axis=1)


def _half_masks(domain: Domain, center: Any) -> dict[str, np.ndarray]:
    """``{"y_low": ..., "x_low": ...}`` (and ``"z_low"`` on a 3-D grid): the points with
    that coordinate below the fraction ``center`` of the domain -- grid rows, columns and
    planes; a mesh's bounding box, ``center = (y, x)``, default the middle."""
    n = 2 if domain.unstructured else len(domain.kernel_shape)
    fractions = _centre(center, n, "halves")
    if not all(0 <= c <= 1 for c in fractions):
        raise ValueError(f"init halves center is fractions in [0, 1], got {tuple(fractions)}")
    if not domain.unstructured:
        names = ("z_low", "y_low", "x_low")[-n:]
        index = np.indices(domain.kernel_shape, sparse=True)
        return {name: np.broadcast_to(i < c * cells, domain.kernel_shape) for name, i, c, cells
                in zip(names, index, fractions, domain.kernel_shape, strict=True)}
    V = np.asarray(domain.vertices, dtype=np.float64)
    lo, hi = V.min(axis=0), V.max(axis=0)
    cy, cx = fractions
    return {"y_low": V[:, 1] < lo[1] + cy * (hi[1] - lo[1]),
            "x_low": V[:, 0] < lo[0] + cx * (hi[0] - lo[0])}


def _ball_mask(domain: Domain, rng: np.random.Generator, count: int, radius: float,
               *, cells: bool) -> np.ndarray:
    """Union of ``count`` balls (discs in 2-D) around random cells/vertices; ``radius`` in
    cells (mesh: mean edge lengths) when ``cells``, else as a fraction of the domain
    extent.  Grid centres are drawn axis by axis, ``(y, x)`` or ``(z, y, x)``."""
    if not domain.unstructured:
        centres = [rng.integers(0, n, count) for n in domain.kernel_shape]
        r = radius if cells else radius * _extent(domain)
        mask = np.zeros(domain.kernel_shape, dtype=bool)
        for c in zip(*centres, strict=True):  # loop over spots, not cells
            mask |= _grid_distance(domain, tuple(float(i) for i in c), cells=cells) <= r
        return mask
    V = np.asarray(domain.vertices)
    centres = rng.integers(0, V.shape[0], count)
    r = radius * (domain.mean_edge_length if cells else _extent(domain))
    mask = np.zeros(V.shape[0], dtype=bool)
    for c in centres:
        mask |= ((V - V[c]) ** 2).sum(axis=1) <= r * r
    return mask


def _set_seed(fields: dict[str, np.ndarray], init: Mapping[str, Any], kind: str,
              domain: Domain, species: tuple[str, ...], rng: np.random.Generator) -> None:
    """Apply the ``inside`` values of a ``"square"`` or ``"spots"`` init to ``fields``
    (see `initial_state`)."""
    if kind == "square":
        mask = _square_mask(domain, _number(init.get("size", 0.1), "size"),
                            init.get("center"))
    else:
        # at most one spot per point when a count is given (the default draws 10)
        count = (spots_count(init["count"], math.prod(domain.kernel_shape)) if "count" in init
                 else 10)
        radius = _number(init.get("radius", 3), "radius")
        if radius <= 0:
            raise ValueError(f"init spots radius must be > 0, got {radius}")
        mask = _ball_mask(domain, rng, count, radius, cells=True)
    inside = init.get("inside")
    if inside is None:
        raise ValueError(f"init kind {kind!r} needs 'inside' values")
    inside = inside if isinstance(inside, Mapping) else dict.fromkeys(species, inside)
    for s, x in per_species(inside, species, "inside", None).items():
        if x is not None:
            fields[s][mask] = _number(x, f"inside value of {s!r}")


def _set_patch(fields: dict[str, np.ndarray], init: Mapping[str, Any], domain: Domain,
               species: tuple[str, ...], rng: np.random.Generator) -> None:
    """Apply a ``"patch"`` init to ``fields`` (see `initial_state`)."""
    radius = _number(init.get("radius", 0.3), "radius")
    if radius <= 0:
        raise ValueError(f"init patch radius must be > 0, got {radius}")
    mask = _ball_mask(domain, rng, 1, radius, cells=False)
    patch = init.get("patch", "random")
    patch = patch if isinstance(patch, Mapping) else dict.fromkeys(species, patch)
    n_in = int(mask.sum())
    for s, x in per_species(patch, species, "patch", None).items():
        if x is None:
            continue
        if isinstance(x, str):
            if x != "random":
                raise ValueError(f"init patch value of {s!r} must be a number, 'random' "
                                 f"or [lo, hi], got {x!r}")
            fields[s][mask] = rng.uniform(-1.0, 1.0, n_in)
        elif isinstance(x, (list, tuple)):
            lo, hi = (_number(b, f"patch range of {s!r}") for b in x)
            fields[s][mask] = rng.uniform(lo, hi, n_in)
        else:
            fields[s][mask] = _number(x, f"patch value of {s!r}")


def _set_halves(fields: dict[str, np.ndarray], init: Mapping[str, Any], domain: Domain,
                species: tuple[str, ...]) -> None:
    """Apply the ``y_low``, ``x_low`` (and on a 3-D grid ``z_low``) values of a
    ``"halves"`` init to ``fields`` (see `initial_state`)."""
    masks = _half_masks(domain, init.get("center"))
    if init.get("z_low") is not None and "z_low" not in masks:
        raise ValueError("init halves z_low needs a 3-D grid (nz, ny, nx); this domain has "
                         "no z axis")
    for key in ("z_low", "y_low", "x_low"):
        if key not in masks:
            continue
        for s, x in per_species(init.get(key), species, key, None).items():
            if x is not None:
                fields[s][masks[key]] = _number(x, f"{key} value of {s!r}")


def initial_state(
    init: Mapping[str, Any] | None,
    domain: Domain,
    species: tuple[str, ...] | list[str],
    seed: int = 0,
    dtype: Any = np.float64,
) -> dict[str, np.ndarray]:
    """Initial fields for ``species`` on ``domain`` (grid ``[ny, nx]`` -- ``[1, nx]`` in 1-D
    -- or ``[nz, ny, nx]``, mesh ``[n]``).

    Generated on the host in float64 with ``numpy.random.default_rng(seed)``, then cast to
    ``dtype``: the same seed gives the same fields whatever the backend.  ``init`` kinds:

    * ``{"kind": "uniform", "values": {"u": 1.0, "v": 0.0}, "noise": 0.05}``
    * ``{"kind": "square", "values": ..., "inside": {"u": 0.5, "v": 0.25}, "size": 0.1,
      "center": (0.5, 0.5)}`` -- a central square whose side is ``size`` times each side
      of the grid (``center`` in fractions of the sides); on a mesh, the vertices in an
      axis-aligned box of ``size`` times the bounding box around the vertex nearest the
      bounding-box centre (or ``center``, a point).
    * ``{"kind": "spots", "values": ..., "inside": ..., "count": 10, "radius": 3}`` --
      ``count`` discs of ``radius`` cells (mesh: mean edge lengths) around random cells or
      vertices; distances wrap across periodic grid sides.
    * ``{"kind": "patch", "values": {"u": 1.0}, "patch": {"u": "random"}, "radius": 0.3}``
      -- a localized patch (Dascal et al.): the cells/vertices within ``radius`` times the
      domain extent (largest side of the grid or of the mesh's bounding box, Euclidean
      distance) of a random cell/vertex take the patch values: a number, ``"random"``
      (uniform in [-1, 1] at each point) or ``[lo, hi]`` (uniform in [lo, hi]).
    * ``{"kind": "halves", "values": 0.0, "x_low": {"u": 1.0}, "y_low": {"v": 0.5},
      "center": (0.5, 0.5)}`` -- the species of ``x_low`` take its values where x is below
      the centre (grid columns; on a mesh the vertices' x coordinate, ``center`` in
      fractions of the bounding box, ``(y, x)``), those of ``y_low`` where y is below it:
      an excited half meeting a refractory half breaks a wave, the seed of spirals.

    On a 3-D grid ``(nz, ny, nx)`` every kind keeps its meaning with one more axis:
    ``square`` is a box of ``size`` times each side (a cube on a cubic grid), ``spots``
    are balls of ``radius`` cells, ``patch`` a ball of ``radius`` times the largest side
    (physical units, periodic axes wrapped), and ``halves`` cut along planes: ``x_low`` and
    ``y_low`` as in 2-D (so a 2-D spiral seed becomes a scroll-wave seed), plus ``z_low``
    (3-D only) below the z fraction, applied in the order ``z_low``, ``y_low``, ``x_low``
    (the later wins where they overlap).  ``center`` is ``(z, y, x)``, or ``(y, x)`` with
    z in the middle.  Random centres are drawn axis by axis, z first.

    ``values`` (everywhere; missing species are 0) and ``inside`` are per-species dicts or
    one number for all.  ``noise`` (a number or per-species dict) adds uniform noise in
    ``[-noise, noise]`` to every point of that species.  Random numbers are drawn in this
    order: positions, patch values, then noise species by species.
    """
    species = tuple(species)
    init = init_spec(init)
    kind = init.pop("kind", "uniform")
    if kind not in INIT_KEYS:
        raise ValueError(f"unknown init kind {kind!r}; allowed: {', '.join(INIT_KINDS)}")
    unknown = set(init) - INIT_KEYS[kind]
    if unknown:
        raise ValueError(f"unknown option(s) {sorted(unknown)} for init kind {kind!r}; "
                         f"allowed: {sorted(INIT_KEYS[kind])}")
    if not is_domain(domain):
        raise TypeError(f"domain must be a Grid or a SurfaceMesh, got {type(domain).__name__}")
    # built on the kernels' shape (a 1-D grid is one row; 3-D is (nz, ny, nx))
    shape = domain.kernel_shape
    rng = np.random.default_rng(seed)
    values = per_species(init.get("values"), species, "values", 0.0)
    fields = {s: np.full(shape, _number(values[s], f"value of {s!r}"), dtype=np.float64)
              for s in species}

    if kind in ("square", "spots"):
        _set_seed(fields, init, kind, domain, species, rng)
    elif kind == "patch":
        _set_patch(fields, init, domain, species, rng)
    elif kind == "halves":
        _set_halves(fields, init, domain, species)

    noise = per_species(init.get("noise", 0.0), species, "noise", 0.0)
    for s in species:
        a = _number(noise[s], f"noise of {s!r}")
        if a:
            fields[s] += a * rng.uniform(-1.0, 1.0, shape)
    dtype = np.dtype(dtype)
    return {s: np.ascontiguousarray(f.astype(dtype)) for s, f in fields.items()}

