"""Temporal blocking of the fused model kernels against the single-step memory roofline.

    python perf/blocking.py [--dtype float32] [--factor 4] [--nx 2048] [--warmup 2000]
                            [--steps 2 4 8 16] [--rows 128 512] [--repeats 5]

Gray-Scott (2 species: 16 bytes per cell and step in float32, the state read and written
once) on a periodic grid whose fields are ``factor`` × the last-level cache, from its
default initial condition run ``warmup`` steps (a real state: a pattern growing in a
decayed background, where the kernels flush subnormals).  In one run it times:

* the single-step OpenCL rate (Mcell·steps/s) and the blocked rates (``rdgpu.integrators.blocking``)
  for every K in ``--steps`` and band height B in ``--rows``;
* the single-step memory roofline: the bandwidth of an OpenCL triad ``a = b + s·c`` over
  three arrays each the size of the state (3 arrays counted, as STREAM does; as many
  bytes per timing as the single steps move) ÷ the bytes per cell;
* the compute ceiling: the single-step rate on ``small_rows`` × nx rows of the same state,
  a grid whose state (read and written) fills half the last-level cache;
* the Warp single-step rate at the same size, and on the compute ceiling's grid.

Every timing is the best of ``repeats`` rounds (one round times every configuration once,
each from the same saved state), so a moment when the machine is busy does not count.
Prints a Markdown table and writes it to ``perf/results/blocking.md`` (float32) or
``perf/results/blocking-float64.md``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

try:
    import rdgpu  # noqa: F401
except ImportError:  # a source checkout without installing
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from real_states import subnormal_fraction, timed

from rdgpu.integrators.blocking import BlockedEuler, last_level_cache
from rdgpu.simulation.driver import Simulation

TRIAD = """
__kernel void triad(__global float *restrict a, __global const float *restrict b,
                    __global const float *restrict c, const float s, const long n)
{
    const long chunk = (n + get_global_size(0) - 1) / get_global_size(0);
    const long lo = get_global_id(0) * chunk;
    const long hi = (lo + chunk < n) ? lo + chunk : n;
    for (long i = lo; i < hi; ++i) a[i] = b[i] + s * c[i];
}
"""


class Triad:
    """``a = b + s·c`` over float32 arrays of ``n`` values (3·4·n bytes moved), one chunk
    of consecutive values per work-item, on the backend's OpenCL device."""

    def __init__(self, backend, n: int):
        cl = self.cl = backend._cl
        self.queue, self.n = backend.queue, n
        self.kernel = cl.Kernel(cl.Program(backend.context, TRIAD).build(), "triad")
        host = np.ones(n, np.float32)
        flags = cl.mem_flags.READ_WRITE | cl.mem_flags.COPY_HOST_PTR
        # kept: a kernel argument does not keep its buffer alive
        self.bufs = [cl.Buffer(backend.context, flags, hostbuf=host) for _ in range(3)]
        self.items = 16 * max(1, int(backend.cl_device.max_compute_units))
        self.kernel.set_args(*self.bufs, np.float32(0.5), np.int64(n))
        self.seconds()  # compile, touch the pages

    def seconds(self, reps: int = 1) -> float:
        """Seconds of ``reps`` triads in a row."""
        t0 = time.perf_counter()
        for _ in range(reps):
            self.cl.enqueue_nd_range_kernel(self.queue, self.kernel, (self.items,), (1,))
        self.queue.finish()
        return time.perf_counter() - t0


def measure(args) -> dict:
    llc = last_level_cache()
    if llc is None:
        raise SystemExit("the last-level cache size is unknown (no /sys cache info, no lscpu)")
    itemsize = np.dtype(args.dtype).itemsize
    bytes_per_cell = 2 * 2 * itemsize  # two species, read and written
    cells = args.factor * llc / bytes_per_cell
    ny = int(-(-cells // args.nx))
    ny = -(-ny // 64) * 64
    grid = {"grid": (ny, args.nx), "dx": 1.0, "bc": "periodic"}
    sim = Simulation("gray-scott", grid, backend="opencl", dtype=args.dtype,
                     options={"block_steps": 1})
    st = sim.stepper
    be = st.backend
    print(f"LLC {llc / 2**20:.0f} MiB; grid {ny} x {args.nx} ({ny * args.nx / 1e6:.1f} M cells, "
          f"{ny * args.nx * bytes_per_cell / llc:.1f} x LLC); warm-up {args.warmup} steps",
          flush=True)
    st.blocked = BlockedEuler(st, 8)  # bit for bit the single steps, faster
    st.advance(args.warmup)
    start = st.get_state()
    n_steps = int(np.lcm.reduce([*args.steps, 2])) * args.passes
    configs: dict[str, BlockedEuler | None] = {"single step": None}
    for k in args.steps:
        for b in args.rows:
            configs[f"blocked K={k} B={b}"] = BlockedEuler(st, k, b)
    # the Warp single step on the same state, and the compute ceiling: single steps on
    # the central rows, a grid that fits in the last-level cache (periodic: the seam
    # does not matter for the timing)
    warp = Simulation("gray-scott", grid, backend="warp", dtype=args.dtype, fields=start)
    # the state read and written in half the LLC
    c = args.small_rows or max(1, int(llc // 2 // (args.nx * bytes_per_cell)))
    crop = {s: a[(ny - c) // 2: (ny + c) // 2] for s, a in start.items()}
    small, warp_small = (
        Simulation("gray-scott", {"grid": (c, args.nx), "dx": 1.0, "bc": "periodic"},
                   backend=name, dtype=args.dtype, fields=crop, options={"block_steps": 1})
        for name in ("opencl", "warp"))
    small_steps = n_steps * (ny // c)
    triad = Triad(be, 3 * ny * args.nx)
    # as many bytes per timing as the single steps move (16 bytes/cell): equal durations,
    # so that a busy moment of the machine weighs alike on both
    triad_reps = max(1, round(n_steps * bytes_per_cell / (12 * 3)))
    best: dict[str, float] = {}

    def keep(name: str, seconds: float) -> None:
        best[name] = min(best.get(name, float("inf")), seconds)

    for sim_ in (warp, small, warp_small):  # compile outside the timed rounds
        sim_.stepper.advance(2)
    for cfg in configs.values():
        st.blocked = cfg
        st.advance(n_steps)
    for r in range(args.repeats):
        for label, cfg in configs.items():
            st.blocked = cfg
            keep(label, timed(sim, start, n_steps, 1))
        keep("warp", timed(warp, start, args.warp_steps, 1))
        keep("small", timed(small, crop, small_steps, 1))
        keep("warp small", timed(warp_small, crop, args.warp_steps * (ny // c), 1))
        keep("triad", triad.seconds(triad_reps))
        print(f"round {r + 1}/{args.repeats} done", flush=True)
    bw = 12.0 * triad.n * triad_reps / best["triad"]
    rates = {label: ny * args.nx * n_steps / best[label] / 1e6 for label in configs}
    return {
        "llc": llc, "shape": (ny, args.nx), "dtype": args.dtype, "warmup": args.warmup,
        "steps_timed": n_steps, "bytes_per_cell": bytes_per_cell,
        "subnormal_fraction": subnormal_fraction(start),
        "bandwidth": bw, "roofline": bw / bytes_per_cell / 1e6, "rates": rates,
        "warp": ny * args.nx * args.warp_steps / best["warp"] / 1e6,
        "warp_small": c * args.nx * args.warp_steps * (ny // c) / best["warp small"] / 1e6,
        "small": c * args.nx * small_steps / best["small"] / 1e6, "small_shape": (c, args.nx),
        "device": be.device,
    }


def markdown(m: dict) -> str:
    ny, nx = m["shape"]
    roof = m["roofline"]
    blocked = {k: v for k, v in m["rates"].items() if k != "single step"}
    top = max(blocked, key=blocked.get) if blocked else None
    lines = [
        f"Gray-Scott {m['dtype']}, {ny} × {nx} periodic "
        f"({ny * nx * m['bytes_per_cell'] / m['llc']:.1f} × the {m['llc'] / 2**20:.0f} MiB "
        "last-level cache), the state after "
        f"{m['warmup']} steps from the default initial condition (subnormal: "
        f"{100 * m['subnormal_fraction']:.1f}%); {m['steps_timed']} steps per timing, best of "
        f"the rounds; {m['device']}.",
        "",
        f"Triad bandwidth {m['bandwidth'] / 1e9:.1f} GB/s → single-step roofline "
        f"{roof:.0f} Mcell·steps/s at {m['bytes_per_cell']} bytes/cell.",
        "",
        "| kernel | Mcell·steps/s | × roofline |",
        "|---|---:|---:|",
        f"| roofline (triad ÷ {m['bytes_per_cell']} B/cell) | {roof:.0f} | 1.00 |",
        f"| compute ceiling: OpenCL single step, {m['small_shape'][0]} × "
        f"{m['small_shape'][1]} (in the LLC) | "
        f"{m['small']:.0f} | {m['small'] / roof:.2f} |",
        f"| Warp single step, the same grid in the LLC | {m['warp_small']:.0f} | "
        f"{m['warp_small'] / roof:.2f} |",
        f"| Warp single step | {m['warp']:.0f} | {m['warp'] / roof:.2f} |",
    ]
    for label, rate in m["rates"].items():
        name = f"OpenCL {label}" + (" (best)" if label == top else "")
        lines.append(f"| {name} | {rate:.0f} | {rate / roof:.2f} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dtype", default="float32", choices=["float32", "float64"])
    parser.add_argument("--factor", type=float, default=4.0,
                        help="the fields' size in last-level caches")
    parser.add_argument("--nx", type=int, default=2048)
    parser.add_argument("--warmup", type=int, default=2000)
    parser.add_argument("--steps", type=int, nargs="+", default=[2, 4, 8, 12, 16])
    parser.add_argument("--rows", type=int, nargs="+", default=[64, 256])
    parser.add_argument("--passes", type=int, default=2,
                        help="timed steps: this many × the lcm of --steps")
    parser.add_argument("--warp-steps", type=int, default=10)
    parser.add_argument("--small-rows", type=int, default=None,
                        help="rows of the compute ceiling's grid (nx columns; default: the "
                        "state read and written fills half the LLC)")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--out", default=str(Path(__file__).parent / "results"))
    args = parser.parse_args(argv)
    md = markdown(measure(args))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    name = "blocking.md" if args.dtype == "float32" else f"blocking-{args.dtype}.md"
    (out / name).write_text(md)
    print(md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
