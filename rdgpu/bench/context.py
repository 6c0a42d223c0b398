"""What every row group of ``rdgpu bench`` is given (`Context`): the backends by label,
each device's memory, the effective LLC, the square grid edges of the kernel rows, the
timing per row, whether the run is ``--quick`` (tiny sizes) or ``--full`` (the slowest rows
too), the machine record and where progress goes; and the line naming the machine a
table ran on."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

from rdgpu.backends.base import Backend
from rdgpu.bench.machine import MiB

__all__ = ["Context", "kernel_sizes"]


def _round(x: float, quantum: int, up: bool) -> int:
    q = x / quantum
    return quantum * max(1, int(math.ceil(q) if up else math.floor(q)))


def kernel_sizes(llc: int, small_bytes: int, large_bytes: int) -> list[int]:
    """Three square grid edges (multiples of 64) for kernels moving ``small_bytes`` to
    ``large_bytes`` bytes per cell: the working set of the most demanding kernel at most a
    quarter of ``llc`` (the measured effective LLC), that of the least demanding at least
    4x ``llc``, and their geometric mean."""
    small = _round(math.sqrt(llc / 4 / large_bytes), 64, up=False)
    large = _round(math.sqrt(4 * llc / small_bytes), 64, up=True)
    mid = _round(math.sqrt(small * large), 64, up=True)
    return sorted({small, mid, large})


@dataclass
class Context:
    """The run as a row group sees it (module docstring)."""

    backends: dict[str, Backend]
    memory: dict
    llc: int
    sizes: list[int]
    seconds: float
    machine: dict
    quick: bool = False
    full: bool = False
    say: Callable[[str], None] = field(default=print)

    def ran_on(self, labels: list[str] | None = None) -> str:
        """``Ran on: <CPU>, <cores> cores (triad ..., LLC ...); <label>: <device>; ...``
        for the backends ``labels`` (default: all)."""
        m = self.machine
        cpu = self.memory["cpu"]
        parts = [f"Ran on: {m['cpu']}, {m['cores']} cores (triad {cpu['GBps']:.1f} GB/s "
                 f"out of cache, effective LLC {cpu['llc'] / MiB:.0f} MiB)"]
        for label in labels if labels is not None else list(self.backends):
            if label in self.backends:
                mem = self.memory.get(label)
                extra = (f" (L2 {mem['llc'] / MiB:.0f} MiB, {mem['kind']} {mem['GBps']:.0f} "
                         "GB/s)" if mem else "")
                parts.append(f"{label}: {self.backends[label].device}{extra}")
        return "; ".join(parts) + "."
