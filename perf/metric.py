"""The metric Laplace-Beltrami kernel (``rdgpu.laplacian(height=)``): the seed's heat-equation
convergence check and a benchmark against the flat 5-point Laplacian.

    python perf/metric.py [--sizes N ...] [--backends B ...] [--seconds 0.3]
                          [--heat-sizes 16 32 64 128] [--heat-backend numpy] [--out perf/results]

(a) Seed 002 §3, eq. 14: ``u_t = Δ_Γ u + f`` on the rough periodic surface ``z = h(x, y)``
over ``[0, 2π]²`` (:data:`HEIGHT`, waves up to wave number 2, max |h| ≈ 1), with the
manufactured solution ``u = e^{-t} sin(x) cos(y)`` and ``f = e^{-t}(−s − Δ_Γ s)``,
``s = sin(x) cos(y)``, where ``Δ_Γ s`` is the exact operator (closed form of
``rdgpu/families/metric/exact.py``, checked here against its FFT form).  Forward Euler with
``rdgpu.laplacian(height=)`` every step (float64) to ``T = 1``, ``dt = κ dx²`` with one ``κ``
for every grid (stable on all: ``κ dx² · λ_max ≤ 1`` by the Gershgorin bound), so the time
error is second order too.  The table: the relative ℓ² error ``‖u − u_exact‖₂ / ‖u_exact‖₂``
at ``T`` against ``n`` and the observed orders; written to ``metric_convergence.md``.

(b) The metric kernel against the flat 5-point one on each backend, side by side in one
run (float32, the same random ``u``; the metric coefficients uploaded once): Mcell/s and
% of the memory-bandwidth roofline (`rdgpu.bench.machine`: the triad measured over a sweep
of array sizes, bytes counted the STREAM way; flat 8 bytes per cell, u and out; metric 24,
u, out and the four coefficient arrays).  Sizes from the measured cache as ``rdgpu bench
--rows kernels`` picks them (a cache-resident one, a mid one, one whose working set is at
least 4× the LLC); written to ``metric_bench.md``.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

try:
    import rdgpu
except ImportError:  # run from a source checkout without installing
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    import rdgpu
from rdgpu.bench.context import kernel_sizes  # noqa: E402
from rdgpu.bench.devices import (  # noqa: E402
    add_roofline,
    device_memory,
    fmt,
    memory_of,
    resolve,
    roof_text,
    time_case,
)
from rdgpu.bench.machine import MiB, effective_llc, triad_sweep  # noqa: E402
from rdgpu.core.hardware import cpu_caches  # noqa: E402
from rdgpu.domains.boundary import parse_bc  # noqa: E402
from rdgpu.domains.graph_surface import GraphSurface  # noqa: E402
from rdgpu.families import load_module  # noqa: E402

EXACT = load_module("metric", "exact.py")
#: the rough surface of the heat check: a few waves, max |h| about 1
HEIGHT = EXACT.Waves(((0.4, 1, 1, 0.3), (0.3, 2, -1, 1.1), (0.2, 1, 2, 2.0), (0.2, 0, 1, 0.0)))
#: ``s = sin(x) cos(y)`` as waves: ½ sin(x + y) + ½ sin(x − y)
SHAPE = EXACT.Waves(((0.5, 1, 1, -np.pi / 2), (0.5, 1, -1, -np.pi / 2)))
T_END = 1.0
#: float32 bytes moved per cell: the Laplacians, and one Gray-Scott step of the model layer
#: (read u, v, write u, v; the surface's step reads the four coefficients too)
BYTES = {"flat 5-point": 8, "metric": 24, "gray-scott flat": 16, "gray-scott surface": 32}


# ---------------------------------------------------------------------------- (a) heat
def heat_error(n: int, kappa: float, backend: str | None) -> dict:
    """Forward Euler to ``T_END`` on the n² grid; the relative ℓ² error and the run's facts."""
    d = 2 * np.pi / n
    x = (np.arange(n) + 0.5) * d
    X, Y = np.meshgrid(x, x)
    h = HEIGHT(X, Y)
    s = SHAPE(X, Y)
    lap_s = EXACT.exact_laplace_beltrami(HEIGHT, SHAPE, X, Y)
    spectral_gap = np.abs(lap_s - EXACT.spectral_laplace_beltrami(h, s, d, d)).max()
    forcing = -s - lap_s  # f = e^{-t} forcing
    steps = int(np.ceil(T_END / (kappa * d * d)))
    dt = T_END / steps
    u = s.copy()
    t0 = time.perf_counter()
    for k in range(steps):
        u = u + dt * (rdgpu.laplacian(u, height=h, dx=d, backend=backend)
                      + np.exp(-k * dt) * forcing)
    exact = np.exp(-T_END) * s
    return dict(n=n, dx=d, dt=dt, steps=steps, seconds=time.perf_counter() - t0,
                error=float(np.linalg.norm(u - exact) / np.linalg.norm(exact)),
                spectral_gap=float(spectral_gap))


def heat_table(sizes: list[int], backend: str | None) -> tuple[list[dict], str]:
    """The error table over ``sizes`` (one κ for all) and its Markdown."""
    bounds = []
    for n in sizes:
        d = 2 * np.pi / n
        x = (np.arange(n) + 0.5) * d
        X, Y = np.meshgrid(x, x)
        bounds.append(GraphSurface((n, n), dx=d, height=HEIGHT(X, Y)).spectral_bound() * d * d)
    kappa = 1.0 / max(bounds)  # dt λ_max ≤ 1 < 2 on every grid
    rows = []
    for n in sizes:
        r = heat_error(n, kappa, backend)
        r["order"] = None if not rows else float(np.log2(rows[-1]["error"] / r["error"]))
        rows.append(r)
        print(f"heat n={n:4d}  dt={r['dt']:.3e}  steps={r['steps']:6d}  rel l2 error "
              f"{r['error']:.3e}  order {fmt(r['order'], '.2f')}  "
              f"({r['seconds']:.1f} s)", flush=True)
    be = rdgpu.get_backend(backend)
    lines = [
        "# Heat equation on a rough periodic surface (seed 002 §3, eq. 14)",
        "",
        f"`u_t = Δ_Γ u + f` on `z = h(x, y)` over `[0, 2π]²`, `h` = {_waves_text(HEIGHT)} "
        f"(max |h| = {np.abs(HEIGHT(X, Y)).max():.2f}); exact `u = e^(-t) sin(x) cos(y)`, "
        "`f` from the exact operator (closed form; its FFT form agrees to the gap below). "
        f"Forward Euler with `rdgpu.laplacian(height=)` (backend {be.name}, float64) to "
        f"`T = {T_END:g}`, `dt = κ dx²` with κ = {kappa:.4f} for every grid "
        "(`dt · λ_max ≤ 1`). Error: `‖u − u_exact‖₂ / ‖u_exact‖₂` at `T`.",
        "",
        "| n | dx | dt | steps | relative ℓ² error | observed order | exact − FFT |",
        "|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(f"| {r['n']} | {r['dx']:.4f} | {r['dt']:.3e} | {r['steps']} | "
                     f"{r['error']:.3e} | {fmt(r['order'], '.2f')} | "
                     f"{r['spectral_gap']:.1e} |")
    lines += ["", f"Command: `python perf/metric.py --heat-sizes {' '.join(map(str, sizes))}"
              f"{'' if backend is None else ' --heat-backend ' + backend}`", ""]
    return rows, "\n".join(lines)


def _waves_text(w) -> str:
    return " + ".join(f"{a:g} cos({kx:g}x {'+' if ky >= 0 else '−'} {abs(ky):g}y + {p:.2g})"
                      for a, kx, ky, p in w.terms)


# ---------------------------------------------------------------------------- (b) bench
def make_step(kind: str, be, n: int):
    """Device arrays for one case and a closure applying the kernel once."""
    if kind.startswith("gray-scott"):
        return _model_step(kind.endswith("surface"), be, n)
    rng = np.random.default_rng(0)
    u = be.upload(rng.random((n, n), np.float32))
    out = be.empty((n, n), np.float32)
    if kind == "metric":
        d = 2 * np.pi / n
        x = (np.arange(n) + 0.5) * d
        X, Y = np.meshgrid(x, x)
        surface = GraphSurface((n, n), dx=d, height=HEIGHT(X, Y))
        coefficients = be.upload_metric(surface, np.float32)
        return lambda: be.metric_laplacian(u, coefficients, out)
    bc = parse_bc("periodic")
    d = 2 * np.pi / n
    return lambda: be.laplacian(u, out, dx=d, dy=d, bc=bc, stencil=5)


def _model_step(surface: bool, be, n: int):
    """One fused Gray-Scott step (``Model.stepper``, euler, float32, dx = 1) on the flat
    periodic n² grid or on the graph surface of :data:`HEIGHT` scaled to it, from the state
    2000 steps into a run (a real pattern, its subnormal background included; computed once
    per case on the fastest backend, :func:`_real_state`)."""
    from rdgpu.models import MODELS

    domain = _gray_scott_domain(surface, n)
    stepper = MODELS["gray-scott"].stepper(domain, GS_PARAMS, dt=0.5, backend=be,
                                           dtype=np.float32, block_steps=1)
    stepper.set_state(_real_state(surface, n))
    return lambda: stepper.advance(1)


GS_PARAMS = {"F": 0.035, "k": 0.060}


def _gray_scott_domain(surface: bool, n: int):
    from rdgpu.domains.grid import Grid

    if not surface:
        return Grid((n, n))
    x = (np.arange(n) + 0.5) * (2 * np.pi / n)
    X, Y = np.meshgrid(x, x)
    return GraphSurface((n, n), height=HEIGHT(X, Y) * (0.05 * n / (2 * np.pi)))


_STATES: dict = {}


def _real_state(surface: bool, n: int) -> dict:
    """Gray-Scott 2000 steps from a central square (OpenCL when there is one)."""
    if (surface, n) not in _STATES:
        from rdgpu.backends.registry import available_backends
        from rdgpu.models import MODELS

        fast = "opencl" if any(b.name == "opencl" and b.available
                               for b in available_backends()) else None
        stepper = MODELS["gray-scott"].stepper(_gray_scott_domain(surface, n), GS_PARAMS,
                                               dt=0.5, backend=fast, dtype=np.float32)
        u, v = np.ones((n, n), np.float32), np.zeros((n, n), np.float32)
        c = slice(n // 2 - n // 8, n // 2 + n // 8)
        u[c, c], v[c, c] = 0.5, 0.25
        stepper.set_state({"u": u, "v": v})
        stepper.advance(2000)
        _STATES[surface, n] = stepper.get_state()
    return _STATES[surface, n]


def bench_rows(sizes: list[int], backends: dict, memory: dict, seconds: float) -> list[dict]:
    rows = []
    for n in sizes:
        for label, be in backends.items():
            for kind, nbytes in BYTES.items():
                step = make_step(kind, be, n)
                t = time_case(be, step, seconds)
                del step
                row = dict(kernel=kind, size=n, cells=n * n, backend=label, device=be.device,
                           seconds_per_step=t, mcells=n * n / t / 1e6)
                rows.append(add_roofline(row, memory_of(label, memory), nbytes))
                print(f"{kind:13s} {n:5d}² {label:12s} {row['mcells']:9.1f} Mcell/s  "
                      f"roofline {roof_text(row)}", flush=True)
    flat = {(r["size"], r["backend"], r["kernel"].split()[0]): r["mcells"] for r in rows
            if r["kernel"] in ("flat 5-point", "gray-scott flat")}
    for r in rows:
        family = "flat" if r["kernel"] in ("flat 5-point", "metric") else "gray-scott"
        r["vs_flat"] = r["mcells"] / flat[r["size"], r["backend"], family]
    return rows


def bench_markdown(rows: list[dict], memory: dict, caches, sizes_auto: bool,
                   argv: list[str]) -> str:
    cpu = memory["cpu"]
    lines = [
        "# The metric Laplace-Beltrami kernel against the flat 5-point Laplacian",
        "",
        f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs; "
        f"{caches.describe()}. Load average (1 min) at the end: {os.getloadavg()[0]:.1f}.",
        "",
        f"Bandwidth (the triad sweep of `rdgpu.bench.machine`, out of the cache): "
        f"**{cpu['GBps']:.1f} GB/s**; effective LLC {cpu['llc'] / MiB:.0f} MiB. "
        "float32, periodic, best of "
        "repeats. Bytes per cell counted "
        "the STREAM way: flat 8 (read u, write out), metric 24 (u, the four coefficient "
        "arrays ex, ny, bx, w, out); one fused Gray-Scott step of the model layer (euler, "
        "dt = 0.5, the state 2000 steps into a run, no temporal blocking) 16 on the flat "
        "grid and 32 on the surface (plus the coefficients). % roofline = Mcell/s ÷ "
        "(bandwidth ÷ bytes per cell), only "
        "where the working set exceeds the LLC (`cache` otherwise). Sizes "
        + ", ".join(f"{n}²" for n in sorted({r['size'] for r in rows}))
        + (" from the caches (cache-resident, mid, ≥ 4× LLC)." if sizes_auto else " (given)."),
        "",
        "| size | backend | kernel | Mcell/s | ÷ flat | working set / LLC | "
        "roofline Mcell/s | % roofline |",
        "|---|---|---|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(f"| {r['size']}² | {r['backend']} | {r['kernel']} | {r['mcells']:.0f} | "
                     f"{r['vs_flat']:.2f} | {fmt(r['working_set_over_llc'], '.2f')} | "
                     f"{r['roofline_mcells']:.0f} | {roof_text(r)} |")
    lines += ["", f"Command: `{' '.join(['python perf/metric.py', *argv])}`", ""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="*", default=None,
                        help="benchmark grid sizes (default: from the caches; none: no bench)")
    parser.add_argument("--backends", nargs="+", default=["numpy", "warp", "opencl"],
                        help="backend specs (default: numpy warp opencl)")
    parser.add_argument("--seconds", type=float, default=0.3, help="timing per case")
    parser.add_argument("--heat-sizes", type=int, nargs="*", default=[16, 32, 64, 128],
                        help="grids of the heat check (none: no heat check)")
    parser.add_argument("--heat-backend", default=None,
                        help="backend of the heat check (default: rdgpu's choice)")
    parser.add_argument("--out", default=str(Path(__file__).parent / "results"))
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    if args.heat_sizes:
        _, text = heat_table(args.heat_sizes, args.heat_backend)
        (out / "metric_convergence.md").write_text(text)
        print(text)
    if args.sizes is not None and not args.sizes:
        return 0
    caches = cpu_caches()
    backends = resolve(args.backends, print)
    print("backends: " + "; ".join(f"{k} = {b.device}" for k, b in backends.items()))
    measured = effective_llc(triad_sweep(2048 * MiB))
    llc = measured["llc"] or caches.llc or 32 * MiB
    memory = device_memory(backends, llc, measured["dram_GBps"], min(args.seconds, 0.5))
    sizes_auto = args.sizes is None
    sizes = args.sizes or kernel_sizes(llc, min(BYTES.values()), max(BYTES.values()))
    print(f"sizes: {sizes}; bandwidth {memory['cpu']['GBps']:.1f} GB/s", flush=True)
    rows = bench_rows(sizes, backends, memory, args.seconds)
    text = bench_markdown(rows, memory, caches, sizes_auto, argv)
    (out / "metric_bench.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
