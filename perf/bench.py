"""Benchmark every grid kernel and the mesh (CSR) kernels on every backend, in one run.

    python perf/bench.py [--sizes 256 1024 2048] [--seconds 0.4] [--out perf/results]
                         [--mesh-vertices 1000000] [--mesh-kernels spmv mesh_gray_scott]

Prints and saves (JSON and a Markdown table) Mcell/s, the ratio to NumPy measured in the
same run, and the fraction of the memory-bandwidth roofline: the machine's bandwidth is
measured here (a STREAM-style triad, the best of NumPy on one core and OpenCL on all),
and each kernel's roofline is bandwidth / (bytes it must move per cell).

Model rows (``--model-size N``, 0 to skip; ``--models``): every built-in model's generated
fused step (``model.stepper``, float32, an N² periodic grid, near its steady state) in
Mcell/s and as a fraction of the hand-written Gray-Scott kernel timed in the same run.

Real-state rows (``--real-size N``, 0 to skip): presets advanced from their default initial
conditions, the first 200 steps against steps 2000-2200 of the same run (see
``perf/real_states.py``): random fields never show the slowdown of subnormal floats.

Mesh rows (``--mesh-vertices N``, 0 to skip): a geodesic icosphere with about N vertices
(class-I subdivision of the icosahedron at frequency f, ``10 f² + 2`` vertices, ordered face
by face), float32 ``L = A⁻¹W``.  ``spmv`` is ``y = L x``; ``mesh_gray_scott`` one fused
Gray-Scott step.  Rows per backend plus a ``scipy`` baseline (``L @ x``, single-threaded;
for Gray-Scott two ``L @`` products plus the NumPy update); Mvertex/s, the ratio to SciPy and
to the NumPy backend (the reference kernels), and the roofline fraction.  Bytes a CSR row
moves (float32, int32): ``indptr`` 4 + (``indices`` 4 + ``data`` 4) per stored entry + ``x``
4 + ``y`` 4 — ``x`` counted once per vertex, the *lower* bound (the caches catch the reuse of
``x[j]`` by the ~7 rows that share it; counting it once per stored entry, the upper bound,
adds 4 per entry and is saved as ``bytes_per_row_upper``).  Gray-Scott: ``indptr``, indices
and data once, ``u``, ``v`` read, ``u'``, ``v'`` written.  The roofline fraction uses the
lower bound, i.e. the most demanding roofline.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

try:
    import rdgpu
except ImportError:  # run from a source checkout without installing
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    import rdgpu
from rdgpu.boundary import parse_bc

# Bytes a kernel must move per cell in float32 (reads + writes of full arrays).
BYTES_PER_CELL = {
    "laplacian": 8,  # read u, write Lu
    "bernoulli": 8,  # read u, write u'
    "gray_scott": 16,  # read u, v; write u', v'
    "sor_sweep": 14,  # two half-sweeps: read c (4) + write half (2) + mask (1), twice
    "levelset_step": 8,  # read phi, write phi'
    "reinit_step": 12,  # read phi, phi0; write phi'
}


def measure_bandwidth(seconds: float) -> dict:
    """Triad ``a = b + s c`` on 32 Mi floats: NumPy (one core) and OpenCL (all cores)."""
    n = 1 << 25
    b = np.random.rand(n).astype(np.float32)
    c = np.random.rand(n).astype(np.float32)
    a = np.empty_like(b)
    best = float("inf")
    end = time.perf_counter() + seconds
    while time.perf_counter() < end or best == float("inf"):
        t0 = time.perf_counter()
        np.multiply(c, np.float32(3.0), out=a)
        np.add(a, b, out=a)
        best = min(best, time.perf_counter() - t0)
    # np.multiply + np.add move 5 arrays' worth (c, a, a, b, a); count the triad's 3.
    result = {"numpy_triad_GBps": 3 * 4 * n / best / 1e9}
    try:
        import pyopencl as cl

        be = rdgpu.get_backend("opencl")
        ctx, queue = be.context, be.queue
        prg = cl.Program(ctx, """
            __kernel void triad(__global float *a, __global const float *b,
                                __global const float *c, float s) {
                size_t i = get_global_id(0); a[i] = b[i] + s * c[i]; }""").build()
        mf = cl.mem_flags
        db = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=b)
        dc = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=c)
        da = cl.Buffer(ctx, mf.WRITE_ONLY, a.nbytes)
        kernel = prg.triad
        best = float("inf")
        end = time.perf_counter() + seconds
        while time.perf_counter() < end or best == float("inf"):
            t0 = time.perf_counter()
            kernel(queue, (n,), None, da, db, dc, np.float32(3.0))
            queue.finish()
            best = min(best, time.perf_counter() - t0)
        result["opencl_triad_GBps"] = 3 * 4 * n / best / 1e9
    except Exception as exc:  # noqa: BLE001 - bandwidth from NumPy alone then
        result["opencl_error"] = str(exc)
    result["GBps"] = max(v for k, v in result.items() if k.endswith("GBps"))
    return result


def make_case(kernel: str, be, n: int):
    """Device inputs for one kernel and a closure running one step (ping-pong inside)."""
    rng = np.random.default_rng(0)
    shape = (n, n)
    bc = parse_bc("periodic")
    f32 = np.float32
    if kernel == "laplacian":
        u, out = be.upload(rng.random(shape, f32)), be.empty(shape, f32)
        return lambda: be.laplacian(u, out, dx=1.0, dy=1.0, bc=bc, stencil=5)
    if kernel == "bernoulli":
        bufs = [be.upload(rng.uniform(-1, 1, shape).astype(f32)), be.empty(shape, f32)]

        def step():
            be.bernoulli(bufs[0], bufs[1], decay=0.99)
            bufs.reverse()

        return step
    if kernel == "gray_scott":
        u = np.ones(shape, f32)
        v = np.zeros(shape, f32)
        u[n // 3: n // 2, n // 3: n // 2], v[n // 3: n // 2, n // 3: n // 2] = 0.5, 0.25
        bufs = [be.upload(u), be.upload(v), be.empty(shape, f32), be.empty(shape, f32)]

        def step():
            be.gray_scott(bufs[0], bufs[1], bufs[2], bufs[3], Du=0.16, Dv=0.08, F=0.035,
                          k=0.06, dt=1.0, dx=1.0, dy=1.0, bc=bc)
            bufs[:] = [bufs[2], bufs[3], bufs[0], bufs[1]]

        return step
    if kernel == "sor_sweep":
        c = be.upload(rng.random(shape, f32))
        fixed = np.zeros(shape, np.uint8)
        fixed[0] = 1
        d_fixed, change = be.upload(fixed), be.empty((n,), f32)
        omega = rdgpu.optimal_omega(shape)

        def step():
            for color in (0, 1):
                be.sor_half_sweep(c, d_fixed, None, change, color=color, omega=omega, dx=1.0,
                                  dy=1.0, bc=bc)

        return step
    i, j = np.indices(shape)
    phi = (np.sqrt((i - n / 2) ** 2 + (j - n / 2) ** 2) - n / 4).astype(f32)
    if kernel == "levelset_step":
        bufs = [be.upload(phi), be.empty(shape, f32)]

        def step():
            be.levelset_step(bufs[0], 1.0, bufs[1], dt=0.4, dx=1.0, dy=1.0, bc=bc)
            bufs.reverse()

        return step
    if kernel == "reinit_step":
        phi0 = be.upload(phi * 3)
        bufs = [be.upload(phi * 3), be.empty(shape, f32)]

        def step():
            be.reinit_step(bufs[0], phi0, bufs[1], dtau=0.5, width=1.0, dx=1.0, dy=1.0, bc=bc)
            bufs.reverse()

        return step
    raise ValueError(kernel)


def time_case(be, step, seconds: float) -> float:
    """Best seconds per step: warm up, then time batches until ``seconds`` have passed."""
    step()
    be.synchronize()
    t0 = time.perf_counter()
    step()
    be.synchronize()
    one = max(time.perf_counter() - t0, 1e-7)
    batch = max(1, int(0.05 / one))
    best = float("inf")
    end = time.perf_counter() + seconds
    while time.perf_counter() < end or best == float("inf"):
        t0 = time.perf_counter()
        for _ in range(batch):
            step()
        be.synchronize()
        best = min(best, (time.perf_counter() - t0) / batch)
    return best


# ---------------------------------------------------------------------------- model rows
def model_case(model, be, n: int):
    """A float32 stepper of ``model`` on an n² periodic grid (fields near its steady state
    with ±10 % noise, dt half the stability limit, capped by the model's own step) and a
    closure advancing it one step."""
    from rdgpu.domains import Grid

    grid = Grid((n, n), bc="periodic")
    rng = np.random.default_rng(1)
    guess = model.steady_guess({}) or [0.5] * len(model.species)
    own = (model.default_dt(dict(model.defaults)) if callable(model.default_dt)
           else model.default_dt)
    dt = min(0.5 * model.dt_limit(grid, {}), own or np.inf)
    st = model.stepper(grid, {}, dt=dt, backend=be, dtype=np.float32)
    st.set_state({s: (x + 0.1 * (abs(x) + 0.1) * rng.uniform(-1, 1, grid.shape))
                  for s, x in zip(model.species, guess, strict=True)})
    return lambda: st.advance(1)


def model_bytes(model) -> int:
    """float32 bytes a step must move per cell: each species read and written once (the
    fused kernel); Allen-Cahn's Bernoulli pass moves its field once more."""
    extra = 8 if model.name == "allen-cahn" else 0
    return 8 * len(model.species) + extra


def model_rows(args, backends: dict, bw: dict) -> list[dict]:
    """Every built-in model's generated fused step against the hand-written Gray-Scott
    kernel (``backend.gray_scott``), side by side in this run, at ``--model-size``; the
    roofline counts :func:`model_bytes` per cell."""
    from rdgpu.models import MODELS

    n = args.model_size
    rows = []
    for name, be in backends.items():
        hand = n * n / time_case(be, make_case("gray_scott", be, n), args.seconds) / 1e6
        roof = bw["GBps"] * 1e9 / 16 / 1e6
        rows.append(dict(kernel="model", model="gray-scott (hand-written)", size=n,
                         backend=name, device=be.device, mcells=hand, vs_hand=1.0,
                         roofline_fraction=hand / roof))
        print(f"model {'gray-scott (hand)':26s} {n}² {name:7s} {hand:9.1f} Mcell/s", flush=True)
        for mname in args.models:
            model = MODELS[mname]
            mc = n * n / time_case(be, model_case(model, be, n), args.seconds) / 1e6
            roof = bw["GBps"] * 1e9 / model_bytes(model) / 1e6
            rows.append(dict(kernel="model", model=mname, size=n, backend=name,
                             device=be.device, mcells=mc, vs_hand=mc / hand,
                             species=len(model.species), roofline_fraction=mc / roof))
            print(f"model {mname:26s} {n}² {name:7s} {mc:9.1f} Mcell/s "
                  f"x{mc / hand:5.2f} hand-written GS", flush=True)
    return rows


def model_markdown(rows: list[dict]) -> str:
    if not rows:
        return ""
    lines = ["", f"Models: one fused generated step per model (float32, {rows[0]['size']}², "
             "periodic), against the hand-written Gray-Scott kernel in the same run.", "",
             "| model | backend | Mcell/s | × hand-written Gray-Scott | % roofline |",
             "|---|---|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['model']} | {r['backend']} | {r['mcells']:.0f} | "
                     f"{r['vs_hand']:.2f} | {100 * r['roofline_fraction']:.0f} |")
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------- mesh rows
MESH_KERNELS = ("spmv", "mesh_gray_scott")


def geodesic_sphere(frequency: int):
    """Unit geodesic sphere: every icosahedron face cut into ``frequency²`` triangles,
    vertices projected to the sphere; ``10 f² + 2`` vertices numbered face by face (each
    new vertex in the order the faces' barycentric grids reach it), ``20 f²`` faces."""
    import trimesh

    from rdgpu.mesh import SurfaceMesh

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
    """(lower, upper) bytes per row of ``y = L x`` in float32 (see the module doc)."""
    n = L.shape[0]
    per_row_entries = L.nnz / n
    base = 4 + 8 * per_row_entries + 4  # indptr, indices + data, y
    return base + 4, base + 4 * per_row_entries


def make_mesh_case(kernel: str, name: str, be, L, n: int):
    """A closure running one step of ``kernel`` on backend ``be`` (``name == "scipy"``: the
    SciPy baseline on the host)."""
    f32 = np.float32
    rng = np.random.default_rng(0)
    x = rng.random(n, f32)
    u = np.ones(n, f32)
    v = np.zeros(n, f32)
    u[: n // 20], v[: n // 20] = 0.5, 0.25
    params = dict(Du=2e-5, Dv=1e-5, F=0.035, k=0.06, dt=1e-3)
    if name == "scipy":
        L32 = L.astype(f32)
        if kernel == "spmv":
            return lambda: L32 @ x
        h, F, k = f32(params["dt"]), f32(params["F"]), f32(params["k"])
        Du, Dv = f32(params["Du"]), f32(params["Dv"])

        def gs():
            uvv = u * v * v
            return (u + h * (Du * (L32 @ u) - uvv + F * (f32(1) - u)),
                    v + h * (Dv * (L32 @ v) + uvv - (F + k) * v))

        return gs
    A = be.upload_csr(L, f32)
    if kernel == "spmv":
        dx, y = be.upload(x), be.empty((n,), f32)
        return lambda: be.spmv(A, dx, y)
    bufs = [be.upload(u), be.upload(v), be.empty((n,), f32), be.empty((n,), f32)]

    def step():
        be.mesh_gray_scott(A, bufs[0], bufs[1], bufs[2], bufs[3], **params)
        bufs[:] = [bufs[2], bufs[3], bufs[0], bufs[1]]

    return step


def mesh_rows(args, backends: dict, bw: dict) -> list[dict]:
    f = max(1, round(((args.mesh_vertices - 2) / 10) ** 0.5))
    t0 = time.perf_counter()
    mesh = geodesic_sphere(f)
    L = mesh.laplacian
    n = mesh.n_vertices
    print(f"mesh: geodesic sphere f={f}: {n} vertices, {L.nnz} stored entries "
          f"({L.nnz / n:.2f}/row), assembled in {time.perf_counter() - t0:.1f} s", flush=True)
    lower, upper = mesh_bytes(L)
    gs_bytes = 4 + 8 * L.nnz / n + 16
    rows = []
    host = rdgpu.get_backend("numpy")
    for kernel in args.mesh_kernels:
        per_row = lower if kernel == "spmv" else gs_bytes
        roof = bw["GBps"] * 1e9 / per_row / 1e6
        timed = {}
        for name in ("scipy", *backends):
            be = host if name == "scipy" else backends[name]
            timed[name] = time_case(be, make_mesh_case(kernel, name, be, L, n), args.seconds)
        for name, seconds in timed.items():
            mv = n / seconds / 1e6
            row = dict(kernel=kernel, size=n, backend=name,
                       device="cpu (SciPy, 1 thread)" if name == "scipy"
                       else backends[name].device,
                       seconds_per_step=seconds, mvertices=mv, mcells=mv,
                       vs_scipy=timed["scipy"] / seconds,
                       speedup=timed["numpy"] / seconds if "numpy" in timed else float("nan"),
                       bytes_per_row=per_row,
                       bytes_per_row_upper=upper if kernel == "spmv" else gs_bytes
                       + 8 * L.nnz / n,
                       roofline_mcells=roof, roofline_fraction=mv / roof, nnz=L.nnz)
            rows.append(row)
            print(f"{kernel:16s} {n:8d}v {name:7s} {mv:9.1f} Mvertex/s  x{row['vs_scipy']:5.2f} "
                  f"scipy  x{row['speedup']:6.1f} numpy  "
                  f"{100 * row['roofline_fraction']:5.1f}% roofline", flush=True)
    return rows


def mesh_markdown(rows: list[dict]) -> str:
    if not rows:
        return ""
    lines = [
        "",
        "Mesh kernels (float32 CSR `L = A⁻¹W` on a geodesic icosphere). Roofline bytes per "
        f"row: {rows[0]['bytes_per_row']:.1f} (SpMV, x counted once per vertex: the lower "
        "bound; once per entry would be "
        f"{rows[0]['bytes_per_row_upper']:.1f}).",
        "",
        "| kernel | vertices | backend | Mvertex/s | × SciPy | × NumPy | roofline Mvertex/s "
        "| % roofline |",
        "|---|---:|---|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(
            f"| {r['kernel']} | {r['size']} | {r['backend']} | {r['mvertices']:.0f} | "
            f"{r['vs_scipy']:.2f} | {r['speedup']:.1f} | {r['roofline_mcells']:.0f} | "
            f"{100 * r['roofline_fraction']:.0f} |"
        )
    return "\n".join(lines) + "\n"


def markdown(rows: list[dict], bandwidth: float) -> str:
    lines = [
        f"Measured bandwidth (triad): {bandwidth:.1f} GB/s. float32, periodic, best of repeats.",
        "",
        "| kernel | size | backend | Mcell/s | × NumPy | roofline Mcell/s | % roofline |",
        "|---|---|---|---:|---:|---:|---:|",
    ]
    for r in rows:
        if r["kernel"] in MESH_KERNELS:
            continue
        lines.append(
            f"| {r['kernel']} | {r['size']}² | {r['backend']} | {r['mcells']:.0f} | "
            f"{r['speedup']:.1f} | {r['roofline_mcells']:.0f} | "
            f"{100 * r['roofline_fraction']:.0f} |"
        )
    return "\n".join(lines) + "\n" + mesh_markdown(
        [r for r in rows if r["kernel"] in MESH_KERNELS])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument("--sizes", type=int, nargs="+", default=[256, 1024, 2048])
    parser.add_argument("--kernels", nargs="*", default=list(BYTES_PER_CELL),
                        help="grid kernels (none: only the mesh rows)")
    parser.add_argument("--backends", nargs="+", default=["numpy", "warp", "opencl"])
    parser.add_argument("--seconds", type=float, default=0.4, help="timing per case")
    parser.add_argument("--out", default=str(Path(__file__).parent / "results"))
    parser.add_argument("--mesh-vertices", type=int, default=1_000_000,
                        help="vertices of the mesh rows' icosphere (about; 0: no mesh rows)")
    parser.add_argument("--mesh-kernels", nargs="+", default=list(MESH_KERNELS),
                        choices=MESH_KERNELS)
    parser.add_argument("--model-size", type=int, default=2048,
                        help="grid size of the model rows (0: none)")
    parser.add_argument("--models", nargs="*", default=None,
                        help="models of the model rows (default: every built-in)")
    parser.add_argument("--real-size", type=int, default=1024,
                        help="grid size of the real-state rows (perf/real_states.py; 0: none)")
    args = parser.parse_args(argv)

    bw = measure_bandwidth(min(args.seconds, 0.5))
    print(f"bandwidth: {bw}")
    backends = {name: rdgpu.get_backend(name) for name in args.backends}
    rows = []
    for kernel in args.kernels:
        for n in args.sizes:
            base = None
            for name, be in backends.items():
                seconds = time_case(be, make_case(kernel, be, n), args.seconds)
                mcells = n * n / seconds / 1e6
                base = mcells if name == "numpy" else base
                roof = bw["GBps"] * 1e9 / BYTES_PER_CELL[kernel] / 1e6
                row = dict(kernel=kernel, size=n, backend=name, device=be.device,
                           seconds_per_step=seconds, mcells=mcells,
                           speedup=mcells / base if base else float("nan"),
                           roofline_mcells=roof, roofline_fraction=mcells / roof)
                rows.append(row)
                print(f"{kernel:14s} {n:5d}² {name:7s} {mcells:9.1f} Mcell/s "
                      f"x{row['speedup']:5.1f} numpy  "
                      f"{100 * row['roofline_fraction']:5.1f}% roofline", flush=True)
    if args.mesh_vertices > 0 and args.mesh_kernels:
        rows += mesh_rows(args, backends, bw)
    models = []
    if args.model_size > 0:
        from rdgpu.models import MODELS

        args.models = list(MODELS) if args.models is None else args.models
        models = model_rows(args, {k: b for k, b in backends.items() if k != "numpy"}, bw)
    real = []
    if args.real_size > 0:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        import real_states

        real = real_states.run(args.real_size, list(backends), ["float32", "float64"],
                               early=200, late=2000)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    meta = dict(machine=platform.processor() or platform.machine(),
                python=platform.python_version(),
                rdgpu=rdgpu.__version__, numpy=np.__version__, bandwidth=bw,
                devices={n: b.device for n, b in backends.items()},
                date=time.strftime("%Y-%m-%d %H:%M"))
    (out / "bench.json").write_text(json.dumps(dict(meta=meta, rows=rows, real_states=real,
                                                    models=models), indent=1))
    table = markdown(rows, bw["GBps"]) + model_markdown(models)
    if real:
        table += "\n" + real_states.markdown(real, 200, 2000)
    (out / "bench.md").write_text(table)
    print(table)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
