"""SOR against algebraic multigrid for the implicit diffusion steps (``ImplicitDiffusion``,
``solver="sor"`` / ``"multigrid"``, rdgpu/ops/multigrid.py): time per step, iterations and
setup, float32.

    python perf/multigrid.py [--backends opencl,warp] [--repeats 3] [--quick]
                             [--out perf/results/multigrid.md]

One backward-Euler step of ``u_t = D Δu`` from a random field (what every ``imex`` step of
Gray-Scott or Allen-Cahn solves per species) on icospheres 4, 5, 6 (2562, 10242, 40962
vertices) and a graph surface of 256² points (``random_waves``, amplitude 4 cells), at
two stiffnesses ``κ = θ dt D · median|diag M|``: 10 (a mildly implicit step) and 1000 (a
step far beyond the explicit limit, where implicit methods pay).  The step's time is the
median of ``--repeats`` steps after one warm-up step; the setup is the solver's
construction (SOR: the colouring and the spectrum estimate; multigrid: that plus pyamg's
hierarchy and its upload).  Iterations: SOR sweeps, multigrid cycles (CG iterations).
The error column is max|out − spsolve| of the float64 system.
"""

from __future__ import annotations

import argparse
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import rdgpu  # noqa: E402
from rdgpu.domains.graph_surface import GraphSurface  # noqa: E402
from rdgpu.domains.mesh.surface_mesh import SurfaceMesh  # noqa: E402
from rdgpu.domains.surfaces import random_waves  # noqa: E402
from rdgpu.ops.implicit import ImplicitDiffusion  # noqa: E402


def domains(quick: bool) -> dict:
    """The domains timed, smallest first."""
    out = {f"icosphere({k})": (lambda k=k: SurfaceMesh.icosphere(k)) for k in (4, 5, 6)}
    out["graph surface 256²"] = lambda: GraphSurface(
        (256, 256), height=random_waves((256, 256), 4.0, 6, seed=1))
    if quick:
        out = {k: v for k, v in out.items() if "6" not in k and "256" not in k}
    return out


def time_solver(domain, backend: str, solver: str, kappa: float, repeats: int) -> dict:
    """Setup, median step time, iterations and error of one solver."""
    M, _ = domain.operator_matrix()
    d = float(np.median(np.abs(M.diagonal())))
    dt = kappa / d
    t0 = time.perf_counter()
    s = ImplicitDiffusion(domain, D=1.0, dt=dt, backend=backend, dtype=np.float32,
                          solver=solver)
    setup = time.perf_counter() - t0
    be = s.backend
    u = np.random.default_rng(0).random(s.shape)
    du = be.upload(u.astype(np.float32))
    out = be.empty(du.shape, np.float32)
    s.step(du, out)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        s.step(du, out)
        times.append(time.perf_counter() - t0)
    err = float(np.max(np.abs(out.numpy() - s.reference(u))))
    levels = s.multigrid.sizes if s.multigrid is not None else None
    return {"setup": setup, "step": statistics.median(times), "iters": s.last_sweeps,
            "err": err, "levels": levels}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--backends", default="opencl,warp")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--quick", action="store_true", help="icospheres 4 and 5 only")
    ap.add_argument("--out", default=None, help="write the table (markdown) here")
    args = ap.parse_args(argv)
    rows = ["| backend | domain | κ | SOR sweeps | SOR ms/step | MG cycles | MG ms/step "
            "| speed-up | SOR setup s | MG setup s | MG levels | max err SOR / MG |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, make in domains(args.quick).items():
        domain = make()
        for backend in args.backends.split(","):
            for kappa in (10.0, 1000.0):
                r = {sv: time_solver(domain, backend, sv, kappa, args.repeats)
                     for sv in ("sor", "multigrid")}
                sor, mg = r["sor"], r["multigrid"]
                rows.append(
                    f"| {backend} | {name} | {kappa:g} | {sor['iters']} | "
                    f"{1e3 * sor['step']:.1f} | {mg['iters']} | {1e3 * mg['step']:.1f} | "
                    f"{sor['step'] / mg['step']:.2f} | {sor['setup']:.2f} | "
                    f"{mg['setup']:.2f} | {mg['levels']} | {sor['err']:.1e} / "
                    f"{mg['err']:.1e} |")
                print(rows[-1], flush=True)
    head = (f"rdgpu {rdgpu.__version__}, {platform.processor() or platform.machine()}, "
            f"{len(__import__('os').sched_getaffinity(0))} cores, "
            f"{time.strftime('%Y-%m-%d %H:%M')}")
    text = "\n".join([head, "", *rows, ""])
    if args.out:
        Path(args.out).write_text(text)
    else:
        print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
