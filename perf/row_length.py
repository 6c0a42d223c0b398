"""Why the generated grid kernels trail in 3-D (issue 22, item 2): the rate of the fused
Gray-Scott step (float32, periodic, `rdgpu.bench.problem`'s stepper) at about the same
number of cells, in grids whose rows (the x axis, the vectorised inner loop of one
work-item) are long or short.

    python perf/row_length.py [--backend opencl] [--cells 900000]

Rows of 96 cells run far below rows of 960 in 2-D, and a 3-D grid of 96³ below both:
the per-row cost of a work-item (its index arithmetic, the peeled edge cells, the vector
loop's scalar remainder) is paid every ``nx`` cells.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rdgpu.bench.problem import stepper  # noqa: E402


def rate(shape: tuple[int, ...], backend: str, seconds: float = 0.3) -> float:
    """Mcell·steps/s of the fused step on ``shape``: the best of 3 batches."""
    st = stepper(shape, np.float32, backend)
    rng = np.random.default_rng(0)
    st.set_state({"u": 1 - 0.3 * rng.random(shape), "v": 0.3 * rng.random(shape)})
    st.advance(3)
    st.backend.synchronize()
    t = time.perf_counter()
    st.advance(5)
    st.backend.synchronize()
    n = max(5, int(seconds / max(time.perf_counter() - t, 1e-9) * 5))
    best = math.inf
    for _ in range(3):
        t = time.perf_counter()
        st.advance(n)
        st.backend.synchronize()
        best = min(best, time.perf_counter() - t)
    return math.prod(shape) * n / best / 1e6


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--backend", default="opencl")
    a = ap.parse_args(argv)
    shapes = [(960, 960), (96, 9600), (9600, 96), (96, 96, 96), (24, 192, 192)]
    print(f"| grid | row length | Mcell·steps/s ({a.backend}, float32) |")
    print("|---|---:|---:|")
    for shape in shapes:
        label = "×".join(map(str, shape))
        print(f"| {label} | {shape[-1]} | {rate(shape, a.backend):.0f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
