"""Random-walker DLA: walker steps per second on every backend, against a plain NumPy
implementation written the obvious way, and the mass-radius dimension of radial clusters
for several sticking probabilities.

    PYTHONPATH=. python perf/walkers.py [--size 256] [--particles 2000]
        [--walkers 1024 4096] [--backends numpy warp opencl] [--plain-steps 2000]
        [--speed-sticking 1] [--speed-max-steps N]
        [--dimension] [--dim-particles 3000] [--dim-walkers 64] [--sticking 1 0.5 0.2]

Speed rows: ``rdgpu.random_walk_dla`` (radial, ``--speed-sticking``, seed 0), after one small run
that compiles; walker steps = swarm steps x walkers in flight.  The plain NumPy version
(`rdgpu.bench.rows_growth.plain_numpy_walkers`, also the walker rows of ``rdgpu bench
--rows growth``) moves every walker one step with ``numpy.random`` draws, checks
the four neighbours, and adds the stickers' cells in a Python loop: the same rules as
``rdgpu/families/walkers/reference.py`` without Philox or the identical-cluster guarantee.

Dimension: the mass-radius fit ``M(r) ∝ r^D`` (``mass_radius_dimension``): M counts the
cells within distance r of the seed; D is the least-squares slope of log M on log r over
12 log-spaced radii from 3 cells to half the cluster's largest radius.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import rdgpu
from rdgpu.bench.rows_growth import plain_numpy_walkers


def mass_radius_dimension(mask: np.ndarray, centre: tuple[int, int]) -> tuple[float, float,
                                                                               float]:
    """``(D, r_lo, r_hi)``: the mass-radius slope and the fit range (module doc)."""
    i, j = np.nonzero(mask)
    d = np.hypot(i - centre[0], j - centre[1])
    r_hi = 0.5 * d.max()
    r_lo = 3.0
    radii = np.geomspace(r_lo, r_hi, 12)
    mass = np.array([(d <= r).sum() for r in radii])
    slope = np.polyfit(np.log(radii), np.log(mass), 1)[0]
    return float(slope), r_lo, float(r_hi)


def gyration_dimension(arrival: np.ndarray, first: int = 100) -> float:
    """Slope of log N on log R_g(N) over the growth: ``R_g(N)`` is the radius of gyration
    of the first N particles (arrival 1 … N), at 12 log-spaced N from ``first`` to all."""
    k = arrival[arrival > 0]
    i, j = np.nonzero(arrival > 0)
    order = np.argsort(k)
    i, j = i[order].astype(float), j[order].astype(float)
    ns = np.unique(np.geomspace(first, len(k), 12).astype(int))
    rg = [np.sqrt(i[:n].var() + j[:n].var()) for n in ns]
    return float(np.polyfit(np.log(rg), np.log(ns), 1)[0])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--particles", type=int, default=2000)
    ap.add_argument("--walkers", type=int, nargs="*", default=[1024, 4096])
    ap.add_argument("--backends", nargs="+", default=["numpy", "warp", "opencl"])
    ap.add_argument("--speed-sticking", type=float, default=1.0)
    ap.add_argument("--speed-max-steps", type=int, default=10**8)
    ap.add_argument("--plain-steps", type=int, default=2000,
                    help="swarm steps the plain NumPy version runs (0 to skip)")
    ap.add_argument("--dimension", action="store_true")
    ap.add_argument("--dim-particles", type=int, default=3000)
    ap.add_argument("--dim-walkers", type=int, default=64)
    ap.add_argument("--dim-backend", default="opencl")
    ap.add_argument("--dim-seeds", type=int, default=1, help="clusters per sticking value")
    ap.add_argument("--sticking", type=float, nargs="+", default=[1.0, 0.5, 0.2])
    args = ap.parse_args()
    shape = (args.size, args.size)
    print("| backend | walkers | particles added | swarm steps | seconds | "
          "walker steps/s |\n|---|---|---|---|---|---|")
    for w in args.walkers:
        for b in args.backends:
            rdgpu.random_walk_dla((32, 32), particles=5, walkers=8, backend=b)  # compile
            t = time.perf_counter()
            r = rdgpu.random_walk_dla(shape, particles=args.particles, walkers=w, backend=b,
                                      sticking=args.speed_sticking,
                                      max_steps=args.speed_max_steps)
            s = time.perf_counter() - t
            print(f"| {b} | {w} | {r.particles_added} | {r.steps} | {s:.2f} | "
                  f"{r.walker_steps / s:.3g} |", flush=True)
        if args.plain_steps:
            _, ws, s = plain_numpy_walkers(shape, args.particles, w, args.speed_sticking,
                                         max_steps=min(args.plain_steps, args.speed_max_steps))
            print(f"| plain numpy | {w} | - | {ws // w} | {s:.2f} | {ws / s:.3g} |", flush=True)
    if args.dimension:
        print("\n| sticking | particles | seeds | D (mass-radius), mean ± sd | each | "
              "fit range (cells) | D (N vs R_g), mean ± sd | largest radius |"
              "\n|---|---|---|---|---|---|---|---|")
        for p in args.sticking:
            ds, his, gs = [], [], []
            for seed in range(args.dim_seeds):
                r = rdgpu.random_walk_dla(shape, particles=args.dim_particles, sticking=p,
                                          walkers=args.dim_walkers, backend=args.dim_backend,
                                          seed=seed)
                d, lo, hi = mass_radius_dimension(r.mask, (args.size // 2, args.size // 2))
                ds.append(d)
                his.append(hi)
                gs.append(gyration_dimension(r.arrival))
            each = " ".join(f"{d:.3f}" for d in ds)
            print(f"| {p} | {r.particles_added} | {len(ds)} | {np.mean(ds):.3f} ± "
                  f"{np.std(ds):.3f} | {each} | {lo:.0f}–{min(his):.0f}…{max(his):.0f} | "
                  f"{np.mean(gs):.3f} ± {np.std(gs):.3f} | {2 * np.mean(his):.0f} |",
                  flush=True)


if __name__ == "__main__":
    main()
