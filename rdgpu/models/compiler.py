"""Equations → one fused kernel per backend (NumPy reference, Warp, OpenCL C).

A :class:`Program` says what one pass over the domain computes: the buffers it reads
(``inputs``, read at each cell and, where the expressions take their Laplacian, at its
neighbours), the parameter fields it reads, and one expression per output buffer.  A
time step of a model is such a program (``out_s = s + h·f_s``; see
:mod:`rdgpu.models.integrators` for the other forms); so is the pre-pass that stores
``laplace(s)`` for a bilaplacian.  Every cell reads each input once and writes each output
once: the stencils and the reaction in the same pass.

Domains (:class:`Target`):

* a 1-D, 2-D or 3-D :class:`~rdgpu.domains.Grid`: the 3-, 5- or 7-point Laplacian
  ``((e + w) − 2c)/dx² + ((n + s) − 2c)/dy² + ((t + b) − 2c)/dz²`` (terms of absent axes
  left out), ghosts by :mod:`rdgpu.domains.boundary` (a Dirichlet ghost of a stored
  ``laplace(s)`` is 0: the bilaplacian's "simply supported" condition ``Δs = 0``).
  ``x, y, z`` are cell centres ``(j + ½) dx`` (0 along absent axes);
* a :class:`~rdgpu.domains.graph_surface.GraphSurface` (kind ``grid2metric``): the periodic 9-point
  ``Δ_Γ`` of ``kernels/metric/reference.py`` in its operation order, its four coefficient
  arrays ``[ny, nx]`` shared by the ensemble members (read at the in-member cell);
* a :class:`~rdgpu.domains.mesh.SurfaceMesh`: ``laplace(s)_i = Σ_q L_iq s_q`` over the CSR row of
  ``L = A⁻¹W`` in index order; ``x, y, z`` are the vertex coordinates.

Kernel shapes follow the hand-written families: OpenCL one work-item per row (CPU: edge
columns peeled, a branch-free vectorisable interior) or strided columns (GPU); Warp one
thread per row in row chunks (CPU) or one per cell (CUDA); CSR rows in blocks.  Values are
emitted fully parenthesised in the tree's operation order with ``FP_CONTRACT OFF`` and
literals exact in the dtype, so the backends agree with the NumPy reference bit for bit
where only ``+ − × ÷`` are used, and to a few ulps where a function (``exp``, ``pow``...)
is.  Every written value is clamped (``bounds``) then flushed of subnormals.
"""

from __future__ import annotations

import hashlib
import importlib.util
import math
import os
import sys
import threading
import weakref
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rdgpu.backends.base import Backend, DeviceArray
from rdgpu.core.conventions import REAL_DTYPES as _REALS
from rdgpu.core.fpenv import flush_subnormals
from rdgpu.domains.graph_surface import GraphSurface
from rdgpu.domains.grid import Grid
from rdgpu.families import load_module, read_source
from rdgpu.ir.equations import Bin, Lap, Neg, Node, Num, Ref, evaluate, walk
from rdgpu.ir.names import flat_view, ident, split

__all__ = ["Output", "PerMember", "Program", "Target", "cache_dir", "launch"]


# ---------------------------------------------------------------------------- programs
@dataclass(frozen=True)
class Output:
    """One output buffer: the value ``expr`` clamped to ``bounds`` (None: no bound)."""

    name: str
    expr: Node
    bounds: tuple[float | None, float | None] = (None, None)


@dataclass(frozen=True, eq=False)
class Program:
    """One pass: read ``inputs`` (field buffers, by name), write ``outputs``.

    Names in the expressions: ``Ref("species", n)`` is input ``n`` at the cell,
    ``Lap(n)`` its Laplacian (``n`` an input; ``order`` must be 1), ``Ref("param", p)``
    a parameter (a field buffer or a scalar argument: decided per launch),
    ``Ref("builtin", b)`` a scalar argument (``_h``, ``_a``...), ``Ref("time", "t")``,
    ``Ref("coord", c)``, ``Ref("length", L)``.  ``zero_ghost``: inputs whose Dirichlet
    ghost is 0 instead of the grid's value."""

    inputs: tuple[str, ...]
    outputs: tuple[Output, ...]
    zero_ghost: frozenset[str] = frozenset()
    #: pointwise fields ``(name, expression of the inputs and scalar parameters)``, readable
    #: at the cell and through ``Lap(name)``: a neighbour's value is the expression of the
    #: inputs there (Dirichlet ghost: the grid's value)
    derived: tuple[tuple[str, Node], ...] = ()
    #: per-program caches (names, sources); programs compare by identity
    cache: dict = field(default_factory=dict, repr=False)

    def refs(self, kind: str) -> tuple[str, ...]:
        """The names of ``Ref``s of ``kind`` the outputs and derived fields use, sorted
        (cached)."""
        key = ("refs", kind)
        found = self.cache.get(key)
        if found is None:
            exprs = [o.expr for o in self.outputs] + [e for _, e in self.derived]
            found = tuple(sorted({n.name for e in exprs for n in walk(e)
                                  if isinstance(n, Ref) and n.kind == kind}))
            self.cache[key] = found
        return found

    @property
    def stencil_inputs(self) -> tuple[str, ...]:
        """Inputs and derived fields whose Laplacian is taken, in that order."""
        used = {n.name for o in self.outputs for n in walk(o.expr) if isinstance(n, Lap)}
        names = (*self.inputs, *(d for d, _ in self.derived))
        return tuple(s for s in names if s in used)

    def derived_expr(self, name: str) -> Node | None:
        return dict(self.derived).get(name)

    def check(self) -> None:
        for o in self.outputs:
            for n in walk(o.expr):
                known = (*self.inputs, *(d for d, _ in self.derived))
                if isinstance(n, Lap) and (n.order != 1 or n.name not in known):
                    raise ValueError(f"program reads laplace^{n.order}({n.name}): only "
                                     "first-order Laplacians of inputs")
                if isinstance(n, Ref) and n.kind == "species" and n.name not in self.inputs:
                    raise ValueError(f"program reads {n.name!r}, which is not an input")


@dataclass(frozen=True)
class PerMember:
    """A parameter with one number per ensemble member: ``values`` is a DeviceArray (or,
    for the NumPy reference, an array) of shape ``(members,)``."""

    values: Any


@dataclass
class Target:
    """A domain bound to a backend and dtype: what a launch needs besides the buffers.

    ``members`` > 1: an ensemble of that many copies of the domain, each buffer
    ``[members, *shape]`` (member-major), advanced side by side in one launch; no cell
    reads another member's cells."""

    domain: Any
    backend: Backend
    dtype: np.dtype
    csr: Any = None  # DeviceCSR of the mesh Laplacian
    #: grids: "compact" (3/5/7 points) or "isotropic" (9 points in 2-D, 19 in 3-D)
    stencil: str = "compact"
    coords: dict[str, Any] = field(default_factory=dict)  # mesh: "x" -> DeviceArray
    host: dict[str, Any] = field(default_factory=dict)  # cached host data (NumPy)
    members: int = 1
    #: graph surfaces: the metric coefficients ``ex, ny, bx, w`` (DeviceArrays ``[ny, nx]``)
    metric: tuple[Any, ...] = ()

    @classmethod
    def bind(cls, domain: Any, backend: Backend, dtype: Any,
             stencil: str = "compact", members: int = 1) -> Target:
        dtype = np.dtype(dtype)
        if dtype not in _REALS:
            raise TypeError(f"dtype must be float32 or float64, got {dtype}")
        check_stencil(domain, stencil)
        if int(members) < 1:
            raise ValueError(f"members must be >= 1, got {members}")
        t = cls(domain, backend, dtype, stencil=stencil, members=int(members))
        if isinstance(domain, GraphSurface):
            c = domain.coefficients_as(dtype)
            t.metric = tuple(backend.upload(c[k]) for k in METRIC_COEFFICIENTS)
        elif not isinstance(domain, Grid):
            t.csr = backend.upload_csr(domain.laplacian, dtype)
        return t

    @property
    def is_grid(self) -> bool:
        return isinstance(self.domain, Grid)

    @property
    def kind(self) -> str:
        """``grid1``..``grid3`` (``+ "iso"`` for the isotropic stencil), ``grid2metric`` (a
        graph surface) or ``mesh``."""
        if not self.is_grid:
            return "mesh"
        if isinstance(self.domain, GraphSurface):
            return "grid2metric"
        iso = self.stencil == "isotropic" and self.domain.ndim > 1
        return f"grid{self.domain.ndim}" + ("iso" if iso else "")

    @property
    def shape(self) -> tuple[int, ...]:
        """The domain's shape (one member's)."""
        return self.domain.shape if self.is_grid else (self.domain.n_vertices,)

    @property
    def field_shape(self) -> tuple[int, ...]:
        """A buffer's shape: ``(members, *shape)`` for an ensemble, else :attr:`shape`."""
        return (self.members, *self.shape) if self.members > 1 else self.shape

    def lengths(self) -> dict[str, float]:
        """``Lx, Ly, Lz``: the grid's extents (0 along absent axes), or the mesh's
        bounding box (cached)."""
        if "lengths" not in self.host:
            self.host["lengths"] = self._lengths()
        return self.host["lengths"]

    def _lengths(self) -> dict[str, float]:
        d = self.domain
        if self.is_grid:
            nz, ny, nx = d.shape3
            return {"Lx": nx * d.dx, "Ly": ny * d.dy if d.ndim > 1 else 0.0,
                    "Lz": nz * d.dz if d.ndim > 2 else 0.0}
        v = np.asarray(d.vertices, dtype=np.float64)
        ext = v.max(axis=0) - v.min(axis=0) if len(v) else np.zeros(3)
        return {"Lx": float(ext[0]), "Ly": float(ext[1]), "Lz": float(ext[2])}

    def spacing(self) -> tuple[float, float, float]:
        """``(dx, dy, dz)`` for coordinates: 0 along absent axes (so y = z = 0 in 1-D)."""
        d = self.domain
        return d.dx, (d.dy if d.ndim > 1 else 0.0), (d.dz if d.ndim > 2 else 0.0)

    def coordinate(self, name: str) -> np.ndarray:
        """Coordinate ``name`` of every cell/vertex, in the dtype, the kernels' way."""
        key = ("coord", name)
        if key not in self.host:
            t = self.dtype.type
            if self.is_grid:
                nz, ny, nx = self.domain.shape3
                axis = {"x": 2, "y": 1, "z": 0}[name]
                h = t(self.spacing()[{"x": 0, "y": 1, "z": 2}[name]])
                n = (nz, ny, nx)[axis]
                c = (np.arange(n).astype(self.dtype) + t(0.5)) * h
                shape = [1, 1, 1]
                shape[axis] = n
                full = np.broadcast_to(c.reshape(shape), (nz, ny, nx)).reshape(self.shape)
                self.host[key] = np.ascontiguousarray(full)
            else:
                k = {"x": 0, "y": 1, "z": 2}[name]
                self.host[key] = np.ascontiguousarray(
                    np.asarray(self.domain.vertices[:, k], dtype=self.dtype))
        return self.host[key]

    def device_coordinate(self, name: str) -> DeviceArray:
        if name not in self.coords:
            self.coords[name] = self.backend.upload(self.coordinate(name))
        return self.coords[name]


STENCILS = ("compact", "isotropic")
#: the metric coefficient arrays in the kernels' argument order (kernels/metric/reference.py)
METRIC_COEFFICIENTS = ("ex", "ny", "bx", "w")


def check_stencil(domain: Any, stencil: str) -> None:
    """``stencil`` is known, and an isotropic one has a uniform grid spacing."""
    if stencil not in STENCILS:
        raise ValueError(f"unknown stencil {stencil!r}; allowed: {', '.join(STENCILS)}")
    if stencil == "isotropic" and isinstance(domain, GraphSurface):
        raise ValueError("the isotropic stencil is a flat-grid stencil; a graph surface has "
                         "its own 9-point Laplace-Beltrami operator: use stencil='compact'")
    if stencil == "isotropic" and isinstance(domain, Grid) and domain.ndim > 1:
        hs = [domain.dx, domain.dy] + ([domain.dz] if domain.ndim > 2 else [])
        if max(hs) != min(hs):
            raise ValueError(f"the isotropic stencil needs equal spacings, got "
                             f"{', '.join(f'{h:g}' for h in hs)}")


def literal(v: float, dtype: np.dtype):
    """A literal rounded to the dtype, subnormals flushed to 0; refused if it overflows."""
    t = np.dtype(dtype).type
    with np.errstate(over="ignore"):
        out = t(flush_subnormals(np.asarray(v, dtype=t)))
    if math.isfinite(v) and not np.isfinite(out):
        raise ValueError(f"the number {v:g} does not fit {np.dtype(dtype).name}")
    return out


# ---------------------------------------------------------------------------- NumPy
def _grid_laplacian(a: np.ndarray, target: Target, zero: bool) -> np.ndarray:
    """The kernels' Laplacian of a grid field (ghosts by the bc; Dirichlet 0 if ``zero``);
    ``a`` is one member's field or an ensemble's ``[members, *shape]``."""
    gc = load_module("", "grid_common.py")
    d = target.domain
    t = a.dtype.type
    nz, ny, nx = d.shape3
    if target.stencil == "isotropic" and d.ndim > 1:
        axes = [(2, d.bcs.x, d.dx), (1, d.bcs.y, d.dy)] + (
            [(0, d.bcs.z, d.dz)] if d.ndim > 2 else [])
        members = a.reshape(-1, nz, ny, nx)
        return np.stack([_isotropic_laplacian(u, axes, zero, t) for u in members]
                        ).reshape(a.shape)
    u = a.reshape(-1, nz, ny, nx)  # axis 0: the members
    axes = [(3, d.bcs.x, d.dx)]
    if d.ndim > 1:
        axes.append((2, d.bcs.y, d.dy))
    if d.ndim > 2:
        axes.append((1, d.bcs.z, d.dz))
    out = None
    for axis, bc, h in axes:
        value = 0.0 if zero else bc.value
        p = gc.pad_axis(u, axis, bc.kind, value)
        lo = np.take(p, range(0, p.shape[axis] - 2), axis=axis)
        hi = np.take(p, range(2, p.shape[axis]), axis=axis)
        term = ((hi + lo) - t(2) * u) * t(1.0 / (h * h))
        out = term if out is None else out + term
    return out.reshape(a.shape)


def _isotropic_laplacian(u, axes, zero: bool, t) -> np.ndarray:
    """9-point (2-D) ``(4 Σ faces + Σ corners − 20 u)/(6h²)`` or 19-point (3-D) ``(2 Σ
    faces + Σ edges − 24 u)/(6h²)``; ghosts padded x, then y, then z, so a diagonal ghost
    follows the outer axis's rule (z before y before x), as the kernels resolve them."""
    gc = load_module("", "grid_common.py")
    p = u
    for axis, bc, _ in axes:
        p = gc.pad_axis(p, axis, bc.kind, 0.0 if zero else bc.value)
    nd = len(axes)
    lo = 1 if nd > 2 else 0  # the z padding exists only in 3-D

    def at(dz, dy, dx):
        zs = slice(lo + dz, p.shape[0] - lo + dz if p.shape[0] - lo + dz else None) \
            if nd > 2 else slice(None)
        ys = slice(1 + dy, p.shape[1] - 1 + dy if p.shape[1] - 1 + dy else None)
        xs = slice(1 + dx, p.shape[2] - 1 + dx if p.shape[2] - 1 + dx else None)
        return p[zs, ys, xs]

    h = axes[0][2]
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


def run_numpy(program: Program, target: Target, inputs: Mapping[str, np.ndarray],
              params: Mapping[str, Any], scalars: Mapping[str, float],
              time: float) -> dict[str, np.ndarray]:
    """The reference of one launch on host arrays: ``{output name: array}``."""
    dtype = target.dtype
    t = dtype.type
    mesh_ref = None if target.is_grid else load_module("mesh", "reference.py")
    gc = load_module("", "grid_common.py")
    shape = target.field_shape
    env: dict[str, Any] = {n: np.asarray(a, dtype=dtype).reshape(shape)
                           for n, a in inputs.items()}
    for p in program.refs("param"):
        v = params[p]
        if isinstance(v, PerMember):  # one number per member, broadcast over its cells
            env[p] = np.asarray(v.values, dtype=dtype).reshape(
                (target.members,) + (1,) * len(target.shape))
        else:
            env[p] = np.asarray(v, dtype=dtype) if isinstance(v, np.ndarray) else t(v)
    for b in program.refs("builtin"):
        env[b] = t(scalars[b])
    env["t"] = t(time)
    for c in program.refs("coord"):
        env[c] = target.coordinate(c)
    env.update({k: t(v) for k, v in target.lengths().items()})
    for name, expr in program.derived:
        with np.errstate(all="ignore"):
            env[name] = np.broadcast_to(np.asarray(
                evaluate(expr, env, literal=lambda v: literal(v, dtype)), dtype=dtype),
                shape)
    laps: dict[str, np.ndarray] = {}

    def lap(name: str, order: int) -> np.ndarray:
        if name not in laps:
            a = env[name]
            if target.kind == "grid2metric":
                ref = load_module("metric", "reference.py")
                c = target.domain.coefficients_as(dtype)
                laps[name] = ref.metric_laplacian(a, *(c[k] for k in METRIC_COEFFICIENTS))
            elif target.is_grid:
                laps[name] = _grid_laplacian(a, target, name in program.zero_ghost)
            else:
                L = target.domain.laplacian
                n = target.shape[0]
                laps[name] = np.stack([
                    mesh_ref._product(L.indptr, L.indices, L.data, m, n)
                    for m in a.reshape(-1, n)]).reshape(a.shape)
        return laps[name]

    out = {}
    for o in program.outputs:
        with np.errstate(all="ignore"):
            val = evaluate(o.expr, env, literal=lambda v: literal(v, dtype), lap=lap)
        val = np.broadcast_to(np.asarray(val, dtype=dtype), shape)
        lo, hi = o.bounds
        if lo is not None:
            val = np.where(val < t(lo), t(lo), val)
        if hi is not None:
            val = np.where(val > t(hi), t(hi), val)
        out[o.name] = gc.flush(val).astype(dtype, copy=False)
    return out


# ---------------------------------------------------------------------------- C-like emitters
def _emit(node: Node, name, lit, fn) -> str:
    """Fully parenthesised source: ``name(ref)``, ``lit(value)``, ``fn(call, args)``."""
    if isinstance(node, Num):
        return lit(node.value)
    if isinstance(node, (Ref, Lap)):
        return name(node)
    if isinstance(node, Bin):
        return f"({_emit(node.a, name, lit, fn)} {node.op} {_emit(node.b, name, lit, fn)})"
    if isinstance(node, Neg):
        return f"(-{_emit(node.a, name, lit, fn)})"
    return fn(node.fn, [_emit(a, name, lit, fn) for a in node.args])


def _var(node: Node, fields: frozenset[str]) -> str:
    """The local variable a kernel body uses for a Ref/Lap."""
    if isinstance(node, Lap):
        return ident("lap", node.name)
    if node.kind == "species":
        return ident("c", node.name)
    if node.kind == "param":
        return ident("f" if node.name in fields else "p", node.name)
    if node.kind == "builtin":
        return ident("b", node.name)
    if node.kind == "time":
        return "b_t"
    if node.kind == "coord":
        return f"{node.name}c"
    return f"len_{node.name[1]}"  # Lx -> len_x


def _signature(program: Program, fields: frozenset[str],
               member: frozenset[str] = frozenset()) -> list[tuple[str, str]]:
    """Buffer/scalar arguments in order: (kind, name) with kind in in/out/field/member/
    scalar (``member``: one number per member, read as ``_p_{name}``; rdgpu.ir.names)."""
    args = [("in", ident("in", s)) for s in program.inputs]
    args += [("out", ident("out", o.name)) for o in program.outputs]
    params = program.refs("param")
    args += [("field", ident("pf", p)) for p in params if p in fields]
    args += [("member", ident("pm", p)) for p in params if p in member]
    args += [("scalar", ident("p", p)) for p in params if p not in fields and p not in member]
    args += [("scalar", ident("b", b)) for b in program.refs("builtin")]
    args.append(("scalar", "b_t"))
    args += [("scalar", f"len_{n[1]}") for n in program.refs("length")]
    return args


# ---------------------------------------------------------------------------- stencils
#: neighbour positions: name -> ((dz, dy, dx), [(flag, ghost axis)] outer axis first)
_POSITIONS = {
    "w": ((0, 0, -1), [("w", "x")]), "e": ((0, 0, 1), [("e", "x")]),
    "s": ((0, -1, 0), [("s", "y")]), "n": ((0, 1, 0), [("n", "y")]),
    "b": ((-1, 0, 0), [("b", "z")]), "t": ((1, 0, 0), [("t", "z")]),
    "sw": ((0, -1, -1), [("s", "y"), ("w", "x")]), "se": ((0, -1, 1), [("s", "y"), ("e", "x")]),
    "nw": ((0, 1, -1), [("n", "y"), ("w", "x")]), "ne": ((0, 1, 1), [("n", "y"), ("e", "x")]),
    "bw": ((-1, 0, -1), [("b", "z"), ("w", "x")]), "be": ((-1, 0, 1), [("b", "z"), ("e", "x")]),
    "tw": ((1, 0, -1), [("t", "z"), ("w", "x")]), "te": ((1, 0, 1), [("t", "z"), ("e", "x")]),
    "bs": ((-1, -1, 0), [("b", "z"), ("s", "y")]), "bn": ((-1, 1, 0), [("b", "z"), ("n", "y")]),
    "ts": ((1, -1, 0), [("t", "z"), ("s", "y")]), "tn": ((1, 1, 0), [("t", "z"), ("n", "y")]),
}
_ROWS = {(0, 0): "r", (0, -1): "s", (0, 1): "n", (-1, 0): "b", (1, 0): "t",
         (-1, -1): "bs", (-1, 1): "bn", (1, -1): "ts", (1, 1): "tn"}


def _stencil_positions(kind: str) -> list[str]:
    nd = int(kind[4])
    names = ["w", "e"] + (["s", "n"] if nd > 1 else []) + (["b", "t"] if nd > 2 else [])
    if kind.endswith(("iso", "metric")):
        names += ["sw", "se", "nw", "ne"]
        if nd > 2:
            names += ["bw", "be", "tw", "te", "bs", "bn", "ts", "tn"]
    return names


def _laplacian_text(kind: str, s: str, num, flush: str = "FLUSH") -> str:
    """The Laplacian of field ``s`` from the position values ``q{pos}_{s}`` and ``c_{s}``,
    in the reference's operation order; ``num(v)`` writes a literal, ``flush`` names the
    subnormal flush (the metric operator flushes its result, as its reference)."""
    nd = int(kind[4])
    v = {p: ident("q" + p, s) for p in _stencil_positions(kind)}
    c = ident("c", s)
    if kind == "grid2metric":  # kernels/metric/reference.py, operation by operation
        def a(coef: str, pos: str, sign: str = "") -> str:
            return f"(m{coef}_ * ({v[pos]} - {c}))" if not sign else \
                f"(m{coef}_ * ({c} - {v[pos]}))"

        axial = (f"(({a('ex', 'e')} - {a('exw', 'w', '-')}) + "
                 f"({a('ny', 'n')} - {a('nys', 's', '-')}))")
        cross = (f"(({a('bx', 'ne')} + {a('bxsw', 'sw')}) - "
                 f"({a('bxs', 'se')} + {a('bxw', 'nw')}))")
        return f"{flush}(mw_ * ({axial} + {cross}))"
    if not kind.endswith("iso"):
        lap = f"(({v['e']} + {v['w']}) - {num(2)} * {c}) * cx"
        if nd > 1:
            lap = f"({lap} + (({v['n']} + {v['s']}) - {num(2)} * {c}) * cy)"
        if nd > 2:
            lap = f"({lap} + (({v['t']} + {v['b']}) - {num(2)} * {c}) * cz)"
        return lap

    def total(names):
        out = v[names[0]]
        for n in names[1:]:
            out = f"({out} + {v[n]})"
        return out

    corners = ["sw", "se", "nw", "ne"]
    if nd == 2:
        faces = total(["w", "e", "s", "n"])
        return f"((({num(4)} * {faces}) + {total(corners)}) - ({num(20)} * {c})) * cx"
    faces = total(["w", "e", "s", "n", "b", "t"])
    edges = total(corners + ["bw", "be", "tw", "te", "bs", "bn", "ts", "tn"])
    return f"((({num(2)} * {faces}) + {edges}) - ({num(24)} * {c})) * cx"


#: the metric coefficients a cell reads: local name -> (argument, row, column offset), the
#: row ``c`` (this cell's) or ``s`` (the south neighbour's), in the reference's notation
_METRIC_LOADS = {
    "ex": ("_me_ex", "c", 0), "exw": ("_me_ex", "c", -1), "ny": ("_me_ny", "c", 0),
    "nys": ("_me_ny", "s", 0), "bx": ("_me_bx", "c", 0), "bxsw": ("_me_bx", "s", -1),
    "bxs": ("_me_bx", "s", 0), "bxw": ("_me_bx", "c", -1), "w": ("_me_w", "c", 0),
}
#: the metric coefficient arguments, after the program's own (:func:`_signature`)
_METRIC_ARGS = tuple(ident("me", k) for k in METRIC_COEFFICIENTS)


def _metric_loads(kind: str, stencil: Sequence[str], load) -> list[str]:
    """The statements loading the metric coefficients of a cell (none unless ``kind`` is
    ``grid2metric`` and a Laplacian is taken): ``load(argument, row, dx)`` writes a load."""
    if kind != "grid2metric" or not stencil:
        return []
    return [f"m{name}_ = {load(arg, row, dx)}" for name, (arg, row, dx) in
            _METRIC_LOADS.items()]


def _neighbour_value(program: Program, s: str, load, fields, lit, fn) -> str:
    """Source of field ``s`` at a neighbour whose input ``i`` reads as ``load(i)``: the
    load itself, or a derived field's expression of the inputs there (both generators)."""
    expr = program.derived_expr(s)
    if expr is None:
        return load(s)
    return _emit(expr, lambda n: load(n.name) if isinstance(n, Ref) and n.kind == "species"
                 else _var(n, fields), lit, fn)


def _grid_coefficients(target: Target) -> tuple[float, float, float]:
    """``(cx, cy, cz)`` of the kernels: ``1/h²`` per axis (0 along absent axes), or
    ``1/(6h²)`` in ``cx`` for the isotropic stencils."""
    d = target.domain
    if target.kind.endswith("iso"):
        return 1.0 / (6.0 * d.dx * d.dx), 0.0, 0.0
    return (1.0 / d.dx**2, 1.0 / d.dy**2 if d.ndim > 1 else 0.0,
            1.0 / d.dz**2 if d.ndim > 2 else 0.0)


# ---------------------------------------------------------------------------- OpenCL
_CL_FUNCS = {"exp": "exp", "log": "log", "sqrt": "SQRT", "sin": "sin", "cos": "cos",
             "tan": "tan", "tanh": "tanh", "abs": "FABS", "pow": "pow", "min": "nanmin2",
             "max": "nanmax2"}


def opencl_source(program: Program, kind: str, fields: frozenset[str], dtype,
                  member: frozenset[str] = frozenset()) -> str:
    """The OpenCL C kernel ``rd_program`` (needs ``common.cl`` first); ``member``: the
    parameters given per ensemble member."""
    decl, body = opencl_cell(program, kind, fields, dtype, member)
    template = read_source("model", "model.cl")
    part = "MESH" if kind == "mesh" else "GRID"
    text = template[template.index(f"/*@{part}@*/"): template.index(f"/*@END {part}@*/")]
    coord_decl = "".join(f",\n        __global const real *RESTRICT coord_{c}"
                         for c in program.refs("coord"))
    row = _member_lines(member) if kind != "mesh" else []
    if kind == "grid2metric":  # the in-member offsets of this row and its south row
        row += ["const long mc_ = (long)i * nx;",
                "const long ms_ = (long)lo_index(i, ny, y_kind) * nx;",
                "(void)mc_; (void)ms_;"]
    return opencl_head(program) + (
        text.replace("@ARGS@", ",\n        ".join(decl))
        .replace("@COORDS@", coord_decl if kind == "mesh" else "")
        .replace("@ROW@", "\n".join("    " + r for r in row))
        .replace("@CELL@", " \\\n".join("        " + b for b in body))
        .replace("@BODY@", "\n".join("        " + b for b in body))
    )


def _member_lines(member: frozenset[str]) -> list[str]:
    """The statements reading the per-member parameters (grids: once per row)."""
    return [f"const real {ident('p', p)} = {ident('pm', p)}[m_];" for p in sorted(member)]


def opencl_head(program: Program) -> str:
    """The part of ``model.cl`` every generated OpenCL program starts with (its comment
    naming the outputs, the helper functions)."""
    template = read_source("model", "model.cl")
    comment = "\n".join(f" *   {o.name} = {_to_text(o.expr)}" for o in program.outputs)
    return template[: template.index("/*@GRID@*/")].replace("@OUTPUTS@", comment)


def opencl_cell(program: Program, kind: str, fields: frozenset[str], dtype,
                member: frozenset[str] = frozenset(), field_index: str = "k_",
                out_index: str = "k_") -> tuple[list[str], list[str]]:
    """``(arguments, statements)`` of one cell of ``program`` in OpenCL C: the kernel's
    argument declarations (:func:`_signature`'s order) and the cell body.  The body reads
    input ``s`` as ``in_s[k_]`` and its neighbours at the row offsets ``rc, rs, rn...``
    plus ``j``/``cc_.w``/``cc_.e``, parameter fields at ``[field_index]``, and stores
    output ``o`` to ``out_o[out_index]`` (the step kernel: all ``k_``)."""
    dtype = np.dtype(dtype)
    if dtype == np.float64:
        def lit(v):
            return f"({float(literal(v, dtype)).hex()})"
    else:
        def lit(v):
            return f"({float(literal(v, dtype)).hex()}f)"

    def fn(name, args):
        return f"{_CL_FUNCS[name]}({', '.join(args)})"

    decl = []
    for k, nm in _signature(program, fields, member):
        if k in ("in", "field", "member"):
            decl.append(f"__global const real *RESTRICT {nm}")
        elif k == "out":
            decl.append(f"__global real *RESTRICT {nm}")
        else:
            decl.append(f"const real {nm}")
    if kind == "grid2metric":
        decl += [f"__global const real *RESTRICT {nm}" for nm in _METRIC_ARGS]
    coords = program.refs("coord")
    body = _member_lines(member) if kind == "mesh" else []
    for p in program.refs("param"):
        if p in fields:
            body.append(f"const real {ident('f', p)} = {ident('pf', p)}[{field_index}];")
    if kind == "mesh":
        body += [f"const real {c}c = coord_{c}[v_];" for c in coords]
    elif "x" in coords:
        body.append("const real xc = ((real)(j) + (real)0.5) * dx;")
    body += [f"const real {ident('c', s)} = {ident('in', s)}[k_];" for s in program.inputs]
    for d, expr in program.derived:
        body.append(f"const real {ident('c', d)} = "
                    f"{_emit(expr, lambda n: _var(n, fields), lit, fn)};")
    stencil = program.stencil_inputs

    def at(s: str, load) -> str:
        return _neighbour_value(program, s, load, fields, lit, fn)

    if kind == "mesh":
        if stencil:
            body += [f"real {ident('lap', s)} = R0;" for s in stencil]
            body.append("for (int q_ = p0_; q_ < p1_; ++q_) {")
            body.append("    const real a_ = data[q_];")
            body.append("    const int j_ = indices[q_];")
            body += [f"    {ident('lap', s)} += a_ * "
                     f"{at(s, lambda i: ident('in', i) + '[moff_ + j_]')};" for s in stencil]
            body.append("}")
    else:
        col = {-1: "cc_.w", 0: "j", 1: "cc_.e"}
        flags = {"w": "cc_.w_dir", "e": "cc_.e_dir", "s": "ds", "n": "dn", "b": "db",
                 "t": "dt_"}
        loaded: set[tuple[str, str]] = set()
        for pos in _stencil_positions(kind):
            (dz, dy, dx), rule = _POSITIONS[pos]
            index = f"r{_ROWS[(dz, dy)].replace('r', '')}" if (dz, dy) != (0, 0) else "rc"
            index = f"{index} + {col[dx]}"

            def load(i, pos=pos, index=index):  # unconditional: indices are in range
                if (pos, i) not in loaded:
                    loaded.add((pos, i))
                    body.append(f"const real {ident(f'q{pos}0', i)} = "
                                f"{ident('in', i)}[{index}];")
                return ident(f"q{pos}0", i)

            for s in stencil:
                value = at(s, load)
                for flag, axis in reversed(rule):
                    g = "R0" if s in program.zero_ghost else f"g{axis}"
                    value = f"({flags[flag]} ? {g} : {value})"
                body.append(f"const real {ident('q' + pos, s)} = {value};")
        cols = {-1: "cc_.w", 0: "j"}
        body += [f"const real {ln};" for ln in _metric_loads(
            kind, stencil, lambda a, r, dx: f"{a}[m{r}_ + {cols[dx]}]")]
        for s in stencil:
            body.append(f"const real {ident('lap', s)} = "
                        f"{_laplacian_text(kind, s, lambda v: f'((real){v})')};")
    for i, o in enumerate(program.outputs):
        body.append(f"real o{i}_ = {_emit(o.expr, lambda n: _var(n, fields), lit, fn)};")
        lo, hi = o.bounds
        if lo is not None:
            body.append(f"o{i}_ = (o{i}_ < {lit(lo)}) ? {lit(lo)} : o{i}_;")
        if hi is not None:
            body.append(f"o{i}_ = (o{i}_ > {lit(hi)}) ? {lit(hi)} : o{i}_;")
        body.append(f"{ident('out', o.name)}[{out_index}] = FLUSH(o{i}_);")
    return decl, body


def _to_text(node: Node) -> str:
    from rdgpu.ir.equations import to_text

    return to_text(node)


_CL_LOCK = threading.Lock()
_CL_PROGRAMS: dict[tuple, Any] = {}


def opencl_kernel(program: Program, target: Target, fields: frozenset[str], name: str,
                  make, member: frozenset[str] = frozenset()) -> Any:
    """Kernel ``name`` of ``program`` for the target, cached in the program per context,
    build options, thread (a kernel's arguments are per object), domain kind, parameter
    fields (and per-member parameters) and dtype; ``make()`` builds it on a miss."""
    be = target.backend
    key = (name, be.context.int_ptr, tuple(be._options), threading.get_ident(),
           target.kind, fields, member, target.dtype.char)
    k = program.cache.get(key)
    if k is None:
        be._check_real(target.dtype)
        k = program.cache[key] = make()
    return k


def _opencl_kernel(program: Program, target: Target, fields: frozenset[str],
                   member: frozenset[str]):
    def make():
        skey = ("opencl source", target.kind, fields, member, target.dtype.char)
        src = program.cache.get(skey)
        if src is None:
            src = program.cache[skey] = opencl_source(program, target.kind, fields,
                                                      target.dtype, member)
        k = target.backend._cl.Kernel(opencl_program(target, src, "model/model.cl"),
                                      "rd_program")
        codes = opencl_arg_dtypes(program, fields, target.dtype, member)
        if target.kind == "mesh":
            codes = [None, None, None, *codes, np.int32, np.int32, np.int32,
                     *[None] * len(program.refs("coord"))]
        else:
            codes += [None] * len(target.metric)
            codes += [np.int32] * 4 + [np.int32, target.dtype] * 3 + [target.dtype] * 6
        k.set_scalar_arg_dtypes(codes)
        return k

    return opencl_kernel(program, target, fields, "rd_program", make, member)


def opencl_program(target: Target, src: str, name: str):
    """``common.cl`` + ``src`` built for the target's backend and dtype (cached per
    context, build options and source; ``name`` labels the source in compiler messages)."""
    be = target.backend
    pkey = (be.context.int_ptr, tuple(be._options), target.dtype.char, src)
    with _CL_LOCK:
        prog = _CL_PROGRAMS.get(pkey)
        if prog is None:
            options = [f"-D REAL_IS_DOUBLE={int(target.dtype == np.float64)}", *be._options]
            full = '#line 1 "common.cl"\n' + read_source("", "common.cl") + "\n"
            full += f'#line 1 "{name} (generated)"\n' + src
            prog = be._cl.Program(be.context, full).build(options=options)
            _CL_PROGRAMS[pkey] = prog
    return prog


def opencl_arg_dtypes(program: Program, fields: frozenset[str], dtype,
                      member: frozenset[str] = frozenset()) -> list:
    """pyopencl's scalar argument dtypes of :func:`_signature` (None for buffers)."""
    return [None if kk in ("in", "out", "field", "member") else np.dtype(dtype)
            for kk, _ in _signature(program, fields, member)]


def _launch_opencl(program, target, bufs, fields, member):
    be = target.backend
    k = _opencl_kernel(program, target, fields, member)
    if target.kind == "mesh":
        A = target.csr
        n = A.shape[0]
        if n == 0:
            return
        head = (A.indptr.handle, A.indices.handle, A.data.handle, *bufs)
        tail = (np.int32(n),
                *(target.device_coordinate(c).handle for c in program.refs("coord")))
        be._launch_rows(k, n * target.members, head, tail)
        return
    d = target.domain
    nz, ny, nx = d.shape3
    if nx == 0:
        return
    b = d.bcs
    dx, dy, dz = target.spacing()
    cx, cy, cz = _grid_coefficients(target)
    nm = target.members
    args = [*bufs, *(c.handle for c in target.metric), nx, ny, nz, nm, b.x.kind, b.x.value,
            b.y.kind, b.y.value, b.z.kind, b.z.value, cx, cy, cz, dx, dy, dz]
    be._launch_grid(k, ny * nz * nm, args)


# ---------------------------------------------------------------------------- Warp
_WP_FUNCS = {"exp": "wp.exp", "log": "wp.log", "sqrt": "wp.sqrt", "sin": "wp.sin",
             "cos": "wp.cos", "tan": "wp.tan", "tanh": "wp.tanh", "abs": "wp.abs",
             "pow": "wp.pow", "min": "nanmin2", "max": "nanmax2"}


def warp_source(program: Program, kind: str, fields: frozenset[str], dtype,
                member: frozenset[str] = frozenset()) -> str:
    """The text of a Warp module with the kernels of ``program`` (see
    ``kernels/model/warp_model.py.in``); ``member``: the parameters given per ensemble
    member (grids read them once per row, meshes once per vertex)."""
    dtype = np.dtype(dtype)
    lits: list[str] = []

    def lit(v):
        value = float(literal(v, dtype))
        lits.append(f"_c{len(lits)} = wp.constant(real({value!r}))")
        return f"_c{len(lits) - 1}"

    def fn(name, args):
        return f"{_WP_FUNCS[name]}({', '.join(args)})"

    sig = _signature(program, fields, member)
    if kind == "grid2metric":
        sig += [("field", nm) for nm in _METRIC_ARGS]
    array = "A" if kind == "mesh" else "A2"
    kdecl = ", ".join(f"{nm}: {array}" if k in ("in", "out", "field") else
                      f"{nm}: A" if k == "member" else f"{nm}: real" for k, nm in sig)
    member_loads = [f"{ident('p', split(nm)[1])} = {nm}[m_]" for k, nm in sig if k == "member"]
    buffers = [nm for k, nm in sig if k in ("in", "out", "field")]
    if kind == "mesh":  # the vertex function reads the member's numbers itself
        decl, names = kdecl, ", ".join(nm for _, nm in sig)
    else:  # the row's numbers are read by the kernel and passed to the cell functions, and
        # so are flat views of the grid buffers (the cells index them at row base + column)
        decl = ", ".join(f"{nm}: A" if k in ("in", "out", "field") else
                         f"{ident('p', split(nm)[1])}: real" if k == "member" else
                         f"{nm}: real" for k, nm in sig)
        names = ", ".join(ident("p", split(nm)[1]) if k == "member" else
                          flat_view(nm) if k in ("in", "out", "field") else nm for k, nm in sig)
    coords = program.refs("coord")
    stencil = program.stencil_inputs

    def cell_body(interior: bool) -> list[str]:
        """The cell's statements; ``interior``: no ghost can occur (no selects).  Grid
        buffers are flat views indexed ``row base + column`` (``r``, ``rs``, …: the flat
        indices of the first cells of the rows), mesh buffers 1-D."""
        at = "k_" if kind == "mesh" else "r + j"
        body = list(member_loads) if kind == "mesh" else []
        for p in program.refs("param"):
            if p in fields:
                body.append(f"{ident('f', p)} = {ident('pf', p)}[{at}]")
        if kind == "mesh":
            body += [f"{c}c = coord_{c}[v_]" for c in coords]
        elif "x" in coords:
            body.append("xc = (real(j) + real(0.5)) * dx")
        body += [f"{ident('c', s)} = {ident('in', s)}[{at}]" for s in program.inputs]
        for d, expr in program.derived:
            body.append(f"{ident('c', d)} = {_emit(expr, lambda n: _var(n, fields), lit, fn)}")

        def value(s: str, load) -> str:
            return _neighbour_value(program, s, load, fields, lit, fn)

        if kind == "mesh":
            if stencil:
                body += [f"{ident('lap', s)} = real(0.0)" for s in stencil]
                body.append("q_ = p0_")
                body.append("while q_ < p1_:")
                body.append("    a_ = data[q_]")
                body.append("    j_ = indices[q_] & NONNEG")
                body += [f"    {ident('lap', s)} += a_ * "
                         f"{value(s, lambda i: ident('in', i) + '[moff_ + j_]')}"
                         for s in stencil]
                body.append("    q_ += 1")
        else:
            col = {-1: "j - 1" if interior else "w", 0: "j", 1: "j + 1" if interior else "e"}
            flags = {"w": "wd", "e": "ed", "s": "ds", "n": "dn", "b": "db", "t": "dt_"}
            for pos in _stencil_positions(kind):
                (dz, dy, dx), rule = _POSITIONS[pos]
                row = _ROWS[(dz, dy)]
                index = f"{'r' if row == 'r' else 'r' + row} + {col[dx]}"
                for s in stencil:
                    v = value(s, lambda i, index=index: f"{ident('in', i)}[{index}]")
                    if not interior:
                        for flag, axis in reversed(rule):
                            g = "real(0.0)" if s in program.zero_ghost else f"g{axis}"
                            v = f"wp.where({flags[flag]}, {g}, {v})"
                    body.append(f"{ident('q' + pos, s)} = {v}")
            if kind == "grid2metric" and stencil:  # the coefficients' rows (one member's)
                body += ["mc_ = r % _me_w.shape[0]", "ms_ = rs % _me_w.shape[0]"]
            body += _metric_loads(kind, stencil,
                                  lambda a, r, dx: f"{a}[m{r}_ + {col[dx]}]")
            for s in stencil:
                lap = _laplacian_text(kind, s, lambda v: f"real({v}.0)", "flush")
                body.append(f"{ident('lap', s)} = {lap}")
        for i, o in enumerate(program.outputs):
            body.append(f"o{i}_ = {_emit(o.expr, lambda n: _var(n, fields), lit, fn)}")
            lo, hi = o.bounds
            if lo is not None:
                body.append(f"o{i}_ = wp.where(o{i}_ < {lit(lo)}, {lit(lo)}, o{i}_)")
            if hi is not None:
                body.append(f"o{i}_ = wp.where(o{i}_ > {lit(hi)}, {lit(hi)}, o{i}_)")
            body.append(f"{ident('out', o.name)}[{at}] = flush(o{i}_)")
        return body

    body = cell_body(False)
    inner = cell_body(True) if kind != "mesh" else []
    template = read_source("model", "warp_model.py.in")
    part = "MESH" if kind == "mesh" else "GRID"
    head = template[: template.index("# @GRID@")]
    text = template[template.index(f"# @{part}@"): template.index(f"# @END {part}@")]
    coord_decl = "".join(f", coord_{c}: A" for c in coords) if kind == "mesh" else ""
    coord_names = "".join(f", coord_{c}" for c in coords) if kind == "mesh" else ""
    return (
        head.replace("@DTYPE@", "float64" if dtype == np.float64 else "float32")
        .replace("@CONSTANTS@", "\n".join(lits))
        .replace("@OUTPUTS@", "\n".join(f"    {o.name} = {_to_text(o.expr)}"
                                          for o in program.outputs))
        + text.replace("@DECL@", decl + coord_decl).replace("@NAMES@", names + coord_names)
        .replace("@KDECL@", kdecl + coord_decl)
        .replace("@ROW@", "\n".join("    " + r for r in member_loads)
                 if kind != "mesh" else "")
        .replace("@FLAT@", "\n".join(f"    {flat_view(nm)} = flat({nm})" for nm in buffers)
                 if kind != "mesh" else "")
        .replace("@BODY@", "\n".join("    " + b for b in body))
        .replace("@INTERIOR@", "\n".join("    " + b for b in inner))
    )


def cache_dir() -> Path:
    """``$RDGPU_CACHE_DIR`` or ``~/.cache/rdgpu``: where generated Warp modules go."""
    root = os.environ.get("RDGPU_CACHE_DIR")
    return Path(root) if root else Path.home() / ".cache" / "rdgpu"


def _write_atomic(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.is_file() and path.read_text() == text:
        return
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


_WARP_LOCK = threading.Lock()
_WARP_MODULES: dict[str, Any] = {}
_WARP_LOADED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def warp_module(src: str, backend: Backend, prefix: str = "rdgpu_model"):
    """Import a generated Warp module (written under :func:`cache_dir`, since Warp needs a
    source file) and load it on the backend's device, once each."""
    digest = hashlib.sha256(src.encode()).hexdigest()[:24]
    with _WARP_LOCK:
        mod = _WARP_MODULES.get(digest)
        if mod is None:
            name = f"{prefix}_{digest}"
            path = cache_dir() / "warp" / f"{name}.py"
            _write_atomic(path, src)
            spec = importlib.util.spec_from_file_location(name, path)
            mod = importlib.util.module_from_spec(spec)
            sys.modules[name] = mod
            try:
                spec.loader.exec_module(mod)
            except BaseException:
                sys.modules.pop(name, None)
                raise
            mod._rdgpu_digest = digest
            _WARP_MODULES[digest] = mod
    loaded = _WARP_LOADED.setdefault(backend, set())
    if digest not in loaded:
        from rdgpu.backends.warp_backend import _WARP_LOCK as BACKEND_LOCK
        from rdgpu.backends.warp_backend import _quiet

        with BACKEND_LOCK, _quiet(backend._wp):
            backend._wp.load_module(mod, device=backend._dev)
        loaded.add(digest)
    return mod


def _launch_warp(program, target, bufs, fields, member):
    from rdgpu.backends.warp_backend import ROW_BLOCK, check_cells

    be = target.backend
    key = ("warp", str(be._dev), target.kind, fields, member, target.dtype.char)
    mod = program.cache.get(key)
    if mod is None:
        src = warp_source(program, target.kind, fields, target.dtype, member)
        mod = program.cache[key] = warp_module(src, be)
    nm = target.members
    if target.kind == "mesh":
        A = target.csr
        n = A.shape[0]
        if n == 0:
            return
        coords = [be._flat(target.device_coordinate(c)) for c in program.refs("coord")]
        args = [A.indptr.handle, A.indices.handle, A.data.handle, *bufs, *coords, n]
        rows = n * nm
        if be._cells:
            be._launch(mod.rows, rows, args, 0)
        else:
            be._run_split(mod.blocks, -(-rows // ROW_BLOCK), (A.nnz + n) * nm,
                          [*args, rows, ROW_BLOCK])
        return
    d = target.domain
    nz, ny, nx = d.shape3
    check_cells(nm * nz * ny * nx, (nm, nz, ny, nx))
    if nx == 0:
        return
    t = target.dtype.type
    b = d.bcs
    dx, dy, dz = target.spacing()
    cx, cy, cz = _grid_coefficients(target)
    args = [*bufs, *(_warp_rows(c) for c in target.metric), nx, ny, nz, nm, b.x.kind,
            t(b.x.value), b.y.kind, t(b.y.value), b.z.kind, t(b.z.value), t(cx), t(cy), t(cz),
            t(dx), t(dy), t(dz)]
    rows = ny * nz * nm
    if be._cells:
        be._launch(mod.cells, (rows, nx), args, 0)
    else:
        be._run_split(mod.rows, rows, rows * nx, args)


# ---------------------------------------------------------------------------- launch
def _handle(a: DeviceArray) -> Any:
    return a.handle


def _warp_rows(a: DeviceArray) -> Any:
    """A cached ``[rows, nx]`` 2-D view of a grid's Warp array (rows = nz·ny); the kernels
    index flat views of it (``warp_common.flat``)."""
    h = a.handle
    if h.ndim == 2:
        return h
    view = a.meta.get("warp_rows")
    if view is None or view._ref is not h:
        view = h.reshape((-1, a.shape[-1]))
        a.meta["warp_rows"] = view
    return view


def arguments(program: Program, target: Target, inputs: Sequence[DeviceArray],
              outputs: Sequence[DeviceArray], params: Mapping[str, Any],
              fields: frozenset[str], scalars: Mapping[str, float], time: float,
              flat=_handle, member: frozenset[str] = frozenset()) -> list[Any]:
    """The kernel arguments of :func:`_signature`: buffers through ``flat``, scalars in
    the target's dtype."""
    t = target.dtype.type
    bufs: list[Any] = [flat(a) for a in inputs] + [flat(a) for a in outputs]
    ps = program.refs("param")
    bufs += [flat(params[p]) for p in ps if p in fields]
    bufs += [params[p].values.handle for p in ps if p in member]
    bufs += [t(params[p]) for p in ps if p not in fields and p not in member]
    bufs += [t(scalars[b]) for b in program.refs("builtin")]
    bufs.append(t(time))
    lengths = target.lengths()
    bufs += [t(lengths[n]) for n in program.refs("length")]
    return bufs


def launch(program: Program, target: Target, inputs: Sequence[DeviceArray],
           outputs: Sequence[DeviceArray], params: Mapping[str, Any],
           scalars: Mapping[str, float], time: float = 0.0) -> None:
    """One pass of ``program`` on ``target``: ``inputs``/``outputs`` in the program's
    order, each of ``target.field_shape``; ``params`` maps each parameter to a number, a
    DeviceArray of ``target.field_shape`` (a field) or a :class:`PerMember`; ``scalars``
    the builtins (``_h``...)."""
    be = target.backend
    if len(inputs) != len(program.inputs) or len(outputs) != len(program.outputs):
        raise ValueError("inputs/outputs do not match the program")
    fields = frozenset(p for p in program.refs("param") if isinstance(params[p], DeviceArray))
    member = frozenset(p for p in program.refs("param") if isinstance(params[p], PerMember))

    def host_value(v: Any, get) -> Any:
        if isinstance(v, PerMember):
            return PerMember(get(v.values))
        return get(v) if isinstance(v, DeviceArray) else v

    if be.name == "numpy":
        host = {n: a.handle for n, a in zip(program.inputs, inputs, strict=True)}
        pv = {p: host_value(v, lambda a: a.handle) for p, v in params.items()
              if p in program.refs("param")}
        res = run_numpy(program, target, host, pv, scalars, time)
        for o, buf in zip(program.outputs, outputs, strict=True):
            buf.handle[...] = res[o.name].reshape(buf.shape)
        return
    if be.name == "warp":
        flat = be._flat if target.kind == "mesh" else _warp_rows
    else:
        flat = _handle
    bufs = arguments(program, target, inputs, outputs, params, fields, scalars, time, flat,
                     member)
    if be.name == "warp":
        _launch_warp(program, target, bufs, fields, member)
    elif be.name == "opencl":
        _launch_opencl(program, target, bufs, fields, member)
    else:  # any other backend: through the host
        host = {n: a.numpy() for n, a in zip(program.inputs, inputs, strict=True)}
        pv = {p: host_value(v, lambda a: a.numpy()) for p, v in params.items()}
        res = run_numpy(program, target, host, pv, scalars, time)
        for o, buf in zip(program.outputs, outputs, strict=True):
            be.copy(be.upload(np.ascontiguousarray(res[o.name].reshape(buf.shape))), buf)

