"""Seed 002 §4's convergence table: reaction-diffusion on a rough surface, space and time
refined together.

    python perf/surface_rds.py [--backend numpy] [--out perf/results]

The manufactured two-species system of ``rdgpu/families/metric/exact.py`` (``manufactured_rds``:
a graph surface over ``[0, 2π]²``, exact solution ``u = e^{−t}φ``, ``v = e^{−t}ψ``) is
stepped to ``T = 0.5`` on ``n²`` cells with ``n/4`` steps (``dt ∝ dx``), float64, by BDF2
(seed 002 eq. 18) and IMEX Euler.  Prints and writes ``surface_rds.md``: the max over the
species of the relative ℓ² error, and the observed order between neighbouring rows.
The error is :func:`rdgpu.analysis.convergence.space_time_error`;
``tests/theory/test_surface_rds.py`` asserts the orders with it.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from rdgpu.analysis.convergence import space_time_error


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--backend", default="numpy")
    ap.add_argument("--out", type=Path, default=Path(__file__).parent / "results")
    args = ap.parse_args()
    ns = [16, 32, 64, 128]
    lines = ["| n (cells per side) | steps | " + " | ".join(
        f"{m} error | {m} order" for m in ("bdf2", "imex")) + " |",
        "|---:|---:|---:|---:|---:|---:|"]
    errors = {m: [space_time_error(n, m, args.backend) for n in ns] for m in ("bdf2", "imex")}
    for i, n in enumerate(ns):
        cells = []
        for m in ("bdf2", "imex"):
            e = errors[m]
            order = f"{math.log2(e[i - 1] / e[i]):.2f}" if i else ""
            cells += [f"{e[i]:.3e}", order]
        lines.append(f"| {n} | {n // 4} | " + " | ".join(cells) + " |")
    text = "\n".join(lines) + "\n"
    print(text)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "surface_rds.md").write_text(text)


if __name__ == "__main__":
    main()
