"""Temporal blocking: K explicit Euler steps of a model per pass over the grid (OpenCL, CPU).

A single step of a fused model kernel reads and writes every field once, so on a grid
larger than the last-level cache its rate is bounded by memory bandwidth (the "roofline":
bandwidth ÷ bytes per cell).  A blocked pass (``kernels/model/blocked.cl``) advances bands
of ``rows`` grid rows by ``steps`` steps each, keeping the intermediate steps in a small
per-work-item scratch area that stays in the core's cache, so the grid crosses memory once
per ``steps`` steps.  Every value is computed by the step kernel's own cell body (generated
by :func:`rdgpu.models.compiler.opencl_cell`), in the same order, so a pass is bit for bit
``steps`` single steps.

Eligible (:func:`why_not`): a :class:`~rdgpu.models.integrators.ModelStepper` with
``method="euler"`` and no bilaplacian pre-pass, on a 2-D grid (compact or isotropic
stencil, every boundary kind), on the OpenCL backend in its row layout (CPU devices);
scalar parameters, parameter fields and parameters that are expressions of ``t`` (the
pass gets the ``steps`` times, computed on the host as a single step computes its time).

``ModelStepper(..., block_steps=K)`` (``Simulation(..., options={"block_steps": K})``):
``None`` (default) blocks automatically (:func:`auto_steps`), ``1`` never, ``K >= 2``
always (an error where the stepper is not eligible).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from rdgpu.backends.base import DeviceArray
from rdgpu.core.hardware import cache_sizes
from rdgpu.families import read_source
from rdgpu.ir.names import ident
from rdgpu.models.compiler import (
    PerMember,
    Program,
    Target,
    _grid_coefficients,
    _member_lines,
    _signature,
    arguments,
    opencl_arg_dtypes,
    opencl_cell,
    opencl_head,
    opencl_kernel,
    opencl_program,
)

__all__ = ["AUTO_STEPS", "BlockedEuler", "auto_steps", "cache_sizes", "fitting_steps",
           "last_level_cache", "why_not"]

#: the most steps of a pass when blocking is on automatically (perf/blocking.py)
AUTO_STEPS = 16
#: grid kinds a pass can run on (the bands are rows of a 2-D grid)
KINDS = ("grid2", "grid2iso")
#: the default band height (perf/blocking.py: 512 rows ran ~10% faster than 256, ~25%
#: faster than 64 at K = 16; a band recomputes 2·(K − 1) halo rows per level)
ROWS = 512
#: work-items per compute unit: each has its own scratch and takes every items-th band
ITEMS_PER_UNIT = 2


# ---------------------------------------------------------------------------- eligibility
def why_not(stepper: Any) -> str | None:
    """Why ``stepper`` cannot run blocked passes, or None when it can."""
    be = stepper.backend
    if be.name != "opencl":
        return f"the {be.name} backend has no blocked kernel (only opencl has)"
    if getattr(be, "layout", None) != "row":
        return (f"the OpenCL backend runs the {be.layout} layout; blocked passes need the row "
                "layout (CPU devices)")
    if stepper.method != "euler":
        return f"method {stepper.method!r} is not a single-pass step; only 'euler' is"
    if stepper._pre is not None:
        return "the equations take a bilaplacian, which needs a pre-pass each step"
    kind = stepper.target.kind
    if kind not in KINDS:
        return f"the domain is a {kind}; blocked passes run on 2-D grids"
    program: Program = stepper._euler
    if tuple(o.name for o in program.outputs) != program.inputs:
        return "the step's outputs are not its inputs"
    return None


def last_level_cache() -> int | None:
    """Bytes of the CPU's last-level cache (:func:`cache_sizes`), or None if unknown."""
    sizes = cache_sizes()
    return sizes[max(sizes)] if sizes else None


def auto_steps(stepper: Any) -> int:
    """The steps of a pass when ``block_steps`` is None: 1 (off) unless the stepper is
    eligible, on a CPU OpenCL device, and its fields (the state read and written, the
    parameter fields) exceed the last-level cache; then :func:`fitting_steps`."""
    if why_not(stepper) is not None:
        return 1
    be = stepper.backend
    if not be.cl_device.type & be._cl.device_type.CPU:
        return 1
    llc = last_level_cache()
    fields = sum(isinstance(v, DeviceArray) for v in stepper._device_params.values())
    cells = math.prod(stepper.shape)
    working = (2 * len(stepper.species) + fields) * cells * stepper.dtype.itemsize
    return fitting_steps(stepper) if llc is not None and working > llc else 1


def fitting_steps(stepper: Any) -> int:
    """The most steps, up to :data:`AUTO_STEPS`, whose scratch rings (``steps − 1`` levels of
    3 rows per species) fit in one core's L2 cache (1 MiB where unknown); 1 where not even
    one level fits.  perf/blocking.py: past that size the rate falls (Gray-Scott float32,
    rows of 4096: K = 11 fits, K = 16 runs ~20% slower, K = 22 ~40%)."""
    l2 = cache_sizes().get(2, 1 << 20)
    level = len(stepper.species) * 3 * stepper.shape[-1] * stepper.dtype.itemsize
    k = 1 + l2 // max(level, 1)
    # a band recomputes K − 1 halo rows per side and level: keep that under ~1/8 of a
    # plane's rows (an ensemble of 64² members: K = 8 ran ~10% faster than K = 16)
    k = min(k, stepper.target.domain.shape3[1] // 8)
    return min(AUTO_STEPS, k) if k >= 2 else 1


def check_steps(block_steps: Any) -> int | None:
    """``block_steps`` as an int >= 1, or None."""
    if block_steps is None:
        return None
    if isinstance(block_steps, bool) or not isinstance(block_steps, (int, np.integer)) \
            or block_steps < 1:
        raise ValueError(f"block_steps must be None (automatic) or an integer >= 1 (1: off), "
                         f"got {block_steps!r}")
    return int(block_steps)


def setup(stepper: Any, block_steps: Any, rows: int | None = None) -> BlockedEuler | None:
    """The :class:`BlockedEuler` of ``stepper`` for ``block_steps`` (module doc), or None
    when it steps one step at a time."""
    k = check_steps(block_steps)
    if k is None:
        k = auto_steps(stepper)
    elif k > 1:
        reason = why_not(stepper)
        if reason is not None:
            raise ValueError(f"block_steps={k}: {reason}; use block_steps=1 (off) or None "
                             "(automatic)")
    return BlockedEuler(stepper, k, rows) if k > 1 else None


# ---------------------------------------------------------------------------- kernel
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
    call = [rename.get(nm, nm) for _, nm in _signature(program, fields, member)]
    text = read_source("model", "blocked.cl")
    return opencl_head(program) + (
        text.replace("@ARGS@", ",\n        ".join(decl))
        .replace("@NS@", str(len(program.inputs)))
        .replace("@SELECT@", "\n".join(" " * 16 + line for line in select))
        .replace("@CALL@", ", ".join(call))
        .replace("@ROW@", "\n".join("    " + line for line in _member_lines(member)))
        .replace("@CELL@", " \\\n".join("        " + b for b in body))
    )


class BlockedEuler:
    """Blocked passes of a :class:`~rdgpu.models.integrators.ModelStepper`'s Euler step:
    ``steps`` steps per pass in bands of ``rows`` grid rows (default: :meth:`default_rows`)."""

    def __init__(self, stepper: Any, steps: int, rows: int | None = None):
        reason = why_not(stepper)
        if reason is not None:
            raise ValueError(f"no blocked passes: {reason}")
        if steps < 2:
            raise ValueError(f"a blocked pass takes >= 2 steps, got {steps}")
        self.stepper = stepper
        self.steps = int(steps)
        self.target: Target = stepper.target
        nz, ny, nx = self.target.domain.shape3
        # one plane per ensemble member (a 2-D grid has nz = 1)
        self.planes, self.ny, self.nx = nz * self.target.members, ny, nx
        self.rows = self.default_rows() if rows is None else int(rows)
        if self.rows < 1:
            raise ValueError(f"rows must be >= 1, got {rows}")
        be = stepper.backend
        bands = self.planes * -(-ny // self.rows)
        units = max(1, int(be.cl_device.max_compute_units))
        self.items = max(1, min(bands, ITEMS_PER_UNIT * units))
        ns = len(stepper.species)
        per_item = (self.steps - 1) * ns * 3 * max(nx, 1)
        self._scratch = be.empty((max(1, self.items * per_item),), stepper.dtype)
        self._times = be.empty((self.steps,), stepper.dtype)
        self._uses_time = bool(stepper._euler.refs("time"))
        self._last_t0: int | None = None

    def default_rows(self) -> int:
        """Band height: :data:`ROWS` rows, fewer where that leaves a work-item without a
        band."""
        units = max(1, int(self.stepper.backend.cl_device.max_compute_units))
        return max(1, min(ROWS, -(-self.ny * self.planes // (ITEMS_PER_UNIT * units))))

    def _kernel(self, fields: frozenset[str], member: frozenset[str]):
        program, target = self.stepper._euler, self.target

        def make():
            src = blocked_source(program, target.kind, fields, target.dtype, member)
            k = target.backend._cl.Kernel(opencl_program(target, src, "model/blocked.cl"),
                                          "rd_blocked")
            dt = target.dtype
            k.set_scalar_arg_dtypes([*opencl_arg_dtypes(program, fields, dt, member), None, None,
                                     np.int32, np.int32, np.int32, np.int32, dt, np.int32, dt,
                                     dt, dt, dt, dt, np.int32, np.int32, np.int32])
            return k

        return opencl_kernel(program, target, fields, "rd_blocked", make, member)

    def run(self, x: list[DeviceArray], y: list[DeviceArray], steps_done: int) -> None:
        """One pass: ``y`` = the state ``steps`` Euler steps after ``x``, which is at step
        ``steps_done`` (time ``steps_done·dt``)."""
        st = self.stepper
        program, target = st._euler, self.target
        if self.nx == 0 or self.ny == 0 or self.planes == 0:
            return
        be = st.backend
        t = target.dtype.type
        if self._uses_time and self._last_t0 != steps_done:
            times = np.array([t((steps_done + k) * st.dt) for k in range(self.steps)],
                             dtype=target.dtype)
            # the in-order queue runs the copy after the previous pass (pyopencl keeps
            # ``times`` alive until it is done)
            be._cl.enqueue_copy(be.queue, self._times.handle, times, is_blocking=False)
            self._last_t0 = steps_done
        fields = frozenset(p for p in program.refs("param")
                           if isinstance(st._device_params[p], DeviceArray))
        member = frozenset(p for p in program.refs("param")
                           if isinstance(st._device_params[p], PerMember))
        args = arguments(program, target, x, y, st._device_params, fields,
                         {"_h": st.dt, "_a": 0.0, "_b": 1.0}, steps_done * st.dt,
                         member=member)
        b = target.domain.bcs
        dx, dy, _ = target.spacing()
        cx, cy, _ = _grid_coefficients(target)
        args += [self._times.handle, self._scratch.handle, self.nx, self.ny, self.planes,
                 b.x.kind, b.x.value, b.y.kind, b.y.value, cx, cy, dx, dy, self.steps,
                 self.rows, self.items]
        k = self._kernel(fields, member)
        k.set_args(*args)
        be._cl.enqueue_nd_range_kernel(be.queue, k, (self.items,), (1,))
