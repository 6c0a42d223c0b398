"""What boundary conditions cost a step (issue 23, item 3): one Gray-Scott-like pair on a
square grid, float32, best of 5 timings of 200 steps (µs a step), with

* the grid's own conditions (periodic, zero-flux Neumann: the kernels' axis codes);
* per-species conditions on every side (face values, a flux, Robin; compiled into the
  kernels as ghost expressions, `rdgpu.ir.boundary`), constant and time-dependent;
* py-pde's Dirichlet/Robin conditions through the py-pde backend's correction fields (two
  per-cell fields per species read by every Laplacian, the path before issue 23) and
  natively (the same conditions as per-species ghosts), fixed-step Euler on the device.

    python perf/boundaries.py [--size 512] [--backends opencl warp]

docs/boundaries.md quotes one run.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from rdgpu.domains import Grid
from rdgpu.models import define_model

MODEL = define_model("bc-cost", {"u": "0.16*laplace(u) - u*v*v + 0.03*(1 - u)",
                                 "v": "0.08*laplace(v) + u*v*v - 0.085*v"})
CASES = {
    "periodic (grid)": ("periodic", None),
    "neumann (grid)": ("neumann", None),
    "value/flux/robin, constant": ("neumann", {
        "u": {"x-": ("value", 1.0), "x+": ("neumann", 0.1), "y": ("robin", 2.0, 0.5)},
        "v": ("value", 0.0)}),
    "value sin(t), flux 0.1*t": ("neumann", {
        "u": {"x-": ("value", "1 + 0.1*sin(t)"), "y": ("neumann", "0.01*t")},
        "v": ("value", 0.0)}),
}


def _time(step, steps: int, repeats: int = 5) -> float:
    step(steps)  # compile, warm up
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        step(steps)
        best = min(best, time.perf_counter() - t0)
    return best / steps * 1e6


def model_rows(n: int, backends: list[str], steps: int) -> None:
    rng = np.random.default_rng(0)
    start = {"u": rng.uniform(0.5, 1, (n, n)), "v": rng.uniform(0, 0.3, (n, n))}
    print(f"{'conditions':32s}" + "".join(f"{b:>12s}" for b in backends))
    for name, (grid_bc, bc) in CASES.items():
        row = []
        for be in backends:
            st = MODEL.stepper(Grid((n, n), bc=grid_bc), dt=0.5, backend=be,
                               dtype="float32", bc=bc, block_steps=1)
            st.set_state(start)

            def step(k, st=st):
                st.advance(k)
                st.get_state()

            row.append(_time(step, steps))
        print(f"{name:32s}" + "".join(f"{v:12.1f}" for v in row))


def pypde_rows(n: int, backends: list[str], steps: int) -> None:
    try:
        import pde

        import rdgpu.integrations.pypde.backend as pb
        import rdgpu.pypde  # noqa: F401 - registers the backend
    except ImportError:
        print("py-pde is not installed: no py-pde rows")
        return
    grid = pde.CartesianGrid([[0, n], [0, n]], [n, n])
    state = pde.ScalarField.random_uniform(grid, 0.2, 0.8, rng=np.random.default_rng(0))
    bc = [[{"value": 1.0}, {"derivative": 0.5}],
          [{"type": "mixed", "value": 2.0, "const": 0.3}, {"value": 0.0}]]
    eq = pde.PDE({"c": "0.2*laplace(c) - c**3 + c"}, bc=bc)
    print(f"\npy-pde PDE with Dirichlet, flux and Robin sides, {n}², fixed-step Euler")
    print(f"{'path':32s}" + "".join(f"{b:>12s}" for b in backends))
    native = pb.native
    for label, patch in (("correction fields (before)", lambda *a: None),
                         ("native ghosts (now)", native)):
        pb.native = patch
        row = []
        try:
            for be in backends:
                def step(k, be=be):
                    eq.solve(state.copy(), t_range=k * 0.1, dt=0.1, solver="euler",
                             backend=f"rdgpu:{be}", tracker=None)

                row.append(_time(step, steps))
        finally:
            pb.native = native
        print(f"{label:32s}" + "".join(f"{v:12.1f}" for v in row))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--backends", nargs="+", default=["opencl", "warp"])
    args = ap.parse_args()
    model_rows(args.size, args.backends, args.steps)
    pypde_rows(args.size, args.backends, args.steps)


if __name__ == "__main__":
    main()
