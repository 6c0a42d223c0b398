"""Row length and the generated grid kernels (issue 22, item 2): the rate of the fused
Gray-Scott step (periodic, `rdgpu.bench.problem`'s stepper) at about the same number of
cells, in grids whose rows (the x axis, the vectorised inner loop) are long or short,
with the row kernels (one work-item or thread per row: OpenCL ``rd_program``, Warp
``rows``) and the flat-span kernels (a span of a plane's interior rows as one loop:
``rd_span``, ``spans``) side by side, interleaved in one process.

    python perf/row_length.py [--backends opencl warp] [--dtypes float32 float64]

With one row per work-item, rows of 96 cells ran far below rows of 960 and a 3-D grid of
96³ below both: the per-row cost (index arithmetic, the peeled edge cells, the vector
loop's scalar remainder) is paid every ``nx`` cells; the spans pay it once per span.
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


def rate(shape: tuple[int, ...], backend: str, dtype=np.float32,
         seconds: float = 0.3) -> float:
    """Mcell·steps/s of the fused step on ``shape``: the best of 3 batches."""
    st = stepper(shape, dtype, backend)
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
    from rdgpu.backends import opencl_codegen, warp_codegen

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--backends", nargs="+", default=["opencl", "warp"])
    ap.add_argument("--dtypes", nargs="+", default=["float32"])
    a = ap.parse_args(argv)
    shapes = [(960, 960), (96, 9600), (9600, 96), (96, 96, 96), (24, 192, 192),
              (1024, 64, 64), (32, 32, 32)]
    modules = {"opencl": opencl_codegen, "warp": warp_codegen}
    print("| grid | row length | backend | dtype | rows | spans | spans / rows |")
    print("|---|---:|---|---|---:|---:|---:|")
    for shape in shapes:
        label = "×".join(map(str, shape))
        for name in a.backends:
            module = modules[name]
            default = module.SPAN_CELLS
            for dtype in a.dtypes:
                best = {"rows": 0.0, "spans": 0.0}
                for _ in range(2):  # interleaved: the machine's drift hits both alike
                    for kind, cells in (("rows", 0), ("spans", default)):
                        module.SPAN_CELLS = cells
                        best[kind] = max(best[kind], rate(shape, name, np.dtype(dtype)))
                module.SPAN_CELLS = default
                print(f"| {label} | {shape[-1]} | {name} | {dtype} | {best['rows']:.0f} | "
                      f"{best['spans']:.0f} | {best['spans'] / best['rows']:.2f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
