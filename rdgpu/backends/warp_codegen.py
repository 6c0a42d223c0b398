"""The Warp printer of a `rdgpu.ir.program.Program`, and its fused pass.

`warp_source` fills ``families/model/warp_model.py.in`` with the kernels of one
program: on grids ``rows`` (one thread per row in row chunks, CPU) and ``cells`` (one per
cell, CUDA), each cell in two bodies (one with the boundary selects, one for interior
columns, which LLVM vectorises); on meshes ``rows`` (one vertex per thread, CUDA) and
``blocks`` (CSR rows in blocks, CPU).  The neighbours come from the stencil walk of
`rdgpu.ir.stencils`, values fully parenthesised in the tree's operation order with
literals exact in the dtype.  `warp_module` imports the generated module (Warp needs a
source file: it goes under `cache_dir`) and `WarpFusedPass` launches it.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import sys
import threading
import weakref
from pathlib import Path
from typing import Any

import numpy as np

from rdgpu.backends.base import Backend, DeviceArray
from rdgpu.backends.target import FusedPass, Target, arguments, flat_rows, spans
from rdgpu.backends.warp_runtime import ROW_BLOCK, check_cells, quiet_warp
from rdgpu.backends.warp_runtime import WARP_LOCK as BACKEND_LOCK
from rdgpu.families import read_source
from rdgpu.ir.equations import to_text
from rdgpu.ir.names import flat_view, ident, split
from rdgpu.ir.program import Program, literal, signature
from rdgpu.ir.stencils import (
    METRIC_ARGS,
    STENCIL_KINDS,
    derivative_text,
    divergence_text,
    emit,
    laplacian_text,
    mesh_divergence_text,
    metric_loads,
    neighbour_values,
    variable,
)

__all__ = ["WarpFusedPass", "cache_dir", "warp_module", "warp_source"]

_WP_FUNCS = {"exp": "wp.exp", "log": "wp.log", "sqrt": "wp.sqrt", "sin": "wp.sin",
             "cos": "wp.cos", "tan": "wp.tan", "tanh": "wp.tanh", "sinh": "wp.sinh",
             "cosh": "wp.cosh", "floor": "wp.floor", "abs": "wp.abs", "pow": "wp.pow",
             "min": "nanmin2",
             "max": "nanmax2", "lt": "cmp_lt",
             "le": "cmp_le", "gt": "cmp_gt", "ge": "cmp_ge", "eq": "cmp_eq", "ne": "cmp_ne"}
#: the boundary flag of each side in the template
_FLAGS = {"w": "wd", "e": "ed", "s": "ds", "n": "dn", "b": "db", "t": "dt_"}


def warp_source(program: Program, kind: str, fields: frozenset[str], dtype,
                member: frozenset[str] = frozenset()) -> str:
    """The text of a Warp module with the kernels of ``program`` (see
    ``families/model/warp_model.py.in``) on stencil kind ``kind``; ``member``: the
    parameters given per ensemble member (grids read them once per row, meshes once per
    vertex)."""
    dtype = np.dtype(dtype)
    lits: list[str] = []

    def lit(v):
        value = float(literal(v, dtype))
        lits.append(f"_c{len(lits)} = wp.constant(real({value!r}))")
        return f"_c{len(lits) - 1}"

    def fn(name, args):
        return f"{_WP_FUNCS[name]}({', '.join(args)})"

    sig = signature(program, fields, member)
    if STENCIL_KINDS[kind].form == "metric":
        sig += [("field", nm) for nm in METRIC_ARGS]
    mesh = kind == "mesh"
    array = "A" if mesh else "A2"
    kdecl = ", ".join(f"{nm}: {array}" if k in ("in", "out", "field") else
                      f"{nm}: A" if k == "member" else f"{nm}: real" for k, nm in sig)
    member_loads = [f"{ident('p', split(nm)[1])} = {nm}[m_]" for k, nm in sig if k == "member"]
    buffers = [nm for k, nm in sig if k in ("in", "out", "field")]
    if mesh:  # the vertex function reads the member's numbers itself
        decl, names = kdecl, ", ".join(nm for _, nm in sig)
    else:  # the row's numbers are read by the kernel and passed to the cell functions, and
        # so are flat views of the grid buffers (the cells index them at row base + column)
        decl = ", ".join(f"{nm}: A" if k in ("in", "out", "field") else
                         f"{ident('p', split(nm)[1])}: real" if k == "member" else
                         f"{nm}: real" for k, nm in sig)
        names = ", ".join(ident("p", split(nm)[1]) if k == "member" else
                          flat_view(nm) if k in ("in", "out", "field") else nm for k, nm in sig)
    # the cell functions' own parameter names, for a function that passes them on
    passed = ", ".join(ident("p", split(nm)[1]) if k == "member" else nm for k, nm in sig)
    coords = program.refs("coord")
    body = _cell_body(program, kind, fields, member_loads, lit, fn, False)
    inner = _cell_body(program, kind, fields, member_loads, lit, fn, True) if not mesh else []
    template = read_source("model", "warp_model.py.in")
    part = "MESH" if mesh else "GRID"
    head = template[: template.index("# @GRID@")]
    text = template[template.index(f"# @{part}@"): template.index(f"# @END {part}@")]
    if not mesh and not flat_rows(program, kind):
        text = text[: text.index("# @SPAN@")] + text[text.index("# @END SPAN@"):]
    coord_decl = "".join(f", coord_{c}: A" for c in coords) if mesh else ""
    coord_names = "".join(f", coord_{c}" for c in coords) if mesh else ""
    return (
        head.replace("@DTYPE@", "float64" if dtype == np.float64 else "float32")
        .replace("@CONSTANTS@", "\n".join(lits))
        .replace("@OUTPUTS@", "\n".join(f"    {o.name} = {to_text(o.expr)}"
                                          for o in program.outputs))
        + text.replace("@DECL@", decl + coord_decl).replace("@NAMES@", names + coord_names)
        .replace("@PASS@", passed if not mesh else "")
        .replace("@KDECL@", kdecl + coord_decl)
        .replace("@ROW@", "\n".join("    " + r for r in member_loads) if not mesh else "")
        .replace("@FLAT@", "\n".join(f"    {flat_view(nm)} = flat({nm})" for nm in buffers)
                 if not mesh else "")
        .replace("@BODY@", "\n".join("    " + b for b in body))
        .replace("@INTERIOR@", "\n".join("    " + b for b in inner))
    )


def _cell_body(program: Program, kind: str, fields: frozenset[str], member_loads: list[str],
               lit, fn, interior: bool) -> list[str]:
    """The cell's statements; ``interior``: no ghost can occur (no selects).  Grid buffers
    are flat views indexed ``row base + column`` (``r``, ``rs``, …: the flat indices of the
    first cells of the rows), mesh buffers 1-D."""
    mesh = kind == "mesh"
    stencil = program.stencil_inputs
    coords = program.refs("coord")

    def var(n):
        return variable(n, fields)

    at = "k_" if mesh else "r + j"
    body = list(member_loads) if mesh else []
    for p in program.refs("param"):
        if p in fields:
            body.append(f"{ident('f', p)} = {ident('pf', p)}[{at}]")
    if mesh:
        body += [f"{c}c = coord_{c}[v_]" for c in coords]
    elif "x" in coords:
        body.append("xc = (real(j) + real(0.5)) * dx")
    body += [f"{ident('c', s)} = {ident('in', s)}[{at}]" for s in program.inputs]
    for d, expr in program.derived:
        body.append(f"{ident('c', d)} = {emit(expr, var, lit, fn)}")
    if mesh:
        if stencil:
            body += [f"{ident('lap', s)} = real(0.0)" for s in stencil]
            body += [f"{var(d)} = real(0.0)" for d in program.divergences]
            body.append("q_ = p0_")
            body.append("while q_ < p1_:")
            body.append("    a_ = data[q_]")
            body.append("    j_ = indices[q_] & NONNEG")
            for _, s, v in neighbour_values(program, kind,
                                            lambda nb, i: ident("in", i) + "[moff_ + j_]",
                                            None, fields, lit, fn):
                body.append(f"    {ident('qcol', s)} = {v}")
                body.append(f"    {ident('lap', s)} += a_ * {ident('qcol', s)}")
            body += [f"    {var(d)} += a_ * {mesh_divergence_text(d, lambda v: f'real({v}.0)')}"
                     for d in program.divergences]
            body.append("    q_ += 1")
    else:
        col = {-1: "j - 1" if interior else "w", 0: "j", 1: "j + 1" if interior else "e"}

        def load(nb, i):
            return f"{ident('in', i)}[r{nb.row} + {col[nb.dx]}]"

        def select(side, ghost, value):
            g = "real(0.0)" if ghost == "0" else ghost
            return f"wp.where({_FLAGS[side]}, {g}, {value})"

        body += [f"{ident('q' + pos, s)} = {v}" for pos, s, v in neighbour_values(
            program, kind, load, None if interior else select, fields, lit, fn)]
        if STENCIL_KINDS[kind].form == "metric" and stencil:  # one member's coefficient rows
            body += ["mc_ = r % _me_w.shape[0]", "ms_ = rs % _me_w.shape[0]"]
        body += metric_loads(kind, stencil, lambda a, r, dx: f"{a}[m{r}_ + {col[dx]}]")
        for s in stencil:
            lap = laplacian_text(kind, s, lambda v: f"real({v}.0)", "flush")
            body.append(f"{ident('lap', s)} = {lap}")
        body += [f"{var(d)} = {derivative_text(kind, d, lambda v: f'real({v}.0)')}"
                 for d in program.derivatives]
        body += [f"{var(d)} = {divergence_text(kind, d, lambda v: f'real({v}.0)')}"
                 for d in program.divergences]
    for i, o in enumerate(program.outputs):
        body.append(f"o{i}_ = {emit(o.expr, var, lit, fn)}")
        lo, hi = o.bounds
        if lo is not None:
            body.append(f"o{i}_ = wp.where(o{i}_ < {lit(lo)}, {lit(lo)}, o{i}_)")
        if hi is not None:
            body.append(f"o{i}_ = wp.where(o{i}_ > {lit(hi)}, {lit(hi)}, o{i}_)")
        body.append(f"{ident('out', o.name)}[{at}] = flush(o{i}_)")
    return body


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


_MODULES_LOCK = threading.Lock()
_MODULES: dict[str, Any] = {}
_LOADED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def warp_module(src: str, backend: Backend, prefix: str = "rdgpu_model"):
    """Import a generated Warp module (written under `cache_dir`, since Warp needs a
    source file) and load it on the backend's device, once each."""
    digest = hashlib.sha256(src.encode()).hexdigest()[:24]
    with _MODULES_LOCK:
        mod = _MODULES.get(digest)
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
            _MODULES[digest] = mod
    loaded = _LOADED.setdefault(backend, set())
    if digest not in loaded:
        with BACKEND_LOCK, quiet_warp(backend._wp):
            backend._wp.load_module(mod, device=backend._dev)
        loaded.add(digest)
    return mod


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


#: about how many cells the ``spans`` kernel gives a thread (a span of rows of one plane):
#: fewer where the grid would not give every chunk four; 0: the ``rows`` kernel always
SPAN_CELLS = 8192


class WarpFusedPass(FusedPass):
    """A program's generated Warp module on one backend (`WarpBackend.fused_pass`)."""

    def __init__(self, program: Program, target: Target, fields: frozenset[str],
                 member: frozenset[str]):
        self.program = program
        self.flat = flat_rows(program, target.kind)
        src = warp_source(program, target.kind, fields, target.dtype, member)
        self.module = warp_module(src, target.backend)

    def launch(self, target, inputs, outputs, params, fields, member, scalars, time):
        program, be, mod = self.program, target.backend, self.module
        mesh = target.kind == "mesh"
        bufs = arguments(program, target, inputs, outputs, params, fields, scalars, time,
                         be.flat if mesh else _warp_rows, member)
        nm = target.members
        if mesh:
            A = target.csr
            n = A.shape[0]
            if n == 0:
                return
            coords = [be.flat(target.device_coordinate(c)) for c in program.refs("coord")]
            args = [A.indptr.handle, A.indices.handle, A.data.handle, *bufs, *coords, n]
            rows = n * nm
            if be.per_cell:
                be.launch(mod.rows, rows, args, 0)
            else:
                be.run_split(mod.blocks, -(-rows // ROW_BLOCK), (A.nnz + n) * nm,
                              [*args, rows, ROW_BLOCK])
            return
        args = self._grid_args(target, bufs)
        if args is None:
            return
        if be.per_cell:
            be.launch(mod.cells, (self._rows(target), target.domain.shape3[2]), args, 0)
            return
        be.run_split(*self._split(target, args))

    def bind(self, target, inputs, outputs, params, fields, member, scalars):
        """On a CPU grid, every chunk's launch recorded once with its arguments packed;
        ``run(time)`` sets the time (where the program reads it) and launches."""
        be = target.backend
        if target.kind == "mesh" or be.per_cell:
            return super().bind(target, inputs, outputs, params, fields, member, scalars)
        program = self.program
        bufs = arguments(program, target, inputs, outputs, params, fields, scalars, 0.0,
                         _warp_rows, member)
        args = self._grid_args(target, bufs)
        if args is None:
            return lambda time: None
        timed = bool(program.refs("time"))
        at = [nm for _, nm in signature(program, fields, member)].index("b_t") if timed else None
        go = be.split_launcher(*self._split(target, args), at=at)
        real = target.dtype.type
        return lambda time: go(real(time))

    @staticmethod
    def _rows(target: Target) -> int:
        nz, ny, _ = target.domain.shape3
        return ny * nz * target.members

    def _grid_args(self, target: Target, bufs: list) -> list | None:
        """The grid kernels' arguments after the buffers ``bufs``, or None: no cells."""
        d = target.domain
        nz, ny, nx = d.shape3
        nm = target.members
        check_cells(nm * nz * ny * nx, (nm, nz, ny, nx))
        if nx == 0:
            return None
        t = target.dtype.type
        b = self.program.kernel_bcs(d)
        dx, dy, dz = target.spacing()
        cx, cy, cz = target.grid_coefficients()
        return [*bufs, *(_warp_rows(c) for c in target.metric), nx, ny, nz, nm, b.x.kind,
                t(b.x.value), b.y.kind, t(b.y.value), b.z.kind, t(b.z.value), t(cx), t(cy),
                t(cz), t(dx), t(dy), t(dz)]

    def _split(self, target: Target, args: list) -> tuple[Any, int, int, list]:
        """`WarpBackend.run_split`'s arguments on the CPU: the ``spans`` kernel where the
        grid is cut in spans, else ``rows``."""
        nz, ny, nx = target.domain.shape3
        rows, planes = self._rows(target), nz * target.members
        span, count = self._spans(target.backend, nx, ny, planes)
        if span:
            return self.module.spans, planes * count, rows * nx, [*args, span, count]
        return self.module.rows, rows, rows * nx, args

    def _spans(self, be, nx: int, ny: int, planes: int) -> tuple[int, int]:
        """`rdgpu.backends.target.spans` of this grid for the ``spans`` kernel (four per
        launch chunk), or ``(0, 0)`` for ``rows`` (programs `flat_rows` refuses)."""
        return spans(nx, ny, planes, SPAN_CELLS, be._chunks) if self.flat else (0, 0)
