"""The row groups of ``rdgpu bench`` beyond the peers (`GROUPS`), what each is given
(`GroupOptions`; `quick_options` for ``--quick``: tiny sizes) and `run_groups`, which
builds the `Context` (the backends, each device's memory, the kernel sizes from the
measured cache) and runs them in order.  Each group's result in the record:
``{"rows": [...], "seconds": wall time, "markdown": [lines]}`` (its section of bench.md,
written as it ran so that it names the machine and devices); a group whose optional
package is missing (the mesh rows' trimesh) has no rows and says so."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

from rdgpu.bench import rows_growth, rows_kernels, rows_mesh, rows_models, rows_states
from rdgpu.bench.context import Context, kernel_sizes
from rdgpu.bench.devices import device_memory, resolve

__all__ = ["GROUPS", "GroupOptions", "TITLES", "quick_options", "run_groups"]

#: every row group, in the order they run (``peers``: `rdgpu.bench.run`)
GROUPS = ("peers", "kernels", "mesh", "models", "ensembles", "blocking", "growth",
          "real-states")
TITLES = {"kernels": "Grid kernels", "mesh": "Mesh kernels", "models": "Models",
          "ensembles": "Ensembles", "blocking": "Temporal blocking",
          "growth": "Growth: DLA and walkers", "real-states": "Real states"}


@dataclass
class GroupOptions:
    """The sizes and counts of the row groups (each module's docstring says what they
    mean); ``kernel_sizes`` None: from the measured cache; ``model_size`` None: the middle
    kernel size; ``numpy``: NumPy runs too, the baseline of the ``× NumPy`` columns."""

    numpy: bool = True
    kernels: list[str] = field(default_factory=lambda: list(rows_kernels.BYTES_PER_CELL))
    kernel_sizes: list[int] | None = None
    mesh_vertices: int = rows_mesh.DEFAULT_VERTICES
    model_size: int | None = None
    members: int = 1024
    member_size: int = 64
    numpy_members: int = 64
    sweep_members: int = 256
    sweep_steps: int = 500
    dla_sizes: list[int] = field(default_factory=lambda: [256, 512])
    dla_steps: int = 12
    walker_size: int = 256
    walkers: int = 1024
    walker_steps: int = 1500
    real_size: int = 1024
    real_subdivisions: int = 6
    early: int = 200
    late: int = 2000
    block_factor: float = 4.0
    block_nx: int = 2048
    block_ny: int | None = None
    block_steps: list[int] = field(default_factory=lambda: [2, 4, 8, 12, 16])
    block_rows: list[int] = field(default_factory=lambda: [64, 256])


def quick_options() -> GroupOptions:
    """Tiny sizes: every group in seconds (``--quick``, the tests)."""
    return GroupOptions(kernel_sizes=list(rows_kernels.QUICK_SIZES),
                        mesh_vertices=rows_mesh.QUICK_VERTICES, model_size=64, members=16,
                        member_size=32, numpy_members=4, sweep_members=4, sweep_steps=4,
                        dla_sizes=[32], dla_steps=1, walker_size=32, walkers=16,
                        walker_steps=40, real_size=64, real_subdivisions=2, early=4, late=8,
                        block_nx=128, block_ny=64, block_steps=[2, 4], block_rows=[32])


def _sizes(g: GroupOptions, memory: dict) -> list[int]:
    if g.kernel_sizes:
        return list(g.kernel_sizes)
    per_cell = [rows_kernels.BYTES_PER_CELL[k] for k in g.kernels] or [16]
    return kernel_sizes(max(m["llc"] for m in memory.values()), min(per_cell), max(per_cell))


def _blocking(ctx: Context, g: GroupOptions) -> list[dict]:
    if g.block_ny is not None:
        shape = small = (g.block_ny, g.block_nx)
    else:
        shape, small = rows_states.blocking_shapes(ctx.llc, g.block_factor, g.block_nx)
    return rows_states.blocking(ctx, shape, small, g.block_steps, g.block_rows)


_RUN: dict[str, Callable[[Context, GroupOptions], list[dict]]] = {
    "kernels": lambda ctx, g: rows_kernels.run(ctx, g.kernels),
    "mesh": lambda ctx, g: rows_mesh.run(ctx, g.mesh_vertices),
    "models": lambda ctx, g: rows_models.models(
        ctx, g.model_size or sorted(ctx.sizes)[len(ctx.sizes) // 2]),
    "ensembles": lambda ctx, g: rows_models.ensembles(
        ctx, g.members, g.member_size, g.numpy_members, g.sweep_members, g.sweep_steps),
    "blocking": _blocking,
    "growth": lambda ctx, g: rows_growth.run(ctx, g.dla_sizes, g.dla_steps, g.walker_size,
                                             g.walkers, g.walker_steps),
    "real-states": lambda ctx, g: rows_states.real_states(ctx, g.real_size,
                                                          g.real_subdivisions, g.early,
                                                          g.late),
}
_MARKDOWN: dict[str, Callable[[list[dict], Context], list[str]]] = {
    "kernels": rows_kernels.markdown, "mesh": rows_mesh.markdown,
    "models": rows_models.model_markdown, "ensembles": rows_models.ensemble_markdown,
    "blocking": rows_states.blocking_markdown, "growth": rows_growth.markdown,
    "real-states": rows_states.real_states_markdown,
}


def run_groups(names: list[str], backends: list[str], g: GroupOptions, machine: dict,
               llc: int, bandwidth: float, seconds: float, *, quick: bool = False,
               full: bool = False, say: Callable[[str], None] = print) -> dict:
    """Run the groups ``names`` (of `GROUPS`, ``peers`` left to `rdgpu.bench.run`) on
    NumPy (the baseline, unless ``g.numpy`` is off) and ``backends`` (``--backends``
    entries): ``{"memory": each device's memory, "sizes": the kernel sizes, "devices",
    name: {"rows", "seconds", "markdown"}}``."""
    labels = (["numpy"] if g.numpy else []) + list(backends)
    ctx_backends = resolve(list(dict.fromkeys(labels)), say)
    memory = device_memory(ctx_backends, llc, bandwidth, min(seconds, 0.5))
    ctx = Context(backends=ctx_backends, memory=memory, llc=llc, sizes=_sizes(g, memory),
                  seconds=seconds, machine=machine, quick=quick, full=full, say=say)
    out: dict = {"memory": memory, "sizes": ctx.sizes,
                 "devices": {k: b.device for k, b in ctx_backends.items()}}
    for name in (n for n in GROUPS if n in names and n != "peers"):
        say(f"{name} ...")
        t0 = time.perf_counter()
        try:
            rows = _RUN[name](ctx, g)
        except ImportError as exc:  # an optional package the group needs (trimesh, ...)
            say(f"{name}: not run: {exc}")
            rows, lines = [], [f"Not run: {exc}."]
        else:
            lines = _MARKDOWN[name](rows, ctx) if rows else ["No rows (nothing to run)."]
        out[name] = {"rows": rows, "seconds": round(time.perf_counter() - t0, 1),
                     "markdown": lines}
    return out
