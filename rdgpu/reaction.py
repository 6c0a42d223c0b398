"""Pointwise reaction kernels generated from a model's reaction expressions.

A :class:`ReactionKernel` takes the species names and one reaction expression per species
and advances, on any backend, one forward-Euler step of

    out_s = x_s + dt · (D_s · lap_s + R_s(x_1, …, x_n; params))

where ``lap_s`` is a precomputed Laplacian of ``x_s`` (grid stencil or mesh SpMV) and a
species with ``D_s = 0`` reads no Laplacian at all.  Each parameter is a scalar or a
per-cell field (a :class:`DeviceArray` of the fields' shape); which ones are fields is part
of the compile key, so one kernel is built per combination actually used.

Expression rules (checked with :mod:`ast`; anything else raises :class:`ExpressionError`):

* the operators ``+ - * /`` and unary ``-``/``+``, parentheses;
* names: the species and the parameters (identifiers; Python keywords are not allowed);
* numeric literals (``2``, ``0.5``, ``1e-3``).  Every literal is a real number of the
  fields' dtype, so ``1/2`` is ``0.5`` in every language (never C's integer division);
* no ``**`` (write ``u*u*u``), no function calls, comparisons, subscripts or attributes.

Each expression is emitted fully parenthesised in the operation order Python's parser
gives it (left to right for ``a*b*c``), into NumPy, Warp and OpenCL C alike; OpenCL
compiles with ``FP_CONTRACT OFF`` and the literals are exact in the dtype (hex floats), so
the three backends agree to round-off (bit for bit in practice).

Subnormals (docs/equations.md, :mod:`rdgpu.fpenv`): every new value is flushed (after its
clamp) in all three implementations, and a literal that would be subnormal in the fields'
dtype is 0.

Warp needs a real source file for a kernel: the module text is written to
``$RDGPU_CACHE_DIR/warp/<hash>.py`` (default ``~/.cache/rdgpu``) and imported.
"""

from __future__ import annotations

import ast
import hashlib
import importlib.util
import keyword
import os
import sys
import threading
import weakref
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .backends.base import Backend, DeviceArray
from .fpenv import flush_subnormals
from .kernel_files import load_module, read_source

__all__ = ["Expression", "ExpressionError", "ReactionKernel", "cache_dir", "parse_expression"]

_BINOPS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/"}
_REALS = (np.dtype(np.float32), np.dtype(np.float64))
#: elements per OpenCL work-item on a CPU device (one vectorisable loop each)
OPENCL_CHUNK = 8192


class ExpressionError(ValueError):
    """A reaction expression uses something outside the allowed subset."""


# ---------------------------------------------------------------------------- expressions
@dataclass(frozen=True)
class Expression:
    """A validated reaction expression."""

    text: str
    tree: ast.expr
    #: the names it uses, sorted
    names: tuple[str, ...]

    def emit(self, name, literal) -> str:
        """Source text, fully parenthesised: ``name(id)`` renders a name and
        ``literal(float)`` a numeric literal in the target language."""

        def go(node: ast.expr) -> str:
            if isinstance(node, ast.BinOp):
                return f"({go(node.left)} {_BINOPS[type(node.op)]} {go(node.right)})"
            if isinstance(node, ast.UnaryOp):
                inner = go(node.operand)
                return f"(-{inner})" if isinstance(node.op, ast.USub) else inner
            if isinstance(node, ast.Name):
                return name(node.id)
            if isinstance(node, ast.Constant):
                return literal(float(node.value))
            raise AssertionError(f"unvalidated node {type(node).__name__}")  # pragma: no cover

        return go(self.tree)

    def literals(self) -> list[float]:
        """The numeric literals, in order of appearance."""
        return [float(n.value) for n in ast.walk(self.tree) if isinstance(n, ast.Constant)]


def _describe(node: ast.AST) -> str:
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow):
        return "the power operator '**' (write u*u*u instead of u**3)"
    if isinstance(node, ast.BinOp):
        return f"the operator {type(node.op).__name__}"
    if isinstance(node, ast.Call):
        return "a function call"
    if isinstance(node, ast.Constant):
        return f"the constant {node.value!r} (only real numbers are allowed)"
    return f"{type(node).__name__} syntax"


def parse_expression(
    text: str, *, names: Iterable[str] | None = None, what: str = "expression"
) -> Expression:
    """Parse and validate one reaction expression (rules in the module docstring).

    ``names``: the allowed names (None: any identifier that is not a Python keyword)."""
    if not isinstance(text, str):
        raise ExpressionError(f"{what} must be a string, got {type(text).__name__}")
    try:
        tree = ast.parse(text.strip(), mode="eval").body
    except SyntaxError as exc:
        raise ExpressionError(f"{what} {text!r} is not a valid expression: {exc.msg}") from None
    allowed = None if names is None else set(names)
    used: set[str] = set()
    for node in ast.walk(tree):
        ok = False
        if isinstance(node, ast.BinOp):
            ok = type(node.op) in _BINOPS
        elif isinstance(node, ast.UnaryOp):
            ok = isinstance(node.op, (ast.USub, ast.UAdd))
        elif isinstance(node, ast.Name):
            if allowed is not None and node.id not in allowed:
                raise ExpressionError(
                    f"{what} {text!r} uses the unknown name {node.id!r}; allowed names: "
                    f"{', '.join(sorted(allowed)) or '(none)'}"
                )
            used.add(node.id)
            ok = isinstance(node.ctx, ast.Load)
        elif isinstance(node, ast.Constant):
            v = node.value
            ok = isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v)
        elif isinstance(node, (ast.operator, ast.unaryop, ast.expr_context)):
            ok = True
        if not ok:
            raise ExpressionError(
                f"{what} {text!r} uses {_describe(node)}; allowed: + - * / and unary -, "
                "parentheses, species and parameter names, numeric literals"
            )
    return Expression(text.strip(), tree, tuple(sorted(used)))


def _check_identifier(name: Any, what: str) -> str:
    if not isinstance(name, str) or not name.isidentifier() or keyword.iskeyword(name):
        raise ExpressionError(f"{what} {name!r} is not a valid identifier")
    if not name.isascii():
        raise ExpressionError(f"{what} {name!r} must be ASCII (it becomes a C identifier)")
    return name


# ---------------------------------------------------------------------------- cache folder
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


# ---------------------------------------------------------------------------- the kernel
class ReactionKernel:
    """``out_s = x_s + dt (D_s lap_s + R_s(x; p))`` for every species ``s``, pointwise.

    ``species``: names of the fields (1 or more); ``reactions``: one expression per species
    (rules in the module docstring); ``params``: the allowed parameter names (None: every
    name in the expressions that is not a species).  :attr:`param_names` lists the
    parameters the expressions actually use: a launch needs a value for each.

    ``bounds``: optional clamps of the updated values, ``{species: (low, high)}`` with
    ``None`` for no bound (e.g. ``{"v": (0.0, None)}`` keeps ``v >= 0``, as Turk 1991 does
    for Turing's model).  A clamp keeps NaN (``x < low ? low : x``)."""

    def __init__(
        self,
        species: Sequence[str],
        reactions: Sequence[str],
        params: Iterable[str] | None = None,
        *,
        bounds: Mapping[str, tuple[float | None, float | None]] | None = None,
    ):
        species = tuple(_check_identifier(s, "species name") for s in species)
        if not species:
            raise ValueError("a reaction kernel needs at least one species")
        if len(set(species)) != len(species):
            raise ValueError(f"species names must be distinct, got {species}")
        if isinstance(reactions, str) or len(reactions) != len(species):
            raise ValueError(
                f"need one reaction expression per species {species}, got {reactions!r}"
            )
        allowed = None
        if params is not None:
            params = tuple(_check_identifier(p, "parameter name") for p in params)
            clash = set(params) & set(species)
            if clash:
                raise ValueError(f"names used both as species and parameter: {sorted(clash)}")
            allowed = set(species) | set(params)
        self.species = species
        self.expressions = tuple(
            parse_expression(r, names=allowed, what=f"reaction of {s!r}")
            for s, r in zip(species, reactions, strict=True)
        )
        used = set().union(*(e.names for e in self.expressions)) - set(species)
        for p in used:
            _check_identifier(p, "parameter name")
        self.param_names: tuple[str, ...] = tuple(sorted(used))
        bounds = dict(bounds or {})
        unknown = set(bounds) - set(species)
        if unknown:
            raise ValueError(f"bounds for unknown species {sorted(unknown)}")
        self.bounds: tuple[tuple[float | None, float | None], ...] = tuple(
            tuple(None if b is None else float(b) for b in bounds.get(s, (None, None)))
            for s in species
        )
        self._numpy_fns: dict = {}

    def __repr__(self) -> str:
        pairs = zip(self.species, self.expressions, strict=True)
        rs = ", ".join(f"{s}: {e.text}" for s, e in pairs)
        return f"ReactionKernel({rs})"

    # ------------------------------------------------------------------ names
    def _py_name(self, name: str) -> str:
        return f"s_{name}" if name in self.species else f"p_{name}"

    # ------------------------------------------------------------------ NumPy
    def _numpy_source(self) -> tuple[str, list[float]]:
        """A Python lambda body per species plus its literal table (``_c[i]``)."""
        lits: list[float] = []

        def lit(v: float) -> str:
            lits.append(v)
            return f"_c[{len(lits) - 1}]"

        exprs = [e.emit(self._py_name, lit) for e in self.expressions]
        args = ", ".join([*(f"s_{s}" for s in self.species), *(f"p_{p}" for p in self.param_names)])
        src = f"lambda _c, {args}: ({', '.join(exprs)},)"
        return src, lits

    def rates(self, fields: Sequence[Any], params: Mapping[str, Any], dtype: Any = None) -> list:
        """The reaction terms ``R_s`` evaluated in NumPy (any real or complex ``dtype``;
        default: the first field's dtype, or float64).  ``fields`` in species order;
        scalars broadcast."""
        if len(fields) != len(self.species):
            raise ValueError(f"need {len(self.species)} fields {self.species}, got {len(fields)}")
        if dtype is None:
            dtype = getattr(fields[0], "dtype", np.dtype(np.float64))
        t = np.dtype(dtype).type
        fn = self._numpy_fns.get("rates")
        if fn is None:
            src, lits = self._numpy_source()
            fn = (eval(src, {"__builtins__": {}}), lits)  # noqa: S307 - validated by ast
            self._numpy_fns["rates"] = fn
        f, lits = fn
        missing = [p for p in self.param_names if p not in params]
        if missing:
            raise KeyError(f"missing reaction parameter(s) {missing}")
        c = [_literal(v, t) for v in lits]
        xs = [_as_dtype(x, t) for x in fields]
        ps = [_as_dtype(params[p], t) for p in self.param_names]
        return list(f(c, *xs, *ps))

    def step_numpy(self, xs, laps, D, dt, params) -> list[np.ndarray]:
        """The NumPy reference of one step on host arrays (``laps[s]`` None where ``D_s = 0``)."""
        ref = load_module("reaction", "reference.py")
        t = xs[0].dtype.type
        return ref.reaction_step(
            list(xs), list(laps), list(D), dt, lambda fs: self.rates(fs, params, t),
            bounds=self.bounds,
        )

    # ------------------------------------------------------------------ launch
    def launch(
        self,
        backend: Backend,
        xs: Sequence[DeviceArray],
        laps: Sequence[DeviceArray | None],
        outs: Sequence[DeviceArray],
        *,
        D: Sequence[float],
        dt: float,
        params: Mapping[str, Any],
    ) -> None:
        """One step on ``backend``: reads ``xs`` (and ``laps[s]`` where ``D[s] != 0``),
        writes ``outs`` (distinct buffers).  ``params`` maps each name of
        :attr:`param_names` to a number or a DeviceArray of the fields' shape and dtype."""
        n_s = len(self.species)
        if not (len(xs) == len(laps) == len(outs) == len(D) == n_s):
            raise ValueError(f"need {n_s} fields, Laplacians, outputs and D values")
        x0 = xs[0]
        if x0.dtype not in _REALS:
            raise TypeError(f"reaction fields must be float32 or float64, got {x0.dtype}")
        diffusing = tuple(float(d) != 0.0 for d in D)
        for what, arrs in (("field", xs), ("output", outs)):
            for a in arrs:
                _same(x0, a, what)
        for s, (lap, dif) in enumerate(zip(laps, diffusing, strict=True)):
            if dif:
                if lap is None:
                    raise ValueError(f"species {self.species[s]!r} diffuses but has no Laplacian")
                _same(x0, lap, "Laplacian")
        pvals = []
        fields = []
        for p in self.param_names:
            if p not in params:
                raise KeyError(
                    f"missing reaction parameter {p!r}; the kernel needs {self.param_names}"
                )
            v = params[p]
            if isinstance(v, DeviceArray):
                _same(x0, v, f"parameter {p!r}")
                fields.append(True)
            else:
                v = float(v)
                fields.append(False)
            pvals.append(v)
        spec = (diffusing, tuple(fields), x0.dtype)
        impl = _IMPLS.get(backend.name, _launch_fallback)
        impl(self, backend, spec, list(xs), list(laps), list(outs), list(D), float(dt), pvals)

    # ------------------------------------------------------------------ code generation
    def _signature(self, spec):
        """Kernel arguments in order: ``(kind, name)`` with kind 'in' (species buffer),
        'lap', 'out', 'pfield', 'pscalar', 'D', 'h'."""
        diffusing, fields, _ = spec
        args = [("in", f"x{i}") for i in range(len(self.species))]
        args += [("lap", f"l{i}") for i, d in enumerate(diffusing) if d]
        args += [("out", f"o{i}") for i in range(len(self.species))]
        for p, f in zip(self.param_names, fields, strict=True):
            args.append(("pfield" if f else "pscalar", f"p_{p}"))
        args += [("D", f"D{i}") for i, d in enumerate(diffusing) if d]
        args.append(("h", "h"))
        return args

    def _param_local(self, spec):
        """How an expression names each parameter in the loop body."""
        _, fields, _ = spec
        pairs = zip(self.param_names, fields, strict=True)
        return {p: (f"f_{p}" if f else f"p_{p}") for p, f in pairs}

    def opencl_source(self, spec) -> str:
        """The OpenCL C kernel ``reaction_step`` for ``spec`` (needs ``common.cl`` first)."""
        diffusing, fields, dtype = spec
        local = self._param_local(spec)
        if dtype == np.float64:
            lit = lambda v: f"({float(_literal(v, np.float64)).hex()})"  # noqa: E731 - exact
        else:
            lit = lambda v: f"({float(_literal(v, np.float32)).hex()}f)"  # noqa: E731

        def name(n: str) -> str:
            return f"s_{n}" if n in self.species else local[n]

        decl = []
        for kind, nm in self._signature(spec):
            if kind == "in" or kind == "lap" or kind == "pfield":
                decl.append(f"__global const real *RESTRICT {nm}")
            elif kind == "out":
                decl.append(f"__global real *RESTRICT {nm}")
            else:
                decl.append(f"const real {nm}")
        body = [f"const real s_{s} = x{i}[k];" for i, s in enumerate(self.species)]
        pairs = zip(self.param_names, fields, strict=True)
        body += [f"const real f_{p} = p_{p}[k];" for p, f in pairs if f]
        for i, e in enumerate(self.expressions):
            body.append(f"const real r{i} = {e.emit(name, lit)};")
        for i, (s, d) in enumerate(zip(self.species, diffusing, strict=True)):
            upd = f"(D{i} * l{i}[k] + r{i})" if d else f"r{i}"
            body.append(f"real n{i} = s_{s} + h * {upd};")
            lo, hi = self.bounds[i]
            if lo is not None:
                body.append(f"n{i} = (n{i} < {lit(lo)}) ? {lit(lo)} : n{i};")
            if hi is not None:
                body.append(f"n{i} = (n{i} > {lit(hi)}) ? {lit(hi)} : n{i};")
            body.append(f"o{i}[k] = FLUSH(n{i});")
        template = read_source("reaction", "reaction.cl")
        pairs = zip(self.species, self.expressions, strict=True)
        comment = "\n".join(f" *   R_{s} = {e.text}" for s, e in pairs)
        return (
            template.replace("@REACTIONS@", comment)
            .replace("@ARGS@", ",\n                            ".join(decl))
            .replace("@BODY@", "\n".join("        " + b for b in body))
        )

    def warp_source(self, spec) -> str:
        """The text of a Warp module with kernels ``blocks`` and ``cells`` for ``spec``."""
        diffusing, fields, dtype = spec
        helpers = load_module("reaction", "warp_kernels.py")
        local = self._param_local(spec)
        lits: list[str] = []

        def lit(v: float) -> str:
            value = float(_literal(v, np.dtype(dtype).type))
            lits.append(f"_c{len(lits)} = wp.constant(real({value!r}))")
            return f"_c{len(lits) - 1}"

        def name(n: str) -> str:
            return f"s_{n}" if n in self.species else local[n]

        exprs = [e.emit(name, lit) for e in self.expressions]
        bounds = [tuple(None if b is None else lit(b) for b in pair) for pair in self.bounds]
        return helpers.module_source(
            dtype="float64" if dtype == np.float64 else "float32",
            signature=self._signature(spec),
            species=[f"s_{s}" for s in self.species],
            fields=[p for p, f in zip(self.param_names, fields, strict=True) if f],
            rates=exprs,
            diffusing=list(diffusing),
            constants=lits,
            bounds=bounds,
            doc="\n".join(
                f"R_{s} = {e.text}" for s, e in zip(self.species, self.expressions, strict=True)
            ),
        )


def _literal(v: float, t: type):
    """A literal rounded to the dtype ``t``, subnormals flushed to 0."""
    return t(flush_subnormals(np.asarray(v, dtype=t)))


def _as_dtype(x: Any, t: type):
    if isinstance(x, np.ndarray):
        return x.astype(t, copy=False)
    if isinstance(x, DeviceArray):
        raise TypeError("rates() takes host values, not device arrays")
    return t(x)


def _same(a: DeviceArray, b: DeviceArray, what: str) -> None:
    if b.shape != a.shape or b.dtype != a.dtype:
        raise ValueError(
            f"reaction {what}: shape/dtype {b.shape} {b.dtype} does not match the fields' "
            f"{a.shape} {a.dtype}"
        )
    if b.backend is not a.backend:
        raise ValueError(f"reaction {what} lives on another backend ({b.backend.name})")


# ---------------------------------------------------------------------------- backends
def _launch_numpy(kernel, backend, spec, xs, laps, outs, D, dt, pvals):
    params = {
        p: (v.handle if isinstance(v, DeviceArray) else v)
        for p, v in zip(kernel.param_names, pvals, strict=True)
    }
    hx = [x.handle for x in xs]
    hl = [lap.handle if d else None for lap, d in zip(laps, spec[0], strict=True)]
    res = kernel.step_numpy(hx, hl, D, dt, params)
    for o, r in zip(outs, res, strict=True):
        o.handle[...] = r


def _launch_fallback(kernel, backend, spec, xs, laps, outs, D, dt, pvals):
    """Any other backend: through the host (download, NumPy reference, upload)."""
    params = {
        p: (v.numpy() if isinstance(v, DeviceArray) else v)
        for p, v in zip(kernel.param_names, pvals, strict=True)
    }
    hx = [x.numpy() for x in xs]
    hl = [lap.numpy() if d else None for lap, d in zip(laps, spec[0], strict=True)]
    for o, r in zip(outs, kernel.step_numpy(hx, hl, D, dt, params), strict=True):
        backend.copy(backend.upload(np.ascontiguousarray(r, dtype=o.dtype)), o)


# --- Warp
_WARP_LOCK = threading.Lock()
_WARP_MODULES: dict[str, Any] = {}  # source hash -> imported module
_WARP_LOADED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()  # backend -> {hash}


def _warp_module(kernel: ReactionKernel, backend, spec):
    cache = kernel._numpy_fns.setdefault("warp", {})
    mod = cache.get(spec)
    if mod is None:
        src = kernel.warp_source(spec)
        digest = hashlib.sha256(src.encode()).hexdigest()[:24]
        with _WARP_LOCK:
            mod = _WARP_MODULES.get(digest)
            if mod is None:
                name = f"rdgpu_reaction_{digest}"
                path = cache_dir() / "warp" / f"{name}.py"
                _write_atomic(path, src)
                loader_spec = importlib.util.spec_from_file_location(name, path)
                mod = importlib.util.module_from_spec(loader_spec)
                sys.modules[name] = mod
                try:
                    loader_spec.loader.exec_module(mod)
                except BaseException:
                    sys.modules.pop(name, None)
                    raise
                mod._rdgpu_digest = digest
                _WARP_MODULES[digest] = mod
        cache[spec] = mod
    loaded = _WARP_LOADED.setdefault(backend, set())
    if mod._rdgpu_digest not in loaded:
        from .backends.warp_backend import _quiet

        wp = backend._wp
        with _WARP_LOCK, _quiet(wp):
            wp.load_module(mod, device=backend._dev)
        loaded.add(mod._rdgpu_digest)
    return mod


def _launch_warp(kernel, backend, spec, xs, laps, outs, D, dt, pvals):
    from .backends.warp_backend import BLOCK

    n = xs[0].size
    if n == 0:
        return
    mod = _warp_module(kernel, backend, spec)
    t = spec[2].type
    flat = backend._flat
    args = [flat(x) for x in xs]
    args += [flat(lap) for lap, d in zip(laps, spec[0], strict=True) if d]
    args += [flat(o) for o in outs]
    args += [flat(v) if isinstance(v, DeviceArray) else t(v) for v in pvals]
    args += [t(d) for d, dif in zip(D, spec[0], strict=True) if dif]
    args.append(t(dt))
    if backend._cells:
        backend._launch(mod.cells, n, args, 0)
    else:
        backend._run_split(mod.blocks, -(-n // BLOCK), n, [*args, BLOCK])


# --- OpenCL
_CL_KERNELS: dict[tuple, Any] = {}
_CL_LOCK = threading.Lock()


def _opencl_kernel(kernel: ReactionKernel, backend, spec):
    cache = kernel._numpy_fns.setdefault("opencl", {})
    ck = (id(backend.context), backend.context.int_ptr, tuple(backend._options), spec)
    k = cache.get(ck)
    if k is not None:
        return k
    backend._check_real(spec[2])
    src = kernel.opencl_source(spec)
    key = (backend.context.int_ptr, tuple(backend._options), spec[2].char, src)
    with _CL_LOCK:
        k = _CL_KERNELS.get(key)
        if k is None:
            cl = backend._cl
            options = [f"-D REAL_IS_DOUBLE={int(spec[2] == np.float64)}", *backend._options]
            full = '#line 1 "common.cl"\n' + read_source("", "common.cl") + "\n"
            full += '#line 1 "reaction/reaction.cl (generated)"\n' + src
            program = cl.Program(backend.context, full).build(options=options)
            k = cl.Kernel(program, "reaction_step")
            codes = []
            for kind, _ in kernel._signature(spec):
                codes.append(None if kind in ("in", "lap", "out", "pfield") else spec[2])
            k.set_scalar_arg_dtypes([*codes, np.int64, np.int64])
            _CL_KERNELS[key] = k
    cache[ck] = k
    return k


def _launch_opencl(kernel, backend, spec, xs, laps, outs, D, dt, pvals):
    n = xs[0].size
    if n == 0:
        return
    k = _opencl_kernel(kernel, backend, spec)
    t = spec[2].type
    args = [x.handle for x in xs]
    args += [lap.handle for lap, d in zip(laps, spec[0], strict=True) if d]
    args += [o.handle for o in outs]
    args += [v.handle if isinstance(v, DeviceArray) else t(v) for v in pvals]
    args += [t(d) for d, dif in zip(D, spec[0], strict=True) if dif]
    args.append(t(dt))
    if backend.layout == "row":
        chunk, group = OPENCL_CHUNK, 1
    else:
        chunk, group = 1, backend.col_stride
    items = -(-n // chunk)
    k.set_args(*args, np.int64(n), np.int64(chunk))
    gsize = (-(-items // group) * group,)
    backend._cl.enqueue_nd_range_kernel(backend.queue, k, gsize, (group,))


_IMPLS = {"numpy": _launch_numpy, "warp": _launch_warp, "opencl": _launch_opencl}
