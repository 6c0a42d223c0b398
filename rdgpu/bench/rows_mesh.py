"""Row group ``mesh``: the mesh (CSR) kernels on a geodesic icosphere of about
``vertices`` vertices -- ``spmv`` ``y = L x`` and ``mesh_gray_scott`` -- on every backend
against SciPy (one thread), float32; bytes per row: see `mesh_bytes`.  Each backend's
step is checked against SciPy's before it is timed.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from rdgpu.backends.base import Backend
from rdgpu.backends.registry import get_backend
from rdgpu.bench.context import Context
from rdgpu.bench.devices import add_ratios, add_roofline, fmt, memory_of, roof_text, time_case
from rdgpu.domains.mesh.surface_mesh import SurfaceMesh

__all__ = ["DEFAULT_VERTICES", "MESH_KERNELS", "QUICK_VERTICES", "geodesic_sphere",
           "markdown", "mesh_bytes", "run"]

MESH_KERNELS = ("spmv", "mesh_gray_scott")
DEFAULT_VERTICES = 1_000_000
QUICK_VERTICES = 2_000
TOLERANCE = 1e-4  # max |diff| / (1 + max |SciPy|), float32, one step
_PARAMS = dict(Du=2e-5, Dv=1e-5, F=0.035, k=0.06, dt=1e-3)


def geodesic_sphere(frequency: int) -> SurfaceMesh:
    """Unit geodesic sphere: every icosahedron face cut into ``frequency²`` triangles,
    vertices projected to the sphere; ``10 f² + 2`` vertices numbered face by face (each
    new vertex in the order the faces' barycentric grids reach it), ``20 f²`` faces."""
    import trimesh

    f = int(frequency)
    ico = trimesh.creation.icosahedron()
    V0, F0 = np.asarray(ico.vertices, dtype=np.float64), np.asarray(ico.faces, dtype=np.int64)
    i, j = (a.ravel() for a in np.meshgrid(np.arange(f + 1), np.arange(f + 1), indexing="ij"))
    keep = i + j <= f
    i, j = i[keep], j[keep]
    k = f - i - j
    lut = np.full((f + 1, f + 1), -1, dtype=np.int64)
    lut[i, j] = np.arange(i.size)
    up = i + j < f
    tri = [np.stack([lut[i[up], j[up]], lut[i[up] + 1, j[up]], lut[i[up], j[up] + 1]], 1)]
    dn = i + j < f - 1
    tri.append(np.stack([lut[i[dn] + 1, j[dn]], lut[i[dn] + 1, j[dn] + 1],
                         lut[i[dn], j[dn] + 1]], 1))
    local_tris = np.concatenate(tri)
    # every point of every face as (corner, weight) pairs; a canonical key merges the points
    # that faces share (edges, corners) exactly, without comparing coordinates
    corners = np.repeat(F0, i.size, axis=0).reshape(20, i.size, 3)
    weights = np.broadcast_to(np.stack([k, i, j], 1), (20, i.size, 3))
    corners = np.where(weights > 0, corners, 15).reshape(-1, 3)
    weights = weights.reshape(-1, 3)
    order = np.argsort(corners, axis=1, kind="stable")
    c = np.take_along_axis(corners, order, 1)
    w = np.take_along_axis(weights, order, 1)
    key = ((c[:, 0] * 4096 + w[:, 0]) * 65536 + c[:, 1] * 4096 + w[:, 1]) * 65536 \
        + c[:, 2] * 4096 + w[:, 2]
    _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    rank = np.empty(first.size, dtype=np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(first.size)
    vid = rank[inverse.ravel()]
    pts = (weights[:, :, None] * V0[np.where(corners == 15, 0, corners)]).sum(1) / f
    V = np.empty((first.size, 3))
    V[vid] = pts
    V /= np.linalg.norm(V, axis=1, keepdims=True)
    faces = (vid.reshape(20, i.size)[:, local_tris]).reshape(-1, 3)
    return SurfaceMesh(V, faces)


def mesh_bytes(L) -> tuple[float, float]:
    """(lower, upper) bytes per row of ``y = L x`` (float32 values, int32 indices):
    ``indptr`` 4 + (``indices`` 4 + ``data`` 4) per stored entry + ``y`` 4, and ``x`` 4
    once per row (the lower bound: the caches catch the reuse of ``x[j]`` by the ~7 rows
    sharing it) or once per stored entry (the upper bound)."""
    per_row_entries = L.nnz / L.shape[0]
    base = 4 + 8 * per_row_entries + 4  # indptr, indices + data, y
    return base + 4, base + 4 * per_row_entries


def _inputs(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    x = np.random.default_rng(0).random(n, np.float32)
    u, v = np.ones(n, np.float32), np.zeros(n, np.float32)
    u[: n // 20], v[: n // 20] = 0.5, 0.25
    return x, u, v


def _scipy_case(kernel: str, L, n: int) -> Callable[[], object]:
    f32 = np.float32
    x, u, v = _inputs(n)
    L32 = L.astype(f32)
    if kernel == "spmv":
        return lambda: L32 @ x
    h, F, k = f32(_PARAMS["dt"]), f32(_PARAMS["F"]), f32(_PARAMS["k"])
    Du, Dv = f32(_PARAMS["Du"]), f32(_PARAMS["Dv"])

    def gs():
        uvv = u * v * v
        return (u + h * (Du * (L32 @ u) - uvv + F * (f32(1) - u)),
                v + h * (Dv * (L32 @ v) + uvv - (F + k) * v))

    return gs


def _device_case(kernel: str, be: Backend, L, n: int) -> tuple[Callable[[], None], list]:
    f32 = np.float32
    x, u, v = _inputs(n)
    A = be.upload_csr(L, f32)
    if kernel == "spmv":
        dx, y = be.upload(x), be.empty((n,), f32)
        return (lambda: be.spmv(A, dx, y)), [y]
    bufs = [be.upload(u), be.upload(v), be.empty((n,), f32), be.empty((n,), f32)]

    def step():
        be.mesh_gray_scott(A, bufs[0], bufs[1], bufs[2], bufs[3], **_PARAMS)
        bufs[:] = [bufs[2], bufs[3], bufs[0], bufs[1]]

    return step, bufs


def _check(kernel: str, be: Backend, L, n: int) -> str | None:
    """None when one step on ``be`` agrees with SciPy's, else what differed."""
    want = _scipy_case(kernel, L, n)()
    ref = np.asarray(want[0] if isinstance(want, tuple) else want, np.float64)
    step, bufs = _device_case(kernel, be, L, n)
    step()
    be.synchronize()
    got = np.asarray(be.download(bufs[0]), np.float64)
    err = float(np.max(np.abs(got - ref))) / (1 + float(np.max(np.abs(ref))))
    return None if err <= TOLERANCE else f"disagrees with SciPy: relative error {err:.2e}"


def _kernel_rows(ctx: Context, kernel: str, L, per_row: float, upper: float) -> list[dict]:
    n = L.shape[0]
    host = get_backend("numpy")
    found = []
    for name in ("scipy", *ctx.backends):
        be = host if name == "scipy" else ctx.backends[name]
        refused = None if name == "scipy" else _check(kernel, be, L, n)
        row = dict(kernel=kernel, size=n, cells=n, backend=name, nnz=L.nnz,
                   device="cpu (SciPy, 1 thread)" if name == "scipy" else be.device,
                   status="refused" if refused else "ok", note=refused)
        if refused is None:
            step = (_scipy_case(kernel, L, n) if name == "scipy"
                    else _device_case(kernel, be, L, n)[0])
            seconds = time_case(be, step, ctx.seconds)
            row.update(seconds_per_step=seconds, mvertices=n / seconds / 1e6,
                       mcells=n / seconds / 1e6, bytes_per_row=per_row,
                       bytes_per_row_upper=upper)
            add_roofline(row, memory_of(name, ctx.memory), per_row)
            ctx.say(f"  {kernel:16s} {n:8d}v {name:12s} {row['mvertices']:9.1f} Mvertex/s")
        found.append(row)
    ok = [r for r in found if r["status"] == "ok"]
    add_ratios(ok, ("kernel",), "scipy", "vs_scipy")
    add_ratios(ok, ("kernel",))
    return found


def run(ctx: Context, vertices: int) -> list[dict]:
    """Both mesh kernels on an icosphere of about ``vertices`` vertices."""
    f = max(1, round(((vertices - 2) / 10) ** 0.5))
    t0 = time.perf_counter()
    L = geodesic_sphere(f).laplacian
    n = L.shape[0]
    ctx.say(f"mesh: geodesic sphere f={f}: {n} vertices, {L.nnz} stored entries "
            f"({L.nnz / n:.2f}/row), assembled in {time.perf_counter() - t0:.1f} s")
    lower, upper = mesh_bytes(L)
    gs_bytes = 4 + 8 * L.nnz / n + 16
    return (_kernel_rows(ctx, "spmv", L, lower, upper)
            + _kernel_rows(ctx, "mesh_gray_scott", L, gs_bytes, gs_bytes + 8 * L.nnz / n))


def markdown(rows: list[dict], ctx: Context) -> list[str]:
    """The mesh kernels' table."""
    first = next(r for r in rows if r["status"] == "ok")
    lines = ["Mesh kernels (float32 CSR `L = A⁻¹W` on a geodesic icosphere), each backend "
             "checked against SciPy first. Roofline bytes per row: "
             f"{first['bytes_per_row']:.1f} (SpMV, x counted once per vertex: the lower "
             f"bound; once per entry would be {first['bytes_per_row_upper']:.1f}).", "",
             ctx.ran_on(), "",
             "| kernel | vertices | backend | Mvertex/s | × SciPy | × NumPy | working set / "
             "LLC | % roofline |", "|---|---:|---|---:|---:|---:|---:|---:|"]
    for r in rows:
        if r["status"] != "ok":
            lines.append(f"| {r['kernel']} | {r['size']} | {r['backend']} | refused: "
                         f"{r['note']} | | | | |")
            continue
        lines.append(f"| {r['kernel']} | {r['size']} | {r['backend']} | {r['mvertices']:.0f} | "
                     f"{fmt(r['vs_scipy'], '.2f')} | {fmt(r['speedup'], '.1f')} | "
                     f"{fmt(r['working_set_over_llc'], '.1f')} | {roof_text(r)} |")
    return lines
