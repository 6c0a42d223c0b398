"""Run by tests/core/test_threads.py in a fresh process: four threads that each, at once and
from a cold start, call several rdgpu functions on a backend, checked against NumPy.

Usage: ``python thread_worker.py MODE ROUNDS SWITCH_INTERVAL`` with MODE ``mixed`` (the
threads use ``warp``, ``warp:cpu``, ``opencl`` and ``numpy``), ``warp`` or ``opencl`` (all
four share that backend).  Each thread has its own inputs, so a launch that picks up
another thread's arguments gives a wrong result.  The references are computed first, with
the NumPy backend only, so Warp and OpenCL are first initialised by the threads
themselves.  Prints ``OK ...`` and exits 0, or prints every mismatch and exits 1 (a crash
exits by signal).
"""

from __future__ import annotations

import sys
import threading

import numpy as np
import scipy.sparse as sp

import rdgpu

MODES = {
    "mixed": ["warp", "warp:cpu", "opencl", "numpy"],
    "warp": ["warp"] * 4,
    "opencl": ["opencl"] * 4,
}


def inputs(k: int) -> dict:
    """Thread ``k``'s problem: sizes and values differ between threads."""
    rng = np.random.default_rng(100 + k)
    n = 24 + 2 * k
    fixed = np.zeros((n, n), bool)
    fixed[0, :] = True
    c = np.zeros((n, n))
    c[0, :] = 1.0 + k
    y, x = np.mgrid[0:n, 0:n] - n / 2
    return {
        "a": rng.random((n, n + 3)),
        "u": 1 - 0.5 * rng.random((n, n)),
        "v": 0.25 * rng.random((n, n)),
        "c": c,
        "fixed": fixed,
        "phi": np.sqrt(x**2 + y**2) - (3 + k),
        "A": sp.random(50 + k, 40 + k, density=0.2, random_state=k, format="csr"),
        "x": rng.random(40 + k),
    }


def work(backend: str, k: int) -> dict:
    d = inputs(k)
    out = {
        "laplacian": rdgpu.laplacian(d["a"], dx=0.5, dy=0.7, bc="periodic", backend=backend),
        "gray_scott": np.stack(rdgpu.gray_scott(
            d["u"], d["v"], Du=0.16, Dv=0.08, F=0.035, k=0.06, dt=1.0, steps=3,
            bc="periodic", backend=backend)),
        "levelset": rdgpu.levelset_advance(d["phi"], 0.5, dt=0.4, steps=3, backend=backend),
        "spmv": rdgpu.spmv(d["A"], d["x"], backend=backend),
    }
    c, sweeps, _ = rdgpu.sor_solve(d["c"], d["fixed"], tol=1e-8, bc=("dirichlet", 0.0),
                                   backend=backend)
    out["sor"], out["sor_sweeps"] = c, sweeps
    return out


def compare(got: dict, expected: dict) -> list[str]:
    """Float64 results of every backend agree with NumPy to round-off (1e-10 is ~10⁵ ulps
    of these O(1) values, and far below any mix-up); SOR stops after the same sweep."""
    bad = []
    for key, ref in expected.items():
        if key == "sor_sweeps":
            if got[key] != ref:
                bad.append(f"sor took {got[key]} sweeps, NumPy {ref}")
        elif not np.allclose(got[key], ref, rtol=1e-10, atol=1e-10):
            bad.append(f"{key} off by {float(np.max(np.abs(got[key] - ref))):.3g}")
    return bad


def main() -> int:
    mode, rounds, interval = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
    names = MODES[mode]
    expected = [work("numpy", k) for k in range(len(names))]
    # switch threads every `interval` seconds of bytecode (default 5 ms): a short interval
    # makes a thread lose the GIL inside any unguarded read-modify-write far more often
    sys.setswitchinterval(interval)
    start = threading.Barrier(len(names))
    problems: list[str] = []

    def run(k: int) -> None:
        try:
            start.wait()
            for r in range(rounds):
                for msg in compare(work(names[k], k), expected[k]):
                    problems.append(f"thread {k} ({names[k]}) round {r}: {msg}")
        except BaseException as exc:  # noqa: BLE001 - report anything, exit non-zero
            problems.append(f"thread {k} ({names[k]}): {type(exc).__name__}: {exc}")

    threads = [threading.Thread(target=run, args=(k,)) for k in range(len(names))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    if problems:
        print("\n".join(problems))
        return 1
    print(f"OK {mode}: {len(names)} threads x {rounds} rounds")
    return 0


if __name__ == "__main__":
    sys.exit(main())
