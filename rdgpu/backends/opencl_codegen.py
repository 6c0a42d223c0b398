"""The OpenCL C printer of a `rdgpu.ir.program.Program`, its fused pass and its
temporally blocked pass.

`opencl_cell` writes one cell of a program (the stencil walk of
`rdgpu.ir.stencils`, values fully parenthesised in the tree's operation order, literals
exact in the dtype, ``FP_CONTRACT OFF``); `opencl_source` puts it in the step kernel
``rd_program`` of ``families/model/model.cl`` (one work-item per row, CPU: edge columns
peeled and a branch-free interior; or strided columns, GPU; CSR rows in blocks on meshes)
and, where `rdgpu.backends.target.flat_rows`, ``rd_span`` (CPU: a span of a plane's
interior rows as one flat loop, its x-edge cells recomputed),
`blocked_source` in ``rd_blocked`` of ``families/model/blocked.cl`` (``steps`` Euler
steps per pass over bands of rows: `rdgpu.integrators.blocking`).  Programs are built per
context, build options and dtype (`opencl_program`), kernels cached in the program per
thread (`opencl_kernel`).
"""

from __future__ import annotations

import threading
from typing import Any

import numpy as np

from rdgpu.backends.base import DeviceArray
from rdgpu.backends.target import BlockedPass, FusedPass, Target, arguments, flat_rows, spans
from rdgpu.families import read_source
from rdgpu.ir.equations import to_text
from rdgpu.ir.names import ident
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

__all__ = ["OpenCLBlockedPass", "OpenCLFusedPass", "blocked_source", "opencl_cell",
           "opencl_source"]

_CL_FUNCS = {"exp": "exp", "log": "log", "sqrt": "SQRT", "sin": "sin", "cos": "cos",
             "tan": "tan", "tanh": "tanh", "sinh": "sinh", "cosh": "cosh", "floor": "floor",
             "abs": "FABS",
             "pow": "pow", "min": "nanmin2",
             "max": "nanmax2", "lt": "cmp_lt", "le": "cmp_le", "gt": "cmp_gt", "ge": "cmp_ge",
             "eq": "cmp_eq", "ne": "cmp_ne"}
#: the boundary flag of each side in the template
_FLAGS = {"w": "cc_.w_dir", "e": "cc_.e_dir", "s": "ds", "n": "dn", "b": "db", "t": "dt_"}
#: the column of a neighbour at each offset
_COLUMNS = {-1: "cc_.w", 0: "j", 1: "cc_.e"}


# ---------------------------------------------------------------------------- printing
def opencl_source(program: Program, kind: str, fields: frozenset[str], dtype,
                  member: frozenset[str] = frozenset()) -> str:
    """The OpenCL C kernel ``rd_program`` on stencil kind ``kind`` (needs ``common.cl``
    first); ``member``: the parameters given per ensemble member."""
    decl, body = opencl_cell(program, kind, fields, dtype, member)
    template = read_source("model", "model.cl")
    part = "MESH" if kind == "mesh" else "GRID"
    text = template[template.index(f"/*@{part}@*/"): template.index(f"/*@END {part}@*/")]
    coord_decl = "".join(f",\n        __global const real *RESTRICT coord_{c}"
                         for c in program.refs("coord"))
    row = []
    if STENCIL_KINDS[kind].form == "metric":  # the in-member offsets of this row and its south
        row += ["const long mc_ = (long)i * nx;",
                "const long ms_ = (long)lo_index(i, ny, y_kind) * nx;",
                "(void)mc_; (void)ms_;"]
    if kind != "mesh" and not flat_rows(program, kind):
        text = text[: text.index("/*@SPAN@*/")] + text[text.index("/*@END SPAN@*/"):]
    return opencl_head(program) + (
        text.replace("@ARGS@", ",\n        ".join(decl))
        .replace("@COORDS@", coord_decl if kind == "mesh" else "")
        .replace("@MEMBER@", "\n".join("    " + r for r in member_lines(member)))
        .replace("@ROW@", "\n".join("    " + r for r in row))
        .replace("@CELL@", " \\\n".join("        " + b for b in body))
        .replace("@BODY@", "\n".join("        " + b for b in body))
    )


def member_lines(member: frozenset[str]) -> list[str]:
    """The statements reading the per-member parameters (grids: once per row)."""
    return [f"const real {ident('p', p)} = {ident('pm', p)}[m_];" for p in sorted(member)]


def opencl_head(program: Program) -> str:
    """The part of ``model.cl`` every generated OpenCL program starts with (its comment
    naming the outputs, the helper functions)."""
    template = read_source("model", "model.cl")
    comment = "\n".join(f" *   {o.name} = {to_text(o.expr)}" for o in program.outputs)
    return template[: template.index("/*@GRID@*/")].replace("@OUTPUTS@", comment)


def opencl_cell(program: Program, kind: str, fields: frozenset[str], dtype,
                member: frozenset[str] = frozenset(), field_index: str = "k_",
                out_index: str = "k_") -> tuple[list[str], list[str]]:
    """``(arguments, statements)`` of one cell of ``program`` in OpenCL C: the kernel's
    argument declarations (`rdgpu.ir.program.signature`'s order) and the cell body.
    The body reads input ``s`` as ``in_s[k_]`` and its neighbours at the row offsets
    ``rc, rs, rn...`` plus ``j``/``cc_.w``/``cc_.e``, parameter fields at
    ``[field_index]``, and stores output ``o`` to ``out_o[out_index]`` (the step kernel:
    all ``k_``)."""
    dtype = np.dtype(dtype)
    if dtype == np.float64:
        def lit(v):
            return f"({float(literal(v, dtype)).hex()})"
    else:
        def lit(v):
            return f"({float(literal(v, dtype)).hex()}f)"

    def fn(name, args):
        return f"{_CL_FUNCS[name]}({', '.join(args)})"

    def var(n):
        return variable(n, fields)

    decl = []
    for k, nm in signature(program, fields, member):
        if k in ("in", "field", "member"):
            decl.append(f"__global const real *RESTRICT {nm}")
        elif k == "out":
            decl.append(f"__global real *RESTRICT {nm}")
        else:
            decl.append(f"const real {nm}")
    if STENCIL_KINDS[kind].form == "metric":
        decl += [f"__global const real *RESTRICT {nm}" for nm in METRIC_ARGS]
    coords = program.refs("coord")
    body = member_lines(member) if kind == "mesh" else []
    for p in program.refs("param"):
        if p in fields:
            body.append(f"const real {ident('f', p)} = {ident('pf', p)}[{field_index}];")
    if kind == "mesh":
        body += [f"const real {c}c = coord_{c}[v_];" for c in coords]
    elif "x" in coords:
        body.append("const real xc = ((real)(j) + (real)0.5) * dx;")
    body += [f"const real {ident('c', s)} = {ident('in', s)}[k_];" for s in program.inputs]
    for d, expr in program.derived:
        body.append(f"const real {ident('c', d)} = {emit(expr, var, lit, fn)};")
    stencil = program.stencil_inputs
    if kind == "mesh":
        if stencil:
            body += [f"real {ident('lap', s)} = R0;" for s in stencil]
            body += [f"real {var(d)} = R0;" for d in program.divergences]
            body.append("for (int q_ = p0_; q_ < p1_; ++q_) {")
            body.append("    const real a_ = data[q_];")
            body.append("    const int j_ = indices[q_];")
            for _, s, v in neighbour_values(program, kind,
                                            lambda nb, i: ident("in", i) + "[moff_ + j_]",
                                            None, fields, lit, fn):
                body.append(f"    const real {ident('qcol', s)} = {v};")
                body.append(f"    {ident('lap', s)} += a_ * {ident('qcol', s)};")
            body += [f"    {var(d)} += a_ * {mesh_divergence_text(d, lambda v: f'((real){v})')};"
                     for d in program.divergences]
            body.append("}")
    else:
        _grid_neighbours(program, kind, fields, lit, fn, body)
        cols = {-1: "cc_.w", 0: "j"}
        body += [f"const real {ln};" for ln in metric_loads(
            kind, stencil, lambda a, r, dx: f"{a}[m{r}_ + {cols[dx]}]")]
        for s in stencil:
            body.append(f"const real {ident('lap', s)} = "
                        f"{laplacian_text(kind, s, lambda v: f'((real){v})')};")
        body += [f"const real {var(d)} = {derivative_text(kind, d, lambda v: f'((real){v})')};"
                 for d in program.derivatives]
        body += [f"const real {var(d)} = {divergence_text(kind, d, lambda v: f'((real){v})')};"
                 for d in program.divergences]
    for i, o in enumerate(program.outputs):
        body.append(f"real o{i}_ = {emit(o.expr, var, lit, fn)};")
        lo, hi = o.bounds
        if lo is not None:
            body.append(f"o{i}_ = (o{i}_ < {lit(lo)}) ? {lit(lo)} : o{i}_;")
        if hi is not None:
            body.append(f"o{i}_ = (o{i}_ > {lit(hi)}) ? {lit(hi)} : o{i}_;")
        body.append(f"{ident('out', o.name)}[{out_index}] = FLUSH(o{i}_);")
    return decl, body


def _grid_neighbours(program: Program, kind: str, fields: frozenset[str], lit, fn,
                     body: list[str]) -> None:
    """Append the neighbour values ``_q{pos}_{s}`` of a grid cell to ``body``: each input
    is loaded once per neighbour, unconditionally (the indices are in range), then the
    boundary selects pick the ghost."""
    loaded: set[tuple[str, str]] = set()

    def load(nb, i):
        if (nb.name, i) not in loaded:
            loaded.add((nb.name, i))
            body.append(f"const real {ident(f'q{nb.name}0', i)} = "
                        f"{ident('in', i)}[r{nb.row or 'c'} + {_COLUMNS[nb.dx]}];")
        return ident(f"q{nb.name}0", i)

    def select(side, ghost, value):
        return f"({_FLAGS[side]} ? {'R0' if ghost == '0' else ghost} : {value})"

    for pos, s, value in neighbour_values(program, kind, load, select, fields, lit, fn):
        body.append(f"const real {ident('q' + pos, s)} = {value};")


def blocked_source(program: Program, kind: str, fields: frozenset[str], dtype,
                   member: frozenset[str] = frozenset()) -> str:
    """The OpenCL C kernel ``rd_blocked`` of ``program`` (needs ``common.cl`` first);
    ``member``: the parameters given per ensemble member."""
    decl, body = opencl_cell(program, kind, fields, dtype, member, field_index="kf_",
                             out_index="ko_")
    select = []
    for q, s in enumerate(program.inputs):
        select.append(f"__global const real *{ident('lin', s)} = (k == 1) ? {ident('in', s)}"
                      f" : src_ + {q} * ring_;")
        select.append(f"__global real *{ident('lout', s)} = (k == steps) ? {ident('out', s)}"
                      f" : dst_ + {q} * ring_;")
    rename = {ident("in", s): ident("lin", s) for s in program.inputs}
    rename.update({ident("out", s): ident("lout", s) for s in program.inputs})
    rename["b_t"] = "times_[k - 1]"
    call = [rename.get(nm, nm) for _, nm in signature(program, fields, member)]
    text = read_source("model", "blocked3.cl" if _is_3d(kind) else "blocked.cl")
    return opencl_head(program) + (
        text.replace("@ARGS@", ",\n        ".join(decl))
        .replace("@NS@", str(len(program.inputs)))
        .replace("@SELECT@", "\n".join(" " * 16 + line for line in select))
        .replace("@CALL@", ", ".join(call))
        .replace("@ROW@", "\n".join("    " + line for line in member_lines(member)))
        .replace("@FLAT@", str(int(flat_rows(program, kind))))
        .replace("@CELL@", " \\\n".join("        " + b for b in body))
    )


def _is_3d(kind: str) -> bool:
    return STENCIL_KINDS[kind].ndim == 3


# ---------------------------------------------------------------------------- building
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
        be.check_real(target.dtype)
        k = program.cache[key] = make()
    return k


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
            prog = be.cl.Program(be.context, full).build(options=options)
            _CL_PROGRAMS[pkey] = prog
    return prog


def opencl_arg_dtypes(program: Program, fields: frozenset[str], dtype,
                      member: frozenset[str] = frozenset()) -> list:
    """pyopencl's scalar argument dtypes of the signature (None for buffers)."""
    return [None if kk in ("in", "out", "field", "member") else np.dtype(dtype)
            for kk, _ in signature(program, fields, member)]


# ---------------------------------------------------------------------------- passes
#: about how many cells `rd_span` gives a work-item (a span of rows of one plane): fewer
#: where the grid would not give every compute unit four; 0: `rd_program` always
SPAN_CELLS = 8192


class OpenCLFusedPass(FusedPass):
    """A program's ``rd_program`` kernel on one OpenCL backend (built on first launch in
    each thread)."""

    def __init__(self, program: Program, fields: frozenset[str], member: frozenset[str]):
        self.program, self.fields, self.member = program, fields, member

    def _kernel(self, target: Target, name: str = "rd_program"):
        """Kernel ``name`` (``rd_program``, or ``rd_span`` where `flat_rows`), this
        thread's."""
        return opencl_kernel(self.program, target, self.fields, name,
                             lambda: self._make(target, name), self.member)

    def _make(self, target: Target, name: str):
        """A new kernel object ``name`` (its own arguments) of the built program."""
        program, fields, member = self.program, self.fields, self.member
        skey = ("opencl source", target.kind, fields, member, target.dtype.char)
        src = program.cache.get(skey)
        if src is None:
            src = program.cache[skey] = opencl_source(program, target.kind, fields,
                                                      target.dtype, member)
        k = target.backend.cl.Kernel(opencl_program(target, src, "model/model.cl"), name)
        codes = opencl_arg_dtypes(program, fields, target.dtype, member)
        if target.kind == "mesh":
            codes = [None, None, None, *codes, np.int32, np.int32, np.int32,
                     *[None] * len(program.refs("coord"))]
        else:
            codes += [None] * len(target.metric)
            codes += [np.int32] * 4 + [np.int32, target.dtype] * 3 + [target.dtype] * 6
            if name == "rd_span":
                codes += [np.int32, np.int32]
        k.set_scalar_arg_dtypes(codes)
        return k

    def _spans(self, target: Target, nx: int, ny: int, planes: int) -> tuple[int, int]:
        """`rdgpu.backends.target.spans` of this grid for `rd_span`, or ``(0, 0)`` for
        `rd_program` (the strided layout, programs `flat_rows` refuses)."""
        be = target.backend
        if be.layout != "row" or not flat_rows(self.program, target.kind):
            return 0, 0
        return spans(nx, ny, planes, SPAN_CELLS, be.compute_units)

    def launch(self, target, inputs, outputs, params, fields, member, scalars, time):
        program, be = self.program, target.backend
        bufs = arguments(program, target, inputs, outputs, params, fields, scalars, time,
                         member=member)
        if target.kind == "mesh":
            A = target.csr
            n = A.shape[0]
            if n == 0:
                return
            head = (A.indptr.handle, A.indices.handle, A.data.handle, *bufs)
            tail = (np.int32(n),
                    *(target.device_coordinate(c).handle for c in program.refs("coord")))
            be.launch_rows(self._kernel(target), n * target.members, head, tail)
            return
        # per thread, as the kernels (a kernel object holds its arguments)
        key = ("opencl grid launch", id(self), threading.get_ident())
        plan = target.host.get(key)
        if plan is None:
            name, items, tail = self._grid_plan(target)
            plan = target.host[key] = (self._kernel(target, name), items, tail)
        kernel, items, tail = plan
        if items:
            be.launch_grid(kernel, items, [*bufs, *(c.handle for c in target.metric), *tail])

    def bind(self, target, inputs, outputs, params, fields, member, scalars):
        """On a grid, a kernel object of its own with every argument set once; ``run(time)``
        sets the time (where the program reads it) and enqueues."""
        if target.kind == "mesh":
            return super().bind(target, inputs, outputs, params, fields, member, scalars)
        name, items, tail = self._grid_plan(target)
        if not items:
            return lambda time: None
        program, be = self.program, target.backend
        kernel = self._make(target, name)
        args = [*arguments(program, target, inputs, outputs, params, fields, scalars, 0.0,
                           member=member), *(c.handle for c in target.metric), *tail]
        kernel.set_args(*args)  # OpenCL keeps no buffer alive: ``run`` keeps ``args``
        enqueue = be.grid_launcher(kernel, items)
        if not program.refs("time"):
            return lambda time, args=args: enqueue()
        at = [nm for _, nm in signature(program, fields, member)].index("b_t")
        real = target.dtype.type

        def run(time: float, args=args) -> None:
            kernel.set_arg(at, real(time))
            enqueue()

        return run

    def _grid_plan(self, target: Target) -> tuple[str, int, list]:
        """What every launch on this grid target shares: the kernel's name (``rd_span`` or
        ``rd_program``), its work-items (0: no cells) and the arguments after the
        buffers."""
        d = target.domain
        nz, ny, nx = d.shape3
        b = self.program.kernel_bcs(d)
        dx, dy, dz = target.spacing()
        cx, cy, cz = target.grid_coefficients()
        nm = target.members
        tail = [nx, ny, nz, nm, b.x.kind, b.x.value, b.y.kind, b.y.value, b.z.kind,
                b.z.value, cx, cy, cz, dx, dy, dz]
        span, count = self._spans(target, nx, ny, nz * nm)
        if span:
            return "rd_span", nz * nm * count, [*tail, span, count]
        return "rd_program", (ny * nz * nm if nx else 0), tail


class OpenCLBlockedPass(BlockedPass):
    """``steps`` Euler steps of ``program`` per pass over a 2-D grid ``target`` in bands of
    ``rows`` rows (``rd_blocked``), or over a 3-D grid in bands of ``rows`` z-planes
    (``rd_blocked3``), over ``items`` work-items, each with its scratch rings
    (`rdgpu.integrators.blocking`; `OpenCLBackend.blocked_pass`)."""

    def __init__(self, program: Program, target: Target, steps: int, rows: int, items: int):
        self.program, self.target = program, target
        self.steps, self.rows, self.items = int(steps), int(rows), int(items)
        be = target.backend
        self.nz, self.ny, self.nx = target.domain.shape3
        self.three = _is_3d(target.kind)
        # 2-D: one plane per ensemble member; 3-D: one volume
        self.planes = (1 if self.three else self.nz) * target.members
        unit = max(self.nx, 1) * (max(self.ny, 1) if self.three else 1)  # a row or a plane
        per_item = (self.steps - 1) * len(program.inputs) * 3 * unit
        self._scratch = be.empty((max(1, self.items * per_item),), target.dtype)
        self._times = be.empty((self.steps,), target.dtype)
        self._name = "rd_blocked3" if self.three else "rd_blocked"

    def _kernel(self, fields: frozenset[str], member: frozenset[str]):
        program, target, name = self.program, self.target, self._name

        def make():
            src = blocked_source(program, target.kind, fields, target.dtype, member)
            label = "model/blocked3.cl" if self.three else "model/blocked.cl"
            k = target.backend.cl.Kernel(opencl_program(target, src, label), name)
            dt, i4 = target.dtype, np.int32
            grid = ([i4] * 4 + [i4, dt] * 3 + [dt] * 6 if self.three else
                    [i4, i4, i4, i4, dt, i4, dt, dt, dt, dt, dt])
            k.set_scalar_arg_dtypes([*opencl_arg_dtypes(program, fields, dt, member), None, None,
                                     *grid, i4, i4, i4])
            return k

        return opencl_kernel(program, target, fields, name, make, member)

    def run(self, x: list[DeviceArray], y: list[DeviceArray], params: dict[str, Any],
            fields: frozenset[str], member: frozenset[str], scalars: dict[str, float],
            time: float, times: np.ndarray | None) -> None:
        """One pass from ``x`` (at ``time``) into ``y``; ``times``: the ``steps`` step times
        where they changed since the last pass (else None)."""
        program, target = self.program, self.target
        if self.nx == 0 or self.ny == 0 or self.nz == 0 or self.planes == 0:
            return
        be = target.backend
        if times is not None:
            # the in-order queue runs the copy after the previous pass (pyopencl keeps
            # ``times`` alive until it is done)
            be.cl.enqueue_copy(be.queue, self._times.handle, times, is_blocking=False)
        args = arguments(program, target, x, y, params, fields, scalars, time, member=member)
        b = program.kernel_bcs(target.domain)
        dx, dy, dz = target.spacing()
        cx, cy, cz = target.grid_coefficients()
        args += [self._times.handle, self._scratch.handle]
        if self.three:
            args += [self.nx, self.ny, self.nz, self.planes, b.x.kind, b.x.value, b.y.kind,
                     b.y.value, b.z.kind, b.z.value, cx, cy, cz, dx, dy, dz]
        else:
            args += [self.nx, self.ny, self.planes, b.x.kind, b.x.value, b.y.kind, b.y.value,
                     cx, cy, dx, dy]
        args += [self.steps, self.rows, self.items]
        k = self._kernel(fields, member)
        k.set_args(*args)
        be.cl.enqueue_nd_range_kernel(be.queue, k, (self.items,), (1,))
