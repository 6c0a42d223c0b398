"""A domain bound to a backend and a dtype (`Target`), and the interface of a compiled
fused pass (`FusedPass`): what the model layer hands a backend to run a
`rdgpu.ir.program.Program`.

``Backend.fused_pass(program, target, fields, member)`` returns a `FusedPass`; its
`FusedPass.launch` runs one pass.  `HostFusedPass` runs a program through
its NumPy semantics (`rdgpu.ir.reference.run_numpy`) with a download and an upload:
a backend without kernels of its own may return it, explicitly; nothing falls back to it.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.backends.base import Backend, DeviceArray, DeviceCSR
from rdgpu.ir.layout import Layout
from rdgpu.ir.program import METRIC_COEFFICIENTS, REALS, PerMember, Program
from rdgpu.ir.reference import run_numpy
from rdgpu.ir.stencils import STENCIL_KINDS, check_stencil

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain

__all__ = ["SPAN_MAX_ROW", "BlockedPass", "FusedPass", "HostFusedPass", "Target", "arguments",
           "flat_rows", "host_params", "spans"]


class Target(Layout):
    """A domain bound to a backend and dtype: what a launch needs besides the buffers
    (`rdgpu.ir.layout.Layout` for the host side).

    ``csr``: the mesh Laplacian on the device; ``metric``: a graph surface's coefficients
    ``ex, ny, bx, w`` (DeviceArrays ``[ny, nx]``); ``coords``: the coordinates uploaded so
    far (``"x"`` -> DeviceArray).  ``backend`` may be None for host data only."""

    def __init__(self, domain: Domain, backend: Backend | None, dtype: Any,
                 csr: DeviceCSR | None = None, stencil: str = "compact",
                 coords: dict[str, DeviceArray] | None = None,
                 host: dict[str, Any] | None = None, members: int = 1,
                 metric: tuple[DeviceArray, ...] = ()):
        super().__init__(domain, dtype, stencil=stencil, members=members, host=host)
        self.backend = backend
        self.csr = csr
        self.coords: dict[str, DeviceArray] = {} if coords is None else coords
        self.metric = metric

    @classmethod
    def bind(cls, domain: Domain, backend: Backend, dtype: Any,
             stencil: str = "compact", members: int = 1) -> Target:
        dtype = np.dtype(dtype)
        if dtype not in REALS:
            raise TypeError(f"dtype must be float32 or float64, got {dtype}")
        check_stencil(domain, stencil)
        if int(members) < 1:
            raise ValueError(f"members must be >= 1, got {members}")
        t = cls(domain, backend, dtype, stencil=stencil, members=int(members))
        if domain.kind == "graph-surface":
            c = domain.coefficients_as(dtype)
            t.metric = tuple(backend.upload(c[k]) for k in METRIC_COEFFICIENTS)
        elif domain.kind == "mesh":
            t.csr = backend.upload_csr(domain.laplacian, dtype)
        return t

    def device_coordinate(self, name: str) -> DeviceArray:
        if name not in self.coords:
            self.coords[name] = self.backend.upload(self.coordinate(name))
        return self.coords[name]


class FusedPass(ABC):
    """One program compiled for one backend (and stencil kind, parameter fields and dtype)."""

    @abstractmethod
    def launch(self, target: Target, inputs: Sequence[DeviceArray],
               outputs: Sequence[DeviceArray], params: Mapping[str, Any],
               fields: frozenset[str], member: frozenset[str],
               scalars: Mapping[str, float], time: float) -> None:
        """One pass: ``inputs``/``outputs`` in the program's order, each of
        ``target.field_shape``; ``params`` maps each parameter to a number, a DeviceArray
        (the names in ``fields``) or a `rdgpu.ir.program.PerMember` (``member``);
        ``scalars`` the builtins (``_h``...)."""

    def bind(self, target: Target, inputs: Sequence[DeviceArray],
             outputs: Sequence[DeviceArray], params: Mapping[str, Any],
             fields: frozenset[str], member: frozenset[str],
             scalars: Mapping[str, float]) -> Callable[[float], None]:
        """`launch` with everything but the time fixed: ``run(time)`` is one pass.  The
        caller keeps the arrays and ``params`` unchanged while it holds ``run`` and calls
        it from one thread at a time; a backend may then set the kernel's arguments once
        (this default launches in full each time)."""

        def run(time: float) -> None:
            self.launch(target, inputs, outputs, params, fields, member, scalars, time)

        return run


class BlockedPass(ABC):
    """``steps`` explicit Euler steps of one program per pass over a 2-D grid, in bands of
    rows (temporal blocking, `rdgpu.integrators.blocking`; ``Backend.blocked_pass``)."""

    @abstractmethod
    def run(self, x: Sequence[DeviceArray], y: Sequence[DeviceArray],
            params: Mapping[str, Any], fields: frozenset[str], member: frozenset[str],
            scalars: Mapping[str, float], time: float, times: np.ndarray | None) -> None:
        """One pass from ``x`` (at ``time``) into ``y``; ``times``: the ``steps`` step times
        where they changed since the last pass (else None)."""


def host_params(program: Program, params: Mapping[str, Any], get) -> dict[str, Any]:
    """The program's parameters with each device array replaced by ``get(array)``."""
    out = {}
    refs = program.refs("param")
    for p, v in params.items():
        if p not in refs:
            continue
        if isinstance(v, PerMember):
            out[p] = PerMember(get(v.values))
        else:
            out[p] = get(v) if isinstance(v, DeviceArray) else v
    return out


class HostFusedPass(FusedPass):
    """A program run through its NumPy semantics: inputs downloaded, outputs uploaded (for
    a backend that has no kernels of its own; it must return this itself)."""

    def __init__(self, program: Program):
        self.program = program

    def launch(self, target, inputs, outputs, params, fields, member, scalars, time):
        program, be = self.program, target.backend
        host = {n: a.numpy() for n, a in zip(program.inputs, inputs, strict=True)}
        res = run_numpy(program, target, host, host_params(program, params, be.download),
                        scalars, time)
        for o, buf in zip(program.outputs, outputs, strict=True):
            be.copy(be.upload(np.ascontiguousarray(res[o.name].reshape(buf.shape))), buf)


def _handle(a: DeviceArray) -> Any:
    return a.handle


def arguments(program: Program, target: Target, inputs: Sequence[DeviceArray],
              outputs: Sequence[DeviceArray], params: Mapping[str, Any],
              fields: frozenset[str], scalars: Mapping[str, float], time: float,
              flat=_handle, member: frozenset[str] = frozenset()) -> list[Any]:
    """The kernel arguments of `rdgpu.ir.program.signature`: buffers through
    ``flat``, scalars in the target's dtype."""
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


def flat_rows(program: Program, kind: str) -> bool:
    """Whether the grid kernels of ``program`` on stencil kind ``kind`` may walk spans of
    interior rows as one flat loop (OpenCL ``rd_span``, Warp ``spans``, the 3-D blocked
    planes): not on meshes, metric grids or programs reading the x or y coordinate (a flat
    loop has no column or row)."""
    if kind == "mesh" or STENCIL_KINDS[kind].form == "metric":
        return False
    return not {"x", "y"} & set(program.refs("coord"))


#: the longest rows the flat-span kernels take: longer rows vectorise as well one by one
#: (perf/results/row_length.md: rows of 32-192 cells ran 1.0-2.0x faster in spans, rows of
#: 960 and 9600 no faster or slower)
SPAN_MAX_ROW = 256


def spans(nx: int, ny: int, planes: int, cells: int, units: int) -> tuple[int, int]:
    """``(span, count)``: how the flat-span grid kernels (OpenCL ``rd_span``, Warp
    ``spans``) cut the ``ny - 2`` interior rows of each of ``planes`` planes of ``ny × nx``
    cells: spans of ``span`` rows, ``count`` per plane, about ``cells`` cells each but at
    least four spans per unit of parallel work (``units``) where there are rows enough.
    ``(0, 0)``: the row kernel (rows or columns fewer than 3, rows longer than
    `SPAN_MAX_ROW`, or ``cells`` <= 0)."""
    if nx < 3 or ny < 3 or nx > SPAN_MAX_ROW or cells <= 0:
        return 0, 0
    interior = ny - 2
    span = min(interior, max(1, -(-cells // nx)))
    count = -(-interior // span)
    while span > 1 and planes * count < 4 * units:
        span = max(1, span // 2)
        count = -(-interior // span)
    return span, count
