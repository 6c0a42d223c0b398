"""Benchmark every grid kernel on every backend, side by side in one run.

    python perf/bench.py [--sizes 256 1024 2048] [--seconds 0.4] [--out perf/results]

Prints and saves (JSON and a Markdown table) Mcell/s, the ratio to NumPy measured in the
same run, and the fraction of the memory-bandwidth roofline: the machine's bandwidth is
measured here (a STREAM-style triad, the best of NumPy on one core and OpenCL on all),
and each kernel's roofline is bandwidth / (bytes it must move per cell).
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np

import rdgpu
from rdgpu.boundary import parse_bc

# Bytes a kernel must move per cell in float32 (reads + writes of full arrays).
BYTES_PER_CELL = {
    "laplacian": 8,  # read u, write Lu
    "bernoulli": 8,  # read u, write u'
    "gray_scott": 16,  # read u, v; write u', v'
    "sor_sweep": 14,  # two half-sweeps: read c (4) + write half (2) + mask (1), twice
    "levelset_step": 8,  # read phi, write phi'
    "reinit_step": 12,  # read phi, phi0; write phi'
}


def measure_bandwidth(seconds: float) -> dict:
    """Triad ``a = b + s c`` on 32 Mi floats: NumPy (one core) and OpenCL (all cores)."""
    n = 1 << 25
    b = np.random.rand(n).astype(np.float32)
    c = np.random.rand(n).astype(np.float32)
    a = np.empty_like(b)
    best = float("inf")
    end = time.perf_counter() + seconds
    while time.perf_counter() < end or best == float("inf"):
        t0 = time.perf_counter()
        np.multiply(c, np.float32(3.0), out=a)
        np.add(a, b, out=a)
        best = min(best, time.perf_counter() - t0)
    # np.multiply + np.add move 5 arrays' worth (c, a, a, b, a); count the triad's 3.
    result = {"numpy_triad_GBps": 3 * 4 * n / best / 1e9}
    try:
        import pyopencl as cl

        be = rdgpu.get_backend("opencl")
        ctx, queue = be.context, be.queue
        prg = cl.Program(ctx, """
            __kernel void triad(__global float *a, __global const float *b,
                                __global const float *c, float s) {
                size_t i = get_global_id(0); a[i] = b[i] + s * c[i]; }""").build()
        mf = cl.mem_flags
        db = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=b)
        dc = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=c)
        da = cl.Buffer(ctx, mf.WRITE_ONLY, a.nbytes)
        kernel = prg.triad
        best = float("inf")
        end = time.perf_counter() + seconds
        while time.perf_counter() < end or best == float("inf"):
            t0 = time.perf_counter()
            kernel(queue, (n,), None, da, db, dc, np.float32(3.0))
            queue.finish()
            best = min(best, time.perf_counter() - t0)
        result["opencl_triad_GBps"] = 3 * 4 * n / best / 1e9
    except Exception as exc:  # noqa: BLE001 - bandwidth from NumPy alone then
        result["opencl_error"] = str(exc)
    result["GBps"] = max(v for k, v in result.items() if k.endswith("GBps"))
    return result


def make_case(kernel: str, be, n: int):
    """Device inputs for one kernel and a closure running one step (ping-pong inside)."""
    rng = np.random.default_rng(0)
    shape = (n, n)
    bc = parse_bc("periodic")
    f32 = np.float32
    if kernel == "laplacian":
        u, out = be.upload(rng.random(shape, f32)), be.empty(shape, f32)
        return lambda: be.laplacian(u, out, dx=1.0, dy=1.0, bc=bc, stencil=5)
    if kernel == "bernoulli":
        bufs = [be.upload(rng.uniform(-1, 1, shape).astype(f32)), be.empty(shape, f32)]

        def step():
            be.bernoulli(bufs[0], bufs[1], decay=0.99)
            bufs.reverse()

        return step
    if kernel == "gray_scott":
        u = np.ones(shape, f32)
        v = np.zeros(shape, f32)
        u[n // 3: n // 2, n // 3: n // 2], v[n // 3: n // 2, n // 3: n // 2] = 0.5, 0.25
        bufs = [be.upload(u), be.upload(v), be.empty(shape, f32), be.empty(shape, f32)]

        def step():
            be.gray_scott(bufs[0], bufs[1], bufs[2], bufs[3], Du=0.16, Dv=0.08, F=0.035,
                          k=0.06, dt=1.0, dx=1.0, dy=1.0, bc=bc)
            bufs[:] = [bufs[2], bufs[3], bufs[0], bufs[1]]

        return step
    if kernel == "sor_sweep":
        c = be.upload(rng.random(shape, f32))
        fixed = np.zeros(shape, np.uint8)
        fixed[0] = 1
        d_fixed, change = be.upload(fixed), be.empty((n,), f32)
        omega = rdgpu.optimal_omega(shape)

        def step():
            for color in (0, 1):
                be.sor_half_sweep(c, d_fixed, None, change, color=color, omega=omega, dx=1.0,
                                  dy=1.0, bc=bc)

        return step
    i, j = np.indices(shape)
    phi = (np.sqrt((i - n / 2) ** 2 + (j - n / 2) ** 2) - n / 4).astype(f32)
    if kernel == "levelset_step":
        bufs = [be.upload(phi), be.empty(shape, f32)]

        def step():
            be.levelset_step(bufs[0], 1.0, bufs[1], dt=0.4, dx=1.0, dy=1.0, bc=bc)
            bufs.reverse()

        return step
    if kernel == "reinit_step":
        phi0 = be.upload(phi * 3)
        bufs = [be.upload(phi * 3), be.empty(shape, f32)]

        def step():
            be.reinit_step(bufs[0], phi0, bufs[1], dtau=0.5, width=1.0, dx=1.0, dy=1.0, bc=bc)
            bufs.reverse()

        return step
    raise ValueError(kernel)


def time_case(be, step, seconds: float) -> float:
    """Best seconds per step: warm up, then time batches until ``seconds`` have passed."""
    step()
    be.synchronize()
    t0 = time.perf_counter()
    step()
    be.synchronize()
    one = max(time.perf_counter() - t0, 1e-7)
    batch = max(1, int(0.05 / one))
    best = float("inf")
    end = time.perf_counter() + seconds
    while time.perf_counter() < end or best == float("inf"):
        t0 = time.perf_counter()
        for _ in range(batch):
            step()
        be.synchronize()
        best = min(best, (time.perf_counter() - t0) / batch)
    return best


def markdown(rows: list[dict], bandwidth: float) -> str:
    lines = [
        f"Measured bandwidth (triad): {bandwidth:.1f} GB/s. float32, periodic, best of repeats.",
        "",
        "| kernel | size | backend | Mcell/s | × NumPy | roofline Mcell/s | % roofline |",
        "|---|---|---|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(
            f"| {r['kernel']} | {r['size']}² | {r['backend']} | {r['mcells']:.0f} | "
            f"{r['speedup']:.1f} | {r['roofline_mcells']:.0f} | {100 * r['roofline_fraction']:.0f} |"
        )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument("--sizes", type=int, nargs="+", default=[256, 1024, 2048])
    parser.add_argument("--kernels", nargs="+", default=list(BYTES_PER_CELL))
    parser.add_argument("--backends", nargs="+", default=["numpy", "warp", "opencl"])
    parser.add_argument("--seconds", type=float, default=0.4, help="timing per case")
    parser.add_argument("--out", default=str(Path(__file__).parent / "results"))
    args = parser.parse_args(argv)

    bw = measure_bandwidth(min(args.seconds, 0.5))
    print(f"bandwidth: {bw}")
    backends = {name: rdgpu.get_backend(name) for name in args.backends}
    rows = []
    for kernel in args.kernels:
        for n in args.sizes:
            base = None
            for name, be in backends.items():
                seconds = time_case(be, make_case(kernel, be, n), args.seconds)
                mcells = n * n / seconds / 1e6
                base = mcells if name == "numpy" else base
                roof = bw["GBps"] * 1e9 / BYTES_PER_CELL[kernel] / 1e6
                row = dict(kernel=kernel, size=n, backend=name, device=be.device,
                           seconds_per_step=seconds, mcells=mcells,
                           speedup=mcells / base if base else float("nan"),
                           roofline_mcells=roof, roofline_fraction=mcells / roof)
                rows.append(row)
                print(f"{kernel:14s} {n:5d}² {name:7s} {mcells:9.1f} Mcell/s "
                      f"x{row['speedup']:5.1f} numpy  {100 * row['roofline_fraction']:5.1f}% roofline",
                      flush=True)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    meta = dict(machine=platform.processor() or platform.machine(), python=platform.python_version(),
                rdgpu=rdgpu.__version__, numpy=np.__version__, bandwidth=bw,
                devices={n: b.device for n, b in backends.items()},
                date=time.strftime("%Y-%m-%d %H:%M"))
    (out / "bench.json").write_text(json.dumps(dict(meta=meta, rows=rows), indent=1))
    table = markdown(rows, bw["GBps"])
    (out / "bench.md").write_text(table)
    print(table)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
