"""The NumPy semantics of a `Program`: what one pass computes,
on host arrays, in the kernels' operation order (every backend's fused pass agrees with it
bit for bit where only ``+ − × ÷`` are used, and to a few ulps where a function is).

The Laplacians are those of `rdgpu.ir.stencils`: on grids the kernels' 3/5/7-point or
isotropic stencils, ghosts by `rdgpu.domains.boundary` (a Dirichlet ghost of a
``zero_ghost`` input is 0), on graph surfaces the metric operator of
``families/metric/reference.py``, on meshes the CSR rows of ``L`` in index order.  The
first derivatives (grids only) are `rdgpu.ir.stencils.derivative_text`'s differences of
the same ghosts, and the divergences (grids, compact stencil) `rdgpu.ir.stencils.
divergence_text`'s face fluxes.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from rdgpu.domains.boundary import WRAPPED
from rdgpu.families import load_module
from rdgpu.ir.boundary import OWN
from rdgpu.ir.equations import Diff, DivGrad, evaluate
from rdgpu.ir.layout import Layout
from rdgpu.ir.program import METRIC_COEFFICIENTS, PerMember, Program, literal
from rdgpu.ir.stencils import STENCIL_KINDS

__all__ = ["run_numpy"]


def _sides(p: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray]:
    """The low and high neighbours along ``axis`` of every cell of an array padded by one
    ghost layer on that axis (`grid_common.pad_axis`)."""
    n = p.shape[axis]
    return np.take(p, range(0, n - 2), axis=axis), np.take(p, range(2, n), axis=axis)


class _Padder:
    """Pads a grid field by one ghost layer along an axis, as the kernels resolve its
    ghosts: by the grid's condition (a ``zero_ghost`` input's Dirichlet ghost 0, an
    ``own_ghost`` one's the edge cell), or on a custom axis by the program's ghost
    expressions (`rdgpu.ir.boundary`) evaluated with ``env``."""

    def __init__(self, program: Program, layout: Layout, env: Mapping[str, Any]):
        self.program, self.layout, self.env = program, layout, env
        self.gc = load_module("", "grid_common.py")

    def __call__(self, name: str, u: np.ndarray, k: int) -> np.ndarray:
        """``u`` (``[members, nz, ny, nx]``) padded along axis ``k`` (0: x, 1: y, 2: z)."""
        gc, program = self.gc, self.program
        dom = self.layout.domain
        bc = (dom.bcs.x, dom.bcs.y, dom.bcs.z)[k]
        axis = 3 - k
        lo, hi = _LETTERS[k]
        if program.ghost(name, lo) is False:
            kind = bc.kind
            if name in program.own_ghost and kind == gc.DIRICHLET:
                kind = gc.NEUMANN
            return gc.pad_axis(u, axis, kind, 0.0 if name in program.zero_ghost else bc.value)
        p = gc.pad_axis(u, axis, self._load_kind(k), 0.0)
        dtype = u.dtype
        for letter, edge in ((lo, 0), (hi, -1)):
            rule = program.ghost(name, letter)
            if rule is None:
                continue
            if rule is OWN:
                ghost = np.take(u, [edge], axis=axis)
            else:
                with np.errstate(all="ignore"):
                    g = evaluate(rule, self.env, literal=lambda v: literal(v, dtype))
                g = np.broadcast_to(np.asarray(g, dtype=dtype), self.layout.field_shape)
                ghost = np.take(g.reshape(u.shape), [edge], axis=axis)
            index = [slice(None)] * p.ndim
            index[axis] = slice(0, 1) if edge == 0 else slice(p.shape[axis] - 1, None)
            p[tuple(index)] = ghost
        return p

    def _load_kind(self, k: int) -> int:
        """How the kernels load beyond the ends of axis ``k`` (0: x, 1: y, 2: z), as
        `grid_common.pad_axis` pads: wrapped on a periodic or `WRAPPED` axis, else
        clamped (Neumann)."""
        gc = self.gc
        b = self.program.kernel_bcs(self.layout.domain)
        kind = (b.x, b.y, b.z)[k].kind
        return gc.PERIODIC if kind in (gc.PERIODIC, WRAPPED) else gc.NEUMANN

    def sides(self, name: str, u: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        """The low and high neighbours of field ``name`` (``u``) along axis ``k``, ghosts
        resolved; with a mask, those outside it read as the cell's own value (`rdgpu.ir.
        stencils.neighbour_values`)."""
        lo, hi = _sides(self(name, u, k), 3 - k)
        mask = self.program.mask
        if mask is None:
            return lo, hi
        gc, t = self.gc, u.dtype.type
        kind = self._load_kind(k)
        m = _members4(np.broadcast_to(self.env[mask], self.layout.field_shape), self.layout)
        m = np.broadcast_to(m, u.shape)
        mlo, mhi = _sides(gc.pad_axis(np.ascontiguousarray(m), 3 - k, kind, 0.0), 3 - k)
        edges = []
        for letter in _LETTERS[k]:
            rule = self.program.mask_ghost(name, letter)
            if rule is None:
                edges.append(u)
                continue
            with np.errstate(all="ignore"):
                g = evaluate(rule, self.env, literal=lambda v: literal(v, u.dtype))
            edges.append(np.broadcast_to(np.asarray(g, dtype=u.dtype),
                                         self.layout.field_shape).reshape(u.shape))
        return (mlo * lo) + ((t(1) - mlo) * edges[0]), (mhi * hi) + ((t(1) - mhi) * edges[1])


#: the neighbour side letters of each axis (x, y, z), low then high
_LETTERS = (("w", "e"), ("s", "n"), ("b", "t"))


def _members4(a: np.ndarray, layout: Layout) -> np.ndarray:
    """``a`` as ``[members, nz, ny, nx]``."""
    return a.reshape(-1, *layout.domain.shape3)


def _grid_laplacian(name: str, a: np.ndarray, layout: Layout, pad: _Padder) -> np.ndarray:
    """The kernels' Laplacian of grid field ``name`` (value ``a``: one member's field or an
    ensemble's ``[members, *shape]``), ghosts by ``pad``."""
    d = layout.domain
    t = a.dtype.type
    u = _members4(a, layout)  # axis 0: the members
    if layout.stencil == "isotropic" and d.ndim > 1:
        p = u
        for k in range(d.ndim):
            p = pad(name, p, k)
        return np.stack([_isotropic_laplacian(u[m], p[m], d.ndim, d.dx, t)
                         for m in range(u.shape[0])]).reshape(a.shape)
    out = None
    for k, h in enumerate((d.dx, d.dy, d.dz)[:d.ndim]):
        lo, hi = pad.sides(name, u, k)
        term = ((hi + lo) - t(2) * u) * t(1.0 / (h * h))
        out = term if out is None else out + term
    return out.reshape(a.shape)


def _grid_derivative(a: np.ndarray, layout: Layout, d: Diff, pad: _Padder):
    """The kernels' first derivative ``d`` of a grid field (`rdgpu.ir.stencils.
    derivative_text`: ghosts by ``pad``); 0 along an absent axis."""
    dom = layout.domain
    t = a.dtype.type
    k = "xyz".index(d.axis)
    if k >= dom.ndim:
        return t(0)
    u = _members4(a, layout)
    h = t((dom.dx, dom.dy, dom.dz)[k])
    lo, hi = pad.sides(d.name, u, k)
    if d.side == 0:
        out = (hi - lo) / (t(2) * h)
    elif d.side == 2:
        out = ((hi + lo) - (t(2) * u)) / (h * h)
    elif d.side > 0:
        out = (hi - u) / h
    else:
        out = (u - lo) / h
    return out.reshape(a.shape)


def _grid_divergence(d: DivGrad, D: np.ndarray, a: np.ndarray, layout: Layout,
                     pad: _Padder) -> np.ndarray:
    """The kernels' ``div(D·grad a)`` (`rdgpu.ir.stencils.divergence_text`), ghosts by
    ``pad`` (``D``'s: the edge cell's own value at a Dirichlet side)."""
    dom = layout.domain
    t = a.dtype.type
    u = _members4(a, layout)
    c = np.broadcast_to(D, a.shape).reshape(u.shape)
    out = None
    for k, coef in enumerate(layout.grid_coefficients()[:dom.ndim]):
        lo, hi = pad.sides(d.name, u, k)
        dlo, dhi = pad.sides(d.coef.name, c, k)
        up = ((c + dhi) / t(2)) * (hi - u)
        down = ((dlo + c) / t(2)) * (u - lo)
        term = (up - down) * t(coef)
        out = term if out is None else out + term
    return out.reshape(a.shape)


def _mesh_divergence(D: np.ndarray, a: np.ndarray, layout: Layout) -> np.ndarray:
    """The kernels' ``div(D·grad a)`` on a mesh (`rdgpu.ir.stencils.mesh_divergence_text`):
    per row ``Σ_q L_iq·(((D_i + D_q)/2)·(a_q − a_i))`` in index order."""
    ref = load_module("mesh", "reference.py")
    L = layout.domain.laplacian
    n = layout.shape[0]
    t = a.dtype.type
    rows = np.repeat(np.arange(n), np.diff(L.indptr))
    data = L.data.astype(a.dtype, copy=False)
    c = np.broadcast_to(D, a.shape).reshape(-1, n)
    out = [ref._row_sums(L.indptr, data * (((d[rows] + d[L.indices]) / t(2))
                                           * (m[L.indices] - m[rows])), n, a.dtype)
           for d, m in zip(c, a.reshape(-1, n), strict=True)]
    return np.stack(out).reshape(a.shape)


def _isotropic_laplacian(u, p, nd: int, h: float, t) -> np.ndarray:
    """9-point (2-D) ``(4 Σ faces + Σ corners − 20 u)/(6h²)`` or 19-point (3-D) ``(2 Σ
    faces + Σ edges − 24 u)/(6h²)`` from ``p``, ``u`` padded x, then y, then z, so a
    diagonal ghost follows the outer axis's rule (z before y before x), as the kernels
    resolve them."""
    lo = 1 if nd > 2 else 0  # the z padding exists only in 3-D

    def at(dz, dy, dx):
        zs = slice(lo + dz, p.shape[0] - lo + dz if p.shape[0] - lo + dz else None) \
            if nd > 2 else slice(None)
        ys = slice(1 + dy, p.shape[1] - 1 + dy if p.shape[1] - 1 + dy else None)
        xs = slice(1 + dx, p.shape[2] - 1 + dx if p.shape[2] - 1 + dx else None)
        return p[zs, ys, xs]

    c6 = t(1.0 / (6.0 * h * h))
    faces = ((at(0, 0, -1) + at(0, 0, 1)) + at(0, -1, 0)) + at(0, 1, 0)
    corners = ((at(0, -1, -1) + at(0, -1, 1)) + at(0, 1, -1)) + at(0, 1, 1)
    if nd == 2:
        return ((t(4) * faces + corners) - t(20) * u) * c6
    faces = (faces + at(-1, 0, 0)) + at(1, 0, 0)
    edges = corners
    for pos in ((-1, 0, -1), (-1, 0, 1), (1, 0, -1), (1, 0, 1), (-1, -1, 0), (-1, 1, 0),
                (1, -1, 0), (1, 1, 0)):
        edges = edges + at(*pos)
    return ((t(2) * faces + edges) - t(24) * u) * c6


def run_numpy(program: Program, layout: Layout, inputs: Mapping[str, np.ndarray],
              params: Mapping[str, Any], scalars: Mapping[str, float],
              time: float) -> dict[str, np.ndarray]:
    """The reference of one launch on host arrays: ``{output name: array}``."""
    dtype = layout.dtype
    t = dtype.type
    mesh_ref = None if layout.is_grid else load_module("mesh", "reference.py")
    gc = load_module("", "grid_common.py")
    shape = layout.field_shape
    env: dict[str, Any] = {n: np.asarray(a, dtype=dtype).reshape(shape)
                           for n, a in inputs.items()}
    for p in program.refs("param"):
        v = params[p]
        if isinstance(v, PerMember):  # one number per member, broadcast over its cells
            env[p] = np.asarray(v.values, dtype=dtype).reshape(
                (layout.members,) + (1,) * len(layout.shape))
        else:
            env[p] = np.asarray(v, dtype=dtype) if isinstance(v, np.ndarray) else t(v)
    for b in program.refs("builtin"):
        env[b] = t(scalars[b])
    env["t"] = t(time)
    for c in program.refs("coord"):
        env[c] = layout.coordinate(c)
    env.update({k: t(v) for k, v in layout.lengths().items()})
    if layout.is_grid:  # a boundary ghost's spacings (rdgpu.ir.boundary.SPACING)
        env.update({f"_d{a}": t(h) for a, h in zip("xyz", layout.spacing(), strict=True)})
    pad = _Padder(program, layout, env) if layout.is_grid else None
    for name, expr in program.derived:
        with np.errstate(all="ignore"):
            env[name] = np.broadcast_to(np.asarray(
                evaluate(expr, env, literal=lambda v: literal(v, dtype)), dtype=dtype),
                shape)
    laps: dict[str, np.ndarray] = {}

    def lap(name: str, order: int) -> np.ndarray:
        if name not in laps:
            a = env[name]
            if STENCIL_KINDS[layout.kind].form == "metric":
                ref = load_module("metric", "reference.py")
                c = layout.domain.coefficients_as(dtype)
                laps[name] = ref.metric_laplacian(a, *(c[k] for k in METRIC_COEFFICIENTS))
            elif layout.is_grid:
                laps[name] = _grid_laplacian(name, a, layout, pad)
            else:
                L = layout.domain.laplacian
                n = layout.shape[0]
                laps[name] = np.stack([
                    mesh_ref._product(L.indptr, L.indices, L.data, m, n)
                    for m in a.reshape(-1, n)]).reshape(a.shape)
        return laps[name]

    diffs: dict[Diff, Any] = {}

    def diff(d: Diff):
        if d not in diffs:
            with np.errstate(all="ignore"):
                diffs[d] = _grid_derivative(env[d.name], layout, d, pad)
        return diffs[d]

    divs: dict[DivGrad, Any] = {}

    def div(d: DivGrad):
        if d not in divs:
            with np.errstate(all="ignore"):
                if layout.is_grid:
                    divs[d] = _grid_divergence(d, env[d.coef.name], env[d.name], layout,
                                               pad)
                else:
                    divs[d] = _mesh_divergence(env[d.coef.name], env[d.name], layout)
        return divs[d]

    out = {}
    for o in program.outputs:
        with np.errstate(all="ignore"):
            val = evaluate(o.expr, env, literal=lambda v: literal(v, dtype), lap=lap,
                           diff=diff, operator=div)
        val = np.broadcast_to(np.asarray(val, dtype=dtype), shape)
        lo, hi = o.bounds
        if lo is not None:
            val = np.where(val < t(lo), t(lo), val)
        if hi is not None:
            val = np.where(val > t(hi), t(hi), val)
        out[o.name] = gc.flush(val).astype(dtype, copy=False)
    return out
