"""What the operators of the equation language cost a step: one model per operator on a
512² periodic grid, float32, OpenCL and Warp, best of 5 timings of 50 steps (µs a step).

    python perf/operators.py [--size 512] [--backends opencl warp]

Rows: the plain Laplacian, the divergence form with a constant, a field-dependent and an
x-dependent coefficient (the last stored once when the run starts), the Laplacian of an
expression (evaluated by the pass at each neighbour), a bilaplacian and Cahn–Hilliard (a
pre-pass each step).  docs/models.md quotes one run.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from rdgpu.domains import Grid
from rdgpu.models import define_model

CASES = {
    "0.2*laplace(u)": ({"u": "0.2*laplace(u) - 0.01*u"}, 1.0),
    "div(0.2*grad(u))": ({"u": "div(0.2*grad(u)) - 0.01*u"}, 1.0),
    "div((0.1 + 0.1*u*u)*grad(u))": ({"u": "div((0.1 + 0.1*u*u)*grad(u)) - 0.01*u"}, 1.0),
    "div((1 + 0.5*sin(x))*grad(u))": (
        {"u": "0.1*div((1 + 0.5*sin(x))*grad(u)) - 0.01*u"}, 1.0),
    "laplace(u*u)": ({"u": "0.1*laplace(u*u) - 0.01*u"}, 1.0),
    "bilaplacian": ({"u": "-0.1*laplace(laplace(u)) - 0.2*laplace(u) - 0.01*u"}, 0.1),
    "Cahn-Hilliard": ({"u": "laplace(u**3 - u - laplace(u))"}, 0.02),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--backends", nargs="+", default=["opencl", "warp"])
    args = parser.parse_args()
    grid = Grid((args.size, args.size), dx=1.0, bc="periodic")
    print(f"| operator | {' | '.join(args.backends)} |")
    print("|---|" + "---:|" * len(args.backends))
    for name, (equations, dt) in CASES.items():
        model = define_model("probe", equations)
        row = []
        for backend in args.backends:
            st = model.stepper(grid, {}, dt=dt, backend=backend, dtype="float32",
                               check_stability=False)
            st.set_state({"u": np.random.default_rng(0).uniform(-0.5, 0.5, grid.shape)})
            st.advance(5)
            best = np.inf
            for _ in range(5):
                start = time.perf_counter()
                st.advance(50)
                st.get_state()
                best = min(best, (time.perf_counter() - start) / 50)
            row.append(f"{best * 1e6:.0f}")
        print(f"| `{name}` | {' | '.join(row)} |")


if __name__ == "__main__":
    main()
