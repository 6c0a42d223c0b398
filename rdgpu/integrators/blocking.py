"""Temporal blocking: K explicit Euler steps of a model per pass over the grid (OpenCL, CPU).

A single step of a fused model kernel reads and writes every field once, so on a grid
larger than the last-level cache its rate is bounded by memory bandwidth (the "roofline":
bandwidth ÷ bytes per cell).  A blocked pass (``families/model/blocked.cl``) advances bands
of ``rows`` grid rows by ``steps`` steps each, keeping the intermediate steps in a small
per-work-item scratch area that stays in the core's cache, so the grid crosses memory once
per ``steps`` steps.  Every value is computed by the step kernel's own cell body (generated
by `rdgpu.backends.opencl_codegen.opencl_cell`), in the same order, so a pass is bit for bit
``steps`` single steps.

Eligible (`why_not`): a `rdgpu.integrators.ModelStepper` with
``method="euler"`` and no bilaplacian pre-pass, on a 2-D grid (compact or isotropic
stencil, every boundary kind), on the OpenCL backend in its row layout (CPU devices);
scalar parameters, parameter fields and parameters that are expressions of ``t`` (the
pass gets the ``steps`` times, computed on the host as a single step computes its time).

``ModelStepper(..., block_steps=K)`` (``Simulation(..., options={"block_steps": K})``):
``None`` (default) blocks automatically (`auto_steps`), ``1`` never, ``K >= 2``
always (an error where the stepper is not eligible).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from rdgpu.backends.base import DeviceArray
from rdgpu.backends.target import Target
from rdgpu.core.hardware import cache_sizes
from rdgpu.ir.program import PerMember, Program

__all__ = ["AUTO_STEPS", "BlockedEuler", "auto_steps", "cache_sizes", "fitting_steps",
           "last_level_cache", "why_not"]

#: the most steps of a pass when blocking is on automatically (`rdgpu bench --rows blocking`)
AUTO_STEPS = 16
#: grid kinds a pass can run on (the bands are rows of a 2-D grid)
KINDS = ("grid2", "grid2iso")
#: the default band height (`rdgpu bench --rows blocking`: 512 rows ran ~10% faster than 256, ~25%
#: faster than 64 at K = 16; a band recomputes 2·(K − 1) halo rows per level)
ROWS = 512
#: work-items per compute unit: each has its own scratch and takes every items-th band
ITEMS_PER_UNIT = 2


# ---------------------------------------------------------------------------- eligibility
def why_not(stepper: Any) -> str | None:
    """Why ``stepper`` cannot run blocked passes, or None when it can."""
    reason = stepper.backend.blocked_pass_support()
    if reason is not None:
        return reason
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
    """Bytes of the CPU's last-level cache (`cache_sizes`), or None if unknown."""
    sizes = cache_sizes()
    return sizes[max(sizes)] if sizes else None


def auto_steps(stepper: Any) -> int:
    """The steps of a pass when ``block_steps`` is None: 1 (off) unless the stepper is
    eligible, on a CPU OpenCL device, and its fields (the state read and written, the
    parameter fields) exceed the last-level cache; then `fitting_steps`."""
    if why_not(stepper) is not None:
        return 1
    if not stepper.backend.on_cpu:
        return 1
    llc = last_level_cache()
    fields = sum(isinstance(v, DeviceArray) for v in stepper._device_params.values())
    cells = math.prod(stepper.shape)
    working = (2 * len(stepper.species) + fields) * cells * stepper.dtype.itemsize
    return fitting_steps(stepper) if llc is not None and working > llc else 1


def fitting_steps(stepper: Any) -> int:
    """The most steps, up to `AUTO_STEPS`, whose scratch rings (``steps − 1`` levels of
    3 rows per species) fit in one core's L2 cache (1 MiB where unknown); 1 where not even
    one level fits: past that size the rate falls (`rdgpu bench --rows blocking`;
    docs/models.md, temporal blocking)."""
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
    """The `BlockedEuler` of ``stepper`` for ``block_steps`` (module doc), or None
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


# ---------------------------------------------------------------------------- passes
class BlockedEuler:
    """Blocked passes of a `rdgpu.integrators.ModelStepper`'s Euler step:
    ``steps`` steps per pass in bands of ``rows`` grid rows (default: `default_rows`),
    run by the backend's blocked pass (``Backend.blocked_pass``)."""

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
        bands = self.planes * -(-ny // self.rows)
        units = stepper.backend.compute_units
        self.items = max(1, min(bands, ITEMS_PER_UNIT * units))
        program: Program = stepper._euler
        self._pass = stepper.backend.blocked_pass(program, self.target, steps=self.steps,
                                                  rows=self.rows, items=self.items)
        self._uses_time = bool(program.refs("time"))
        self._last_t0: int | None = None

    def default_rows(self) -> int:
        """Band height: `ROWS` rows, fewer where that leaves a work-item without a
        band."""
        units = self.stepper.backend.compute_units
        return max(1, min(ROWS, -(-self.ny * self.planes // (ITEMS_PER_UNIT * units))))

    def run(self, x: list[DeviceArray], y: list[DeviceArray], steps_done: int) -> None:
        """One pass: ``y`` = the state ``steps`` Euler steps after ``x``, which is at step
        ``steps_done`` (time ``steps_done·dt``)."""
        st = self.stepper
        program, target = st._euler, self.target
        times = None
        if self._uses_time and self._last_t0 != steps_done:
            t = target.dtype.type
            times = np.array([t((steps_done + k) * st.dt) for k in range(self.steps)],
                             dtype=target.dtype)
            self._last_t0 = steps_done
        fields = frozenset(p for p in program.refs("param")
                           if isinstance(st._device_params[p], DeviceArray))
        member = frozenset(p for p in program.refs("param")
                           if isinstance(st._device_params[p], PerMember))
        self._pass.run(x, y, st._device_params, fields, member, {"_h": st.dt, "_a": 0.0, "_b": 1.0},
                       steps_done * st.dt, times)
