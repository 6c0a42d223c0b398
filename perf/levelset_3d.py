"""Time per step of the 3-D upwind level-set kernels (advance and reinitialisation) and of
the reaction-diffusion front driver (rdgpu.fronts), per backend.

    PYTHONPATH=. python perf/levelset_3d.py [--sizes 64 128] [--backends numpy warp opencl]

Each number is the median over ``--repeats`` timed blocks of device-resident steps (one
upload, ``steps`` kernel launches, one synchronise), in milliseconds per step.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

import rdgpu
from rdgpu.domains.boundary import parse_bc


def _block(fn, steps: int, repeats: int, sync) -> float:
    fn(1)  # compile / warm up
    sync()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn(steps)
        sync()
        times.append((time.perf_counter() - t0) / steps)
    return statistics.median(times) * 1e3


def levelset_rows(backend: str, n: int, dtype, steps: int, repeats: int) -> dict[str, float]:
    be = rdgpu.get_backend(backend)
    x = (np.arange(n) - n / 2 + 0.5)
    zz, yy, xx = np.meshgrid(x, x, x, indexing="ij")
    phi = (np.sqrt(xx**2 + yy**2 + zz**2) - n / 4).astype(dtype)
    bc = parse_bc("neumann", 3)
    cur, nxt, phi0 = be.upload(phi), be.empty(phi.shape, phi.dtype), be.upload(phi)
    speed = be.upload(np.full(phi.shape, 0.5, dtype))

    def advance(k):
        a, b = cur, nxt
        for _ in range(k):
            be.levelset_step(a, speed, b, dt=0.3, dx=1.0, dy=1.0, dz=1.0, bc=bc)
            a, b = b, a

    def reinit(k):
        a, b = cur, nxt
        for _ in range(k):
            be.reinit_step(a, phi0, b, dtau=1 / 3, width=1.0, dx=1.0, dy=1.0, dz=1.0, bc=bc)
            a, b = b, a

    return {"advance": _block(advance, steps, repeats, be.synchronize),
            "reinit": _block(reinit, steps, repeats, be.synchronize)}


def driver_row(backend: str, steps: int, repeats: int) -> float:
    """ms per driver step of the seed-003 configuration (64², Turing, β = Δu, CFL
    substeps, reinit every 20 steps) after the pattern has formed."""
    from rdgpu.growth.fronts import SEED003_FRONT, RDFront
    from rdgpu.simulation.driver import Simulation

    sim = Simulation.from_preset(SEED003_FRONT["preset"], backend=backend, dtype="float64")
    sim.stepper.advance(SEED003_FRONT["warmup"])
    front = RDFront(sim, field="u", reinit_every=SEED003_FRONT["reinit_every"], radius=3.0)
    be = sim.stepper.backend
    return _block(lambda k: [front.step() for _ in range(k)], steps, repeats, be.synchronize)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[64, 128])
    ap.add_argument("--backends", nargs="+", default=["numpy", "warp", "opencl"])
    ap.add_argument("--dtype", default="float32")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    dtype = np.dtype(args.dtype)
    print(f"3-D level sets, {dtype}, ms per step (median of {args.repeats})")
    print(f"{'backend':8} {'size':>6} {'advance':>9} {'reinit':>9} {'Mcell/s adv':>12}")
    for n in args.sizes:
        steps = 20 if n <= 64 else 5
        for b in args.backends:
            r = levelset_rows(b, n, dtype, steps, args.repeats)
            rate = n**3 / (r["advance"] * 1e-3) / 1e6
            print(f"{b:8} {n:>5}³ {r['advance']:9.2f} {r['reinit']:9.2f} {rate:12.1f}")
    print("front driver (seed 003 config, 64², float64), ms per driver step")
    for b in args.backends:
        print(f"{b:8} {driver_row(b, 50, args.repeats):9.2f}")


if __name__ == "__main__":
    main()
