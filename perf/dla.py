"""DLA measurements: the fractal-dimension table and the growth speed (issue 10).

    python perf/dla.py table [--size 128] [--seeds 3] [--backend warp] [--out dims.npz]
    python perf/dla.py speed [--size 256] [--steps 40] [--backends numpy,warp,opencl]

``table`` grows radial and slab clusters at η = 0, 0.5, 1, 2 (η = 0: size²/6 steps,
others until the c = 1 boundary is reached) and prints mass-radius and box-counting
dimensions (default fit ranges, see ``rdgpu.analysis.fractal_dimension``), mean ± spread
over seeds.  ``speed`` times growth steps per second and SOR sweeps per growth step, warm
and cold start, per backend, and a plain NumPy implementation of the same algorithm
written the obvious way (`rdgpu.bench.rows_growth.plain_numpy_dla`, also the growth rows
of ``rdgpu bench --rows growth``) for the ratio.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import rdgpu
from rdgpu.analysis import fractal_dimension
from rdgpu.bench.rows_growth import plain_numpy_dla


def table(args) -> None:
    n = args.size
    saved = {}
    print("| geometry | size | η | cells | D mass-radius | D box | seeds |")
    print("|---|---|---|---|---|---|---|")
    for geometry in ("radial", "slab"):
        for eta in (0.0, 0.5, 1.0, 2.0):
            mr, bx, cells = [], [], []
            for seed in range(args.seeds):
                steps = n * n // 6 if eta == 0 else n * n // 3
                r = rdgpu.dla((n, n), eta=eta, steps=steps, geometry=geometry, seed=seed,
                              backend=args.backend)
                mr.append(fractal_dimension(r.mask, center=r.center).dimension)
                bx.append(fractal_dimension(r.mask, method="box").dimension)
                cells.append(r.size)
                saved[f"{geometry}_{eta}_{seed}"] = r.mask
            print(f"| {geometry} | {n}² | {eta:g} | {int(np.mean(cells))} | "
                  f"{np.mean(mr):.2f} ± {np.std(mr):.2f} | {np.mean(bx):.2f} ± "
                  f"{np.std(bx):.2f} | {args.seeds} |", flush=True)
    if args.out:
        np.savez_compressed(args.out, **saved)


def speed(args) -> None:
    n, steps = args.size, args.steps
    print("| backend | size | start | growth steps/s | SOR sweeps/step |")
    print("|---|---|---|---|---|")
    for backend in args.backends.split(","):
        for warm in (True, False):
            kw = {"eta": 1.0, "geometry": "radial", "seed": 0, "backend": backend,
                  "warm_start": warm}
            rdgpu.dla((n, n), steps=2, **kw)  # compile / warm up
            t = time.perf_counter()
            r = rdgpu.dla((n, n), steps=steps, **kw)
            dt = time.perf_counter() - t
            print(f"| {backend} | {n}² | {'warm' if warm else 'cold'} | {steps / dt:.2f} | "
                  f"{r.sweeps[1:].mean():.0f} |", flush=True)
    t = time.perf_counter()
    _, sw = plain_numpy_dla((n, n), steps=steps)
    dt = time.perf_counter() - t
    print(f"| plain NumPy loop | {n}² | warm | {steps / dt:.2f} | {sw[1:].mean():.0f} |")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="what", required=True)
    t = sub.add_parser("table")
    t.add_argument("--size", type=int, default=128)
    t.add_argument("--seeds", type=int, default=3)
    t.add_argument("--backend", default="warp")
    t.add_argument("--out", default="")
    s = sub.add_parser("speed")
    s.add_argument("--size", type=int, default=256)
    s.add_argument("--steps", type=int, default=40)
    s.add_argument("--backends", default="numpy,warp,opencl")
    args = p.parse_args()
    table(args) if args.what == "table" else speed(args)


if __name__ == "__main__":
    main()
