"""Row group ``kernels``: every hand-written grid kernel family on every backend, float32,
periodic, at the square grids of `Context.sizes` (from the measured cache: in cache, mid,
working set >= 4x the LLC), with the speed-up over NumPy and the % of the roofline, and a
plot (``bench-kernels.png``: Mcell/s against cells, log-log, one panel per kernel, one line
per backend, the LLC and the DRAM roofline of every device marked).

Each backend's first step is checked against NumPy's on the same inputs before it is timed
(`check_kernel`); a backend that disagrees gets a ``refused`` row.  The peers' comparison
on the same Gray-Scott step is the ``peers`` group.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from rdgpu.backends.base import Backend
from rdgpu.backends.registry import get_backend
from rdgpu.bench.context import Context
from rdgpu.bench.devices import add_ratios, add_roofline, fmt, memory_of, roof_text, time_case
from rdgpu.domains.boundary import parse_bc
from rdgpu.ops.solvers import optimal_omega

__all__ = ["BYTES_PER_CELL", "QUICK_SIZES", "check_kernel", "make_case", "markdown", "plot",
           "run"]

#: bytes a kernel must move per cell in float32 (reads + writes of full arrays)
BYTES_PER_CELL = {
    "laplacian": 8,  # read u, write Lu
    "bernoulli": 8,  # read u, write u'
    "gray_scott": 16,  # read u, v; write u', v'
    "sor_sweep": 14,  # two half-sweeps: read c (4) + write half (2) + mask (1), twice
    "levelset_step": 8,  # read phi, write phi'
    "reinit_step": 12,  # read phi, phi0; write phi'
}
QUICK_SIZES = [64]
CHECK_EDGE = 64
TOLERANCE = 1e-4  # max |diff| / (1 + max |NumPy|), float32, one step


def _ping_pong(step: Callable[[list], None], bufs: list, swap: Callable[[list], list]):
    def run():
        step(bufs)
        bufs[:] = swap(bufs)

    return run, bufs


def _gray_scott(be: Backend, n: int, bc) -> tuple[Callable[[], None], list]:
    shape, f32 = (n, n), np.float32
    u, v = np.ones(shape, f32), np.zeros(shape, f32)
    u[n // 3: n // 2, n // 3: n // 2], v[n // 3: n // 2, n // 3: n // 2] = 0.5, 0.25
    bufs = [be.upload(u), be.upload(v), be.empty(shape, f32), be.empty(shape, f32)]
    return _ping_pong(lambda b: be.gray_scott(b[0], b[1], b[2], b[3], Du=0.16, Dv=0.08,
                                              F=0.035, k=0.06, dt=1.0, dx=1.0, dy=1.0, bc=bc),
                      bufs, lambda b: [b[2], b[3], b[0], b[1]])


def _sor(be: Backend, n: int, bc, rng) -> tuple[Callable[[], None], list]:
    shape = (n, n)
    c = be.upload(rng.random(shape, np.float32))
    fixed = np.zeros(shape, np.uint8)
    fixed[0] = 1
    d_fixed, change = be.upload(fixed), be.empty((n,), np.float32)
    omega = optimal_omega(shape)

    def step():
        for color in (0, 1):
            be.sor_half_sweep(c, d_fixed, None, change, color=color, omega=omega, dx=1.0,
                              dy=1.0, bc=bc)

    return step, [c]


def make_case(kernel: str, be: Backend, n: int) -> tuple[Callable[[], None], list]:
    """``(step, buffers)``: device inputs for one kernel on an n² periodic grid and a
    closure running one step (ping-pong inside); ``buffers[0]`` holds the result after an
    odd number of steps of a ping-pong kernel, and after any number for the others."""
    rng = np.random.default_rng(0)
    shape, f32, bc = (n, n), np.float32, parse_bc("periodic")
    if kernel == "laplacian":
        u, out = be.upload(rng.random(shape, f32)), be.empty(shape, f32)
        return (lambda: be.laplacian(u, out, dx=1.0, dy=1.0, bc=bc, stencil=5)), [out]
    if kernel == "bernoulli":
        return _ping_pong(lambda b: be.bernoulli(b[0], b[1], decay=0.99),
                          [be.upload(rng.uniform(-1, 1, shape).astype(f32)),
                           be.empty(shape, f32)], lambda b: b[::-1])
    if kernel == "gray_scott":
        return _gray_scott(be, n, bc)
    if kernel == "sor_sweep":
        return _sor(be, n, bc, rng)
    i, j = np.indices(shape)
    phi = (np.sqrt((i - n / 2) ** 2 + (j - n / 2) ** 2) - n / 4).astype(f32)
    if kernel == "levelset_step":
        return _ping_pong(lambda b: be.levelset_step(b[0], 1.0, b[1], dt=0.4, dx=1.0, dy=1.0,
                                                     bc=bc),
                          [be.upload(phi), be.empty(shape, f32)], lambda b: b[::-1])
    if kernel == "reinit_step":
        phi0 = be.upload(phi * 3)
        return _ping_pong(lambda b: be.reinit_step(b[0], phi0, b[1], dtau=0.5, width=1.0,
                                                   dx=1.0, dy=1.0, bc=bc),
                          [be.upload(phi * 3), be.empty(shape, f32)], lambda b: b[::-1])
    raise ValueError(f"kernels: unknown {kernel!r}; known: {', '.join(BYTES_PER_CELL)}")


def check_kernel(kernel: str, be: Backend) -> str | None:
    """None when one step of ``kernel`` on ``be`` agrees with NumPy's on a 64² grid (to
    `TOLERANCE`), else what differed."""
    results = []
    for backend in (get_backend("numpy"), be):
        step, bufs = make_case(kernel, backend, CHECK_EDGE)
        step()
        backend.synchronize()
        results.append(np.asarray(backend.download(bufs[0]), np.float64))
    ref, got = results
    err = float(np.max(np.abs(got - ref))) / (1 + float(np.max(np.abs(ref))))
    if not err <= TOLERANCE:
        return f"disagrees with NumPy: relative error {err:.2e} after one step"
    return None


def _row(ctx: Context, kernel: str, n: int, label: str, be: Backend, refused: str | None):
    row = dict(kernel=kernel, size=n, cells=n * n, backend=label, device=be.device,
               dtype="float32", status="refused" if refused else "ok", note=refused)
    if refused:
        return row
    t0 = time.perf_counter()
    step, _ = make_case(kernel, be, n)
    row["setup_seconds"] = time.perf_counter() - t0
    seconds = time_case(be, step, ctx.seconds)
    row.update(seconds_per_step=seconds, mcells=n * n / seconds / 1e6)
    add_roofline(row, memory_of(label, ctx.memory), BYTES_PER_CELL[kernel])
    ctx.say(f"  {kernel:14s} {n:5d}² {label:12s} {row['mcells']:9.1f} Mcell/s  "
            f"roofline {roof_text(row)}")
    return row


def run(ctx: Context, kernels: list[str]) -> list[dict]:
    """Every kernel of ``kernels`` at every size on every backend (each checked first);
    ratios to NumPy added once all are timed."""
    rows = []
    for kernel in kernels:
        refused = {label: check_kernel(kernel, be) for label, be in ctx.backends.items()}
        for n in ctx.sizes:
            rows += [_row(ctx, kernel, n, label, be, refused[label])
                     for label, be in ctx.backends.items()]
    ok = [r for r in rows if r["status"] == "ok"]
    add_ratios(ok, ("kernel", "size"))
    return rows


def markdown(rows: list[dict], ctx: Context) -> list[str]:
    """The kernels' table."""
    lines = ["Grid kernels: float32, periodic, best of repeats, each backend checked against "
             "NumPy first. % roofline = Mcell/s ÷ (bandwidth ÷ bytes per cell), only where "
             "the working set exceeds the device's LLC (`cache` where it fits).", "",
             ctx.ran_on(), "",
             "| kernel | size | backend | Mcell/s | × NumPy | working set / LLC | roofline "
             "Mcell/s | % roofline |", "|---|---|---|---:|---:|---:|---:|---:|"]
    for r in rows:
        if r["status"] != "ok":
            lines.append(f"| {r['kernel']} | {r['size']}² | {r['backend']} | refused: "
                         f"{r['note']} | | | | |")
            continue
        lines.append(f"| {r['kernel']} | {r['size']}² | {r['backend']} | {r['mcells']:.0f} | "
                     f"{fmt(r['speedup'], '.1f')} | {fmt(r['working_set_over_llc'], '.2f')} | "
                     f"{r['roofline_mcells']:.0f} | {roof_text(r)} |")
    return lines


def plot(rows: list[dict], ensembles: list[dict], memory: dict, path: Path) -> str | None:
    """Mcell/s against cells, log-log, one panel per kernel, one line per backend; every
    device's LLC as a vertical line at the cell count whose working set fills it and its
    DRAM roofline beyond; ensembles as stars on the Gray-Scott panel.  None, or why there
    is no plot."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return "no kernels plot: matplotlib is missing (pip install rdgpu[media])"
    rows = [r for r in rows if r["status"] == "ok"]
    kernels = list(dict.fromkeys(r["kernel"] for r in rows))
    if not kernels:
        return None
    labels = list(dict.fromkeys(r["backend"] for r in rows + ensembles))
    colors = {b: f"C{i % 10}" for i, b in enumerate(labels)}
    ncol = min(3, len(kernels))
    fig, axes = plt.subplots(math.ceil(len(kernels) / ncol), ncol,
                             figsize=(5.2 * ncol, 4.2 * math.ceil(len(kernels) / ncol)),
                             squeeze=False)
    for ax, kernel in zip(axes.flat, kernels, strict=False):
        _panel(ax, kernel, [r for r in rows if r["kernel"] == kernel], ensembles, memory,
               colors)
    for ax in list(axes.flat)[len(kernels):]:
        ax.set_visible(False)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return None


def _panel(ax, kernel: str, mine: list[dict], ensembles: list[dict], memory: dict,
           colors: dict) -> None:
    for b in dict.fromkeys(r["backend"] for r in mine):
        pts = sorted((r["cells"], r["mcells"]) for r in mine if r["backend"] == b)
        ax.plot(*zip(*pts, strict=True), marker="o", color=colors[b], label=b)
    right = max(r["cells"] for r in mine) * 1.5
    for i, (label, mem) in enumerate(memory.items()):
        name = "CPU" if label == "cpu" else label
        edge = mem["llc"] / BYTES_PER_CELL[kernel]
        style = ("--", ":", "-.")[i % 3]
        ax.axvline(edge, color="0.4", ls=style, lw=1, label=f"{name} LLC filled")
        ax.hlines(mem["GBps"] * 1e3 / BYTES_PER_CELL[kernel], edge, max(right, 2 * edge),
                  color="k", ls=style, lw=1.5, label=f"{name} DRAM roofline")
    if kernel == "gray_scott":
        for r in (e for e in ensembles if e["kernel"] == "ensemble"):
            ax.plot(r["cells"], r["mcells"], marker="*", ms=13, ls="none",
                    color=colors[r["backend"]], label=f"{r['backend']} {r['case']}")
    ax.set(xscale="log", yscale="log", title=kernel, xlabel="cells", ylabel="Mcell/s")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
