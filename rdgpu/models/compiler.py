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
  left out), ghosts by :mod:`rdgpu.boundary` (a Dirichlet ghost of a stored
  ``laplace(s)`` is 0: the bilaplacian's "simply supported" condition ``Δs = 0``).
  ``x, y, z`` are cell centres ``(j + ½) dx`` (0 along absent axes);
* a :class:`~rdgpu.mesh.SurfaceMesh`: ``laplace(s)_i = Σ_q L_iq s_q`` over the CSR row of
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
import sys
import threading
import weakref
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..backends.base import Backend, DeviceArray
from ..domains import Grid
from ..fpenv import flush_subnormals
from ..kernel_files import load_module, read_source
from .equations import Bin, Lap, Neg, Node, Num, Ref, evaluate, walk

__all__ = ["Output", "Program", "Target", "launch"]

_REALS = (np.dtype(np.float32), np.dtype(np.float64))


# ---------------------------------------------------------------------------- programs
@dataclass(frozen=True)
class Output:
    """One output buffer: the value ``expr`` clamped to ``bounds`` (None: no bound)."""

    name: str
    expr: Node
    bounds: tuple[float | None, float | None] = (None, None)


@dataclass(frozen=True)
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

    def refs(self, kind: str) -> tuple[str, ...]:
        found = {n.name for o in self.outputs for n in walk(o.expr)
                 if isinstance(n, Ref) and n.kind == kind}
        return tuple(sorted(found))

    @property
    def stencil_inputs(self) -> tuple[str, ...]:
        """Inputs whose Laplacian is taken, in input order."""
        used = {n.name for o in self.outputs for n in walk(o.expr) if isinstance(n, Lap)}
        return tuple(s for s in self.inputs if s in used)

    def check(self) -> None:
        for o in self.outputs:
            for n in walk(o.expr):
                if isinstance(n, Lap) and (n.order != 1 or n.name not in self.inputs):
                    raise ValueError(f"program reads laplace^{n.order}({n.name}): only "
                                     "first-order Laplacians of inputs")
                if isinstance(n, Ref) and n.kind == "species" and n.name not in self.inputs:
                    raise ValueError(f"program reads {n.name!r}, which is not an input")


@dataclass
class Target:
    """A domain bound to a backend and dtype: what a launch needs besides the buffers."""

    domain: Any
    backend: Backend
    dtype: np.dtype
    csr: Any = None  # DeviceCSR of the mesh Laplacian
    coords: dict[str, Any] = field(default_factory=dict)  # mesh: "x" -> DeviceArray
    host: dict[str, Any] = field(default_factory=dict)  # cached host data (NumPy)

    @classmethod
    def bind(cls, domain: Any, backend: Backend, dtype: Any) -> Target:
        dtype = np.dtype(dtype)
        if dtype not in _REALS:
            raise TypeError(f"dtype must be float32 or float64, got {dtype}")
        t = cls(domain, backend, dtype)
        if not isinstance(domain, Grid):
            t.csr = backend.upload_csr(domain.laplacian, dtype)
        return t

    @property
    def is_grid(self) -> bool:
        return isinstance(self.domain, Grid)

    @property
    def kind(self) -> str:
        return f"grid{self.domain.ndim}" if self.is_grid else "mesh"

    @property
    def shape(self) -> tuple[int, ...]:
        return self.domain.shape if self.is_grid else (self.domain.n_vertices,)

    def lengths(self) -> dict[str, float]:
        """``Lx, Ly, Lz``: the grid's extents (0 along absent axes), or the mesh's
        bounding box."""
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


def literal(v: float, dtype: np.dtype):
    """A literal rounded to the dtype, subnormals flushed to 0."""
    t = np.dtype(dtype).type
    return t(flush_subnormals(np.asarray(v, dtype=t)))


# ---------------------------------------------------------------------------- NumPy
def _grid_laplacian(a: np.ndarray, target: Target, zero: bool) -> np.ndarray:
    """The kernels' Laplacian of a grid field (ghosts by the bc; Dirichlet 0 if ``zero``)."""
    gc = load_module("", "grid_common.py")
    d = target.domain
    t = a.dtype.type
    nz, ny, nx = d.shape3
    u = a.reshape(nz, ny, nx)
    axes = [(2, d.bcs.x, d.dx)]
    if d.ndim > 1:
        axes.append((1, d.bcs.y, d.dy))
    if d.ndim > 2:
        axes.append((0, d.bcs.z, d.dz))
    out = None
    for axis, bc, h in axes:
        value = 0.0 if zero else bc.value
        p = gc.pad_axis(u, axis, bc.kind, value)
        lo = np.take(p, range(0, p.shape[axis] - 2), axis=axis)
        hi = np.take(p, range(2, p.shape[axis]), axis=axis)
        term = ((hi + lo) - t(2) * u) * t(1.0 / (h * h))
        out = term if out is None else out + term
    return out.reshape(a.shape)


def run_numpy(program: Program, target: Target, inputs: Mapping[str, np.ndarray],
              params: Mapping[str, Any], scalars: Mapping[str, float],
              time: float) -> dict[str, np.ndarray]:
    """The reference of one launch on host arrays: ``{output name: array}``."""
    dtype = target.dtype
    t = dtype.type
    mesh_ref = None if target.is_grid else load_module("mesh", "reference.py")
    gc = load_module("", "grid_common.py")
    env: dict[str, Any] = {n: np.asarray(a, dtype=dtype) for n, a in inputs.items()}
    for p in program.refs("param"):
        v = params[p]
        env[p] = np.asarray(v, dtype=dtype) if isinstance(v, np.ndarray) else t(v)
    for b in program.refs("builtin"):
        env[b] = t(scalars[b])
    env["t"] = t(time)
    for c in program.refs("coord"):
        env[c] = target.coordinate(c)
    env.update({k: t(v) for k, v in target.lengths().items()})
    laps: dict[str, np.ndarray] = {}

    def lap(name: str, order: int) -> np.ndarray:
        if name not in laps:
            a = env[name]
            if target.is_grid:
                laps[name] = _grid_laplacian(a, target, name in program.zero_ghost)
            else:
                L = target.domain.laplacian
                laps[name] = mesh_ref._product(L.indptr, L.indices, L.data, a, a.shape[0])
        return laps[name]

    out = {}
    for o in program.outputs:
        with np.errstate(all="ignore"):
            val = evaluate(o.expr, env, literal=lambda v: literal(v, dtype), lap=lap)
        val = np.broadcast_to(np.asarray(val, dtype=dtype), target.shape)
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
        return f"L_{node.name}"
    if node.kind == "species":
        return f"c_{node.name}"
    if node.kind == "param":
        return f"f_{node.name}" if node.name in fields else f"p_{node.name}"
    if node.kind == "builtin":
        return f"b{node.name}"
    if node.kind == "time":
        return "b_t"
    if node.kind == "coord":
        return f"{node.name}c"
    return f"len_{node.name[1]}"  # Lx -> len_x


def _signature(program: Program, fields: frozenset[str]) -> list[tuple[str, str]]:
    """Buffer/scalar arguments in order: (kind, name) with kind in in/out/field/coord/
    scalar."""
    args = [("in", f"in_{s}") for s in program.inputs]
    args += [("out", f"out_{o.name}") for o in program.outputs]
    params = program.refs("param")
    args += [("field", f"pf_{p}") for p in params if p in fields]
    args += [("scalar", f"p_{p}") for p in params if p not in fields]
    args += [("scalar", f"b{b}") for b in program.refs("builtin")]
    args.append(("scalar", "b_t"))
    args += [("scalar", f"len_{n[1]}") for n in program.refs("length")]
    return args


# ---------------------------------------------------------------------------- OpenCL
_CL_FUNCS = {"exp": "exp", "log": "log", "sqrt": "SQRT", "sin": "sin", "cos": "cos",
             "tan": "tan", "tanh": "tanh", "abs": "FABS", "pow": "pow", "min": "nanmin2",
             "max": "nanmax2"}


def opencl_source(program: Program, kind: str, fields: frozenset[str], dtype) -> str:
    """The OpenCL C kernel ``rd_program`` (needs ``common.cl`` first)."""
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
    for k, nm in _signature(program, fields):
        if k in ("in", "field"):
            decl.append(f"__global const real *RESTRICT {nm}")
        elif k == "out":
            decl.append(f"__global real *RESTRICT {nm}")
        else:
            decl.append(f"const real {nm}")
    coords = program.refs("coord")
    body = []
    for p in program.refs("param"):
        if p in fields:
            body.append(f"const real f_{p} = pf_{p}[k_];")
    if kind == "mesh":
        body += [f"const real {c}c = coord_{c}[k_];" for c in coords]
    elif "x" in coords:
        body.append("const real xc = ((real)(j) + (real)0.5) * dx;")
    body += [f"const real c_{s} = in_{s}[k_];" for s in program.inputs]
    stencil = program.stencil_inputs
    if kind == "mesh":
        if stencil:
            body += [f"real L_{s} = R0;" for s in stencil]
            body.append("for (int q_ = p0_; q_ < p1_; ++q_) {")
            body.append("    const real a_ = data[q_];")
            body.append("    const int j_ = indices[q_];")
            body += [f"    L_{s} += a_ * in_{s}[j_];" for s in stencil]
            body.append("}")
    else:
        nd = int(kind[-1])
        for s in stencil:
            gxs = "R0" if s in program.zero_ghost else "gx"
            gys = "R0" if s in program.zero_ghost else "gy"
            gzs = "R0" if s in program.zero_ghost else "gz"
            body.append(f"const real w0_{s} = in_{s}[rc + cc_.w], e0_{s} = in_{s}[rc + cc_.e];")
            body.append(f"const real w_{s} = cc_.w_dir ? {gxs} : w0_{s};")
            body.append(f"const real e_{s} = cc_.e_dir ? {gxs} : e0_{s};")
            lap = f"((e_{s} + w_{s}) - R2 * c_{s}) * cx"
            if nd > 1:
                body.append(f"const real s0_{s} = in_{s}[rs + j], n0_{s} = in_{s}[rn + j];")
                body.append(f"const real s_{s} = ds ? {gys} : s0_{s};")
                body.append(f"const real n_{s} = dn ? {gys} : n0_{s};")
                lap = f"({lap} + ((n_{s} + s_{s}) - R2 * c_{s}) * cy)"
            if nd > 2:
                # zb_/zt_, not b_: b_h, b_a, b_b are the builtins' arguments
                body.append(f"const real zb0_{s} = in_{s}[rb + j], zt0_{s} = in_{s}[rt + j];")
                body.append(f"const real zb_{s} = db ? {gzs} : zb0_{s};")
                body.append(f"const real zt_{s} = dt_ ? {gzs} : zt0_{s};")
                lap = f"({lap} + ((zt_{s} + zb_{s}) - R2 * c_{s}) * cz)"
            body.append(f"const real L_{s} = {lap};")
    for i, o in enumerate(program.outputs):
        body.append(f"real o{i}_ = {_emit(o.expr, lambda n: _var(n, fields), lit, fn)};")
        lo, hi = o.bounds
        if lo is not None:
            body.append(f"o{i}_ = (o{i}_ < {lit(lo)}) ? {lit(lo)} : o{i}_;")
        if hi is not None:
            body.append(f"o{i}_ = (o{i}_ > {lit(hi)}) ? {lit(hi)} : o{i}_;")
        body.append(f"out_{o.name}[k_] = FLUSH(o{i}_);")
    template = read_source("model", "model.cl")
    part = "MESH" if kind == "mesh" else "GRID"
    head = template[: template.index("/*@GRID@*/")]
    text = template[template.index(f"/*@{part}@*/"): template.index(f"/*@END {part}@*/")]
    comment = "\n".join(f" *   {o.name} = {_to_text(o.expr)}" for o in program.outputs)
    coord_decl = "".join(f",\n        __global const real *RESTRICT coord_{c}" for c in coords)
    return head.replace("@OUTPUTS@", comment) + (
        text.replace("@ARGS@", ",\n        ".join(decl))
        .replace("@COORDS@", coord_decl if kind == "mesh" else "")
        .replace("@CELL@", " \\\n".join("        " + b for b in body))
        .replace("@BODY@", "\n".join("        " + b for b in body))
    )


def _to_text(node: Node) -> str:
    from .equations import to_text

    return to_text(node)


_CL_LOCK = threading.Lock()
_CL_PROGRAMS: dict[tuple, Any] = {}


def _opencl_kernel(program: Program, target: Target, fields: frozenset[str]):
    be = target.backend
    key = (program, target.kind, fields, target.dtype.char)
    try:
        mine = be._local.model_kernels
    except AttributeError:
        mine = be._local.model_kernels = {}
    k = mine.get(key)
    if k is not None:
        return k
    be._check_real(target.dtype)
    src = opencl_source(program, target.kind, fields, target.dtype)
    pkey = (be.context.int_ptr, tuple(be._options), target.dtype.char, src)
    with _CL_LOCK:
        prog = _CL_PROGRAMS.get(pkey)
        if prog is None:
            cl = be._cl
            options = [f"-D REAL_IS_DOUBLE={int(target.dtype == np.float64)}", *be._options]
            full = '#line 1 "common.cl"\n' + read_source("", "common.cl") + "\n"
            full += '#line 1 "model/model.cl (generated)"\n' + src
            prog = cl.Program(be.context, full).build(options=options)
            _CL_PROGRAMS[pkey] = prog
    k = be._cl.Kernel(prog, "rd_program")
    codes = [None if kk in ("in", "out", "field") else target.dtype
             for kk, _ in _signature(program, fields)]
    if target.kind == "mesh":
        codes = [None, None, None, *codes, np.int32, np.int32,
                 *[None] * len(program.refs("coord"))]
    else:
        codes += [np.int32] * 3 + [np.int32, target.dtype] * 3 + [target.dtype] * 6
    k.set_scalar_arg_dtypes(codes)
    mine[key] = k
    return k


def _launch_opencl(program, target, bufs, fields, scalars):
    be = target.backend
    k = _opencl_kernel(program, target, fields)
    if target.kind == "mesh":
        A = target.csr
        head = (A.indptr.handle, A.indices.handle, A.data.handle, *bufs)
        tail = tuple(target.device_coordinate(c).handle for c in program.refs("coord"))
        be._launch_rows(k, A.shape[0], head, tail)
        return
    d = target.domain
    nz, ny, nx = d.shape3
    if nx == 0:
        return
    b = d.bcs
    dx, dy, dz = target.spacing()
    cx = 1.0 / d.dx**2
    cy = 1.0 / d.dy**2 if d.ndim > 1 else 0.0
    cz = 1.0 / d.dz**2 if d.ndim > 2 else 0.0
    args = [*bufs, nx, ny, nz, b.x.kind, b.x.value, b.y.kind, b.y.value, b.z.kind, b.z.value,
            cx, cy, cz, dx, dy, dz]
    be._launch_grid(k, ny * nz, args)


# ---------------------------------------------------------------------------- Warp
_WP_FUNCS = {"exp": "wp.exp", "log": "wp.log", "sqrt": "wp.sqrt", "sin": "wp.sin",
             "cos": "wp.cos", "tan": "wp.tan", "tanh": "wp.tanh", "abs": "wp.abs",
             "pow": "wp.pow", "min": "nanmin2", "max": "nanmax2"}


def warp_source(program: Program, kind: str, fields: frozenset[str], dtype) -> str:
    """The text of a Warp module with the kernels of ``program`` (see
    ``kernels/model/warp_model.py.in``)."""
    dtype = np.dtype(dtype)
    lits: list[str] = []

    def lit(v):
        value = float(literal(v, dtype))
        lits.append(f"_c{len(lits)} = wp.constant(real({value!r}))")
        return f"_c{len(lits) - 1}"

    def fn(name, args):
        return f"{_WP_FUNCS[name]}({', '.join(args)})"

    sig = _signature(program, fields)
    decl = ", ".join(f"{nm}: A" if k in ("in", "out", "field") else f"{nm}: real"
                     for k, nm in sig)
    names = ", ".join(nm for _, nm in sig)
    coords = program.refs("coord")
    stencil = program.stencil_inputs
    body = []
    for p in program.refs("param"):
        if p in fields:
            body.append(f"f_{p} = pf_{p}[k_]")
    if kind == "mesh":
        body += [f"{c}c = coord_{c}[k_]" for c in coords]
    elif "x" in coords:
        body.append("xc = (real(j) + real(0.5)) * dx")
    body += [f"c_{s} = in_{s}[k_]" for s in program.inputs]
    if kind == "mesh":
        if stencil:
            body += [f"L_{s} = real(0.0)" for s in stencil]
            body.append("q_ = p0_")
            body.append("while q_ < p1_:")
            body.append("    a_ = data[q_]")
            body.append("    j_ = indices[q_] & NONNEG")
            body += [f"    L_{s} += a_ * in_{s}[j_]" for s in stencil]
            body.append("    q_ += 1")
    else:
        nd = int(kind[-1])
        for s in stencil:
            zero = s in program.zero_ghost
            gxs, gys, gzs = ("real(0.0)",) * 3 if zero else ("gx", "gy", "gz")
            body.append(f"w_{s} = wp.where(wd, {gxs}, in_{s}[rc + w])")
            body.append(f"e_{s} = wp.where(ed, {gxs}, in_{s}[rc + e])")
            lap = f"((e_{s} + w_{s}) - two * c_{s}) * cx"
            if nd > 1:
                body.append(f"s_{s} = wp.where(ds, {gys}, in_{s}[rs + j])")
                body.append(f"n_{s} = wp.where(dn, {gys}, in_{s}[rn + j])")
                lap = f"({lap} + ((n_{s} + s_{s}) - two * c_{s}) * cy)"
            if nd > 2:
                # zb_/zt_, not b_: b_h, b_a, b_b are the builtins' arguments
                body.append(f"zb_{s} = wp.where(db, {gzs}, in_{s}[rb + j])")
                body.append(f"zt_{s} = wp.where(dt_, {gzs}, in_{s}[rt + j])")
                lap = f"({lap} + ((zt_{s} + zb_{s}) - two * c_{s}) * cz)"
            body.append(f"L_{s} = {lap}")
    for i, o in enumerate(program.outputs):
        body.append(f"o{i}_ = {_emit(o.expr, lambda n: _var(n, fields), lit, fn)}")
        lo, hi = o.bounds
        if lo is not None:
            body.append(f"o{i}_ = wp.where(o{i}_ < {lit(lo)}, {lit(lo)}, o{i}_)")
        if hi is not None:
            body.append(f"o{i}_ = wp.where(o{i}_ > {lit(hi)}, {lit(hi)}, o{i}_)")
        body.append(f"out_{o.name}[k_] = flush(o{i}_)")
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
        .replace("@BODY@", "\n".join("    " + b for b in body))
        .replace("@NDIM@", kind[-1])
    )


_WARP_LOCK = threading.Lock()
_WARP_MODULES: dict[str, Any] = {}
_WARP_LOADED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def warp_module(src: str, backend: Backend, prefix: str = "rdgpu_model"):
    """Import a generated Warp module (written under :func:`rdgpu.reaction.cache_dir`,
    since Warp needs a source file) and load it on the backend's device, once each."""
    from ..reaction import _write_atomic, cache_dir

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
        from ..backends.warp_backend import _WARP_LOCK as BACKEND_LOCK
        from ..backends.warp_backend import _quiet

        with BACKEND_LOCK, _quiet(backend._wp):
            backend._wp.load_module(mod, device=backend._dev)
        loaded.add(digest)
    return mod


_WARP_SOURCES: dict[tuple, str] = {}


def _launch_warp(program, target, bufs, fields, scalars):
    from ..backends.warp_backend import ROW_BLOCK

    be = target.backend
    key = (program, target.kind, fields, target.dtype.char)
    src = _WARP_SOURCES.get(key)
    if src is None:
        src = _WARP_SOURCES[key] = warp_source(program, target.kind, fields, target.dtype)
    mod = warp_module(src, be)
    if target.kind == "mesh":
        A = target.csr
        n = A.shape[0]
        if n == 0:
            return
        coords = [be._flat(target.device_coordinate(c)) for c in program.refs("coord")]
        args = [A.indptr.handle, A.indices.handle, A.data.handle, *bufs, *coords]
        if be._cells:
            be._launch(mod.rows, n, args, 0)
        else:
            be._run_split(mod.blocks, -(-n // ROW_BLOCK), A.nnz + n, [*args, n, ROW_BLOCK])
        return
    d = target.domain
    nz, ny, nx = d.shape3
    if nx == 0:
        return
    t = target.dtype.type
    b = d.bcs
    dx, dy, dz = target.spacing()
    cx = 1.0 / d.dx**2
    cy = 1.0 / d.dy**2 if d.ndim > 1 else 0.0
    cz = 1.0 / d.dz**2 if d.ndim > 2 else 0.0
    args = [*bufs, nx, ny, nz, b.x.kind, t(b.x.value), b.y.kind, t(b.y.value), b.z.kind,
            t(b.z.value), t(cx), t(cy), t(cz), t(dx), t(dy), t(dz)]
    if be._cells:
        be._launch(mod.cells, (ny * nz, nx), args, 0)
    else:
        be._run_split(mod.rows, ny * nz, ny * nz * nx, args)


# ---------------------------------------------------------------------------- launch
def launch(program: Program, target: Target, inputs: Sequence[DeviceArray],
           outputs: Sequence[DeviceArray], params: Mapping[str, Any],
           scalars: Mapping[str, float], time: float = 0.0) -> None:
    """One pass of ``program`` on ``target``: ``inputs``/``outputs`` in the program's
    order; ``params`` maps each parameter to a number or a DeviceArray of the domain's
    shape (a field); ``scalars`` the builtins (``_h``...)."""
    be = target.backend
    if len(inputs) != len(program.inputs) or len(outputs) != len(program.outputs):
        raise ValueError("inputs/outputs do not match the program")
    fields = frozenset(p for p in program.refs("param") if isinstance(params[p], DeviceArray))
    t = target.dtype.type
    if be.name == "numpy":
        host = {n: a.handle for n, a in zip(program.inputs, inputs, strict=True)}
        pv = {p: (v.handle if isinstance(v, DeviceArray) else v) for p, v in params.items()
              if p in program.refs("param")}
        res = run_numpy(program, target, host, pv, scalars, time)
        for o, buf in zip(program.outputs, outputs, strict=True):
            buf.handle[...] = res[o.name].reshape(buf.shape)
        return
    flat = be._flat if be.name == "warp" else (lambda a: a.handle)
    bufs: list[Any] = [flat(a) for a in inputs] + [flat(a) for a in outputs]
    ps = program.refs("param")
    bufs += [flat(params[p]) for p in ps if p in fields]
    bufs += [t(params[p]) for p in ps if p not in fields]
    bufs += [t(scalars[b]) for b in program.refs("builtin")]
    bufs.append(t(time))
    lengths = target.lengths()
    bufs += [t(lengths[n]) for n in program.refs("length")]
    if be.name == "warp":
        _launch_warp(program, target, bufs, fields, scalars)
    elif be.name == "opencl":
        _launch_opencl(program, target, bufs, fields, scalars)
    else:  # any other backend: through the host
        host = {n: a.numpy() for n, a in zip(program.inputs, inputs, strict=True)}
        pv = {p: (v.numpy() if isinstance(v, DeviceArray) else v) for p, v in params.items()}
        res = run_numpy(program, target, host, pv, scalars, time)
        for o, buf in zip(program.outputs, outputs, strict=True):
            be.copy(be.upload(np.ascontiguousarray(res[o.name].reshape(buf.shape))), buf)


def is_finite_literal(v: float) -> bool:
    return math.isfinite(v)
