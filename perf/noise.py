"""What noise costs a step (issue 23, item 5): a Gray-Scott-like pair on a square grid,
float32, best of 5 timings of 100 steps (µs a step), per backend:

* deterministic forward Euler (one fused pass; temporal blocking off, so the rows compare
  passes with passes);
* Euler–Maruyama with additive noise on one species, then on both (one `normal_fill` pass
  per noisy species, then the fused step reading the numbers);
* Milstein with multiplicative noise on both (the same passes, a longer expression);
* the fill alone: one `normal_fill` of one field (µs, and M numbers/s).

    python perf/noise.py [--size 512] [--backends numpy warp opencl]

docs/noise.md quotes one run.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import rdgpu
from rdgpu.domains import Grid
from rdgpu.models import define_model

MODEL = define_model("noise-cost", {"u": "0.16*laplace(u) - u*v*v + 0.03*(1 - u)",
                                    "v": "0.08*laplace(v) + u*v*v - 0.085*v"})
CASES = {
    "deterministic Euler": (None, "euler"),
    "Euler-Maruyama, noise on u": ({"u": 1e-4}, "euler"),
    "Euler-Maruyama, noise on u, v": (1e-4, "euler"),
    "Milstein, u*v-dependent on u, v": ("1e-4*u*v", "milstein"),
}


def _best(run, repeats: int = 5) -> float:
    run()  # compile, warm up
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        run()
        best = min(best, time.perf_counter() - t0)
    return best


def rows(n: int, backends: list[str], steps: int) -> None:
    rng = np.random.default_rng(0)
    start = {"u": rng.uniform(0.5, 1, (n, n)), "v": rng.uniform(0, 0.3, (n, n))}
    print(f"{n}² float32, µs a step (best of 5 × {steps} steps)")
    print(f"{'case':34s}" + "".join(f"{b:>12s}" for b in backends))
    for name, (noise, method) in CASES.items():
        row = []
        for be in backends:
            st = MODEL.stepper(Grid((n, n), bc="periodic"), dt=0.5, backend=be,
                               dtype="float32", block_steps=1, noise=noise, method=method)
            st.set_state(start)

            def run(st=st):
                st.advance(steps)
                st.get_state()

            row.append(_best(run) / steps * 1e6)
        print(f"{name:34s}" + "".join(f"{v:12.1f}" for v in row))
    fills = []
    for be in backends:
        backend = rdgpu.get_backend(be)
        out = backend.empty((n, n), np.float32)
        fill = backend.kernel("noise", "normal_fill")

        def run(out=out, fill=fill):
            for k in range(steps):
                fill(out, seed=1, step=k, stream=0)
            out.numpy()

        fills.append(_best(run) / steps * 1e6)
    print(f"{'one normal_fill (µs)':34s}" + "".join(f"{v:12.1f}" for v in fills))
    print(f"{'  M numbers/s':34s}" + "".join(f"{n * n / v:12.1f}" for v in fills))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--backends", nargs="+", default=["numpy", "warp", "opencl"])
    args = parser.parse_args()
    rows(args.size, args.backends, args.steps)


if __name__ == "__main__":
    main()
