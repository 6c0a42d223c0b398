"""Warp CUDA launch shapes for a five-point Laplacian (float32, interior cells, 8192²): one
thread per cell (rdgpu's CUDA shape), flat or 2-D, and several cells per thread along a row
or down a column.  Run on a machine with an NVIDIA GPU: ``python perf/warp_cuda_probe.py``;
results of 2026-11-27 on an H200 in perf/results/gpu-h200/warp_cuda_probe.md."""
import time

import numpy as np
import warp as wp

wp.init()
dev = "cuda:0"
n = 8192


@wp.kernel
def lap2d(u: wp.array2d(dtype=wp.float32), out: wp.array2d(dtype=wp.float32)):
    i, j = wp.tid()
    if i > 0 and i < u.shape[0] - 1 and j > 0 and j < u.shape[1] - 1:
        out[i, j] = u[i - 1, j] + u[i + 1, j] + u[i, j - 1] + u[i, j + 1] - 4.0 * u[i, j]


@wp.kernel
def lapflat2d(u: wp.array(dtype=wp.float32), out: wp.array(dtype=wp.float32), nx: int, ny: int):
    i, j = wp.tid()
    if i > 0 and i < ny - 1 and j > 0 and j < nx - 1:
        k = i * nx + j
        out[k] = u[k - nx] + u[k + nx] + u[k - 1] + u[k + 1] - 4.0 * u[k]


@wp.kernel
def lapflat1d(u: wp.array(dtype=wp.float32), out: wp.array(dtype=wp.float32), nx: int, ny: int):
    k = wp.tid()
    i = k // nx
    j = k - i * nx
    if i > 0 and i < ny - 1 and j > 0 and j < nx - 1:
        out[k] = u[k - nx] + u[k + nx] + u[k - 1] + u[k + 1] - 4.0 * u[k]


@wp.kernel
def copy1d(u: wp.array(dtype=wp.float32), out: wp.array(dtype=wp.float32)):
    k = wp.tid()
    out[k] = u[k]


u2 = wp.array(np.random.rand(n, n).astype(np.float32), device=dev)
o2 = wp.zeros((n, n), dtype=wp.float32, device=dev)
u1, o1 = u2.flatten(), o2.flatten()


def bench(name, kernel, dim, inputs):
    wp.launch(kernel, dim=dim, inputs=inputs, device=dev)
    wp.synchronize_device(dev)
    reps = 50
    t = time.perf_counter()
    for _ in range(reps):
        wp.launch(kernel, dim=dim, inputs=inputs, device=dev)
    wp.synchronize_device(dev)
    dt = (time.perf_counter() - t) / reps
    rate = n * n / dt
    print(f"{name:12s} {rate / 1e6:10.0f} Mcell/s  {8 * rate / 1e9:7.0f} GB/s (8 B/cell)")


bench("copy1d", copy1d, n * n, [u1, o1])
bench("lap2d", lap2d, (n, n), [u2, o2])
bench("lapflat2d", lapflat2d, (n, n), [u1, o1, n, n])
bench("lapflat1d", lapflat1d, n * n, [u1, o1, n, n])
# recorded launch (what rdgpu does)
cmd = wp.launch(lap2d, dim=(n, n), inputs=[u2, o2], device=dev, record_cmd=True)
wp.synchronize_device(dev)
t = time.perf_counter()
for _ in range(50):
    cmd.launch()
wp.synchronize_device(dev)
dt = (time.perf_counter() - t) / 50
print(f"lap2d rec     {n * n / dt / 1e6:10.0f} Mcell/s")


@wp.kernel
def laprows(u: wp.array(dtype=wp.float32), out: wp.array(dtype=wp.float32), nx: int, ny: int,
            stride: int):
    i, c = wp.tid()
    if i > 0 and i < ny - 1:
        j = c
        r = i * nx
        while j < nx:
            if j > 0 and j < nx - 1:
                k = r + j
                out[k] = u[k - nx] + u[k + nx] + u[k - 1] + u[k + 1] - 4.0 * u[k]
            j += stride


for s in (64, 128, 256, 512, 1024):
    bench(f"laprows{s}", laprows, (n, s), [u1, o1, n, n, s])


@wp.kernel
def lapcols(u: wp.array(dtype=wp.float32), out: wp.array(dtype=wp.float32), nx: int, ny: int,
            per: int):
    # thread (b, j): rows b*per .. b*per+per-1 of column j, marching down the column
    b, j = wp.tid()
    if j > 0 and j < nx - 1:
        i0 = wp.max(b * per, 1)
        i1 = wp.min(b * per + per, ny - 1)
        i = i0
        while i < i1:
            k = i * nx + j
            out[k] = u[k - nx] + u[k + nx] + u[k - 1] + u[k + 1] - 4.0 * u[k]
            i += 1


for per in (4, 16, 64):
    bench(f"lapcols{per}", lapcols, ((n + per - 1) // per, n), [u1, o1, n, n, per])
