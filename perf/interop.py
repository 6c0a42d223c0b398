"""What arrays kept on the device and ``out=`` save in a caller's loop (rdgpu.interop).

    python perf/interop.py [--size 1024] [--calls 20] [--repeats 5]

One ``rdgpu.gray_scott(..., steps=1)`` call per loop iteration, float32 ``[size, size]``,
on the warp (CPU) and opencl backends, four ways: NumPy in and out (a host copy each way
per call), NumPy in with ``out=`` NumPy arrays, the backend's own arrays in (Warp CPU
arrays; pyopencl arrays on the backend's context) with new arrays out, and its own arrays
in with ``out=`` its own arrays (no copy at all).  Each time is the best of ``repeats``
means over ``calls`` calls, with the backend synchronised after every call, in ms.
"""

from __future__ import annotations

import argparse
import time
from functools import partial

import numpy as np

import rdgpu

GS = {"Du": 0.16, "Dv": 0.08, "F": 0.035, "k": 0.06, "dt": 1.0}


def best_ms(call, be, calls: int, repeats: int) -> float:
    """Best of ``repeats`` means over ``calls`` synchronised calls, in ms."""
    call()
    be.synchronize()
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(calls):
            call()
            be.synchronize()
        best = min(best, (time.perf_counter() - t0) / calls)
    return best * 1e3


def own_arrays(be, u: np.ndarray, v: np.ndarray):
    """``(u, v, u_out, v_out)`` as the backend's own arrays."""
    if be.name == "warp":
        import warp as wp

        du, dv = wp.array(u, device="cpu"), wp.array(v, device="cpu")
        return du, dv, wp.empty_like(du), wp.empty_like(dv)
    import pyopencl.array as cla

    du, dv = cla.to_device(be.queue, u), cla.to_device(be.queue, v)
    return du, dv, cla.empty_like(du), cla.empty_like(dv)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--calls", type=int, default=20)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    shape = (args.size, args.size)
    u = (1.0 - 0.5 * rng.random(shape)).astype(np.float32)
    v = (0.25 * rng.random(shape)).astype(np.float32)
    print(f"gray_scott steps=1, float32 {args.size}², ms per call")
    print("| backend | NumPy in/out | NumPy in, out=NumPy | own arrays in | own in, out=own |")
    print("|---|---|---|---|---|")
    for name in ("warp", "opencl"):
        be = rdgpu.get_backend(name)
        du, dv, ou, ov = own_arrays(be, u, v)
        nu, nv = np.empty_like(u), np.empty_like(v)
        ways = [(u, v, None), (u, v, (nu, nv)), (du, dv, None), (du, dv, (ou, ov))]
        times = [best_ms(partial(rdgpu.gray_scott, a, b, backend=be, out=out, **GS), be,
                         args.calls, args.repeats) for a, b, out in ways]
        print(f"| {name} | " + " | ".join(f"{t:.2f}" for t in times) + " |")


if __name__ == "__main__":
    main()
