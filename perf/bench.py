"""Benchmark every rdgpu kernel on every backend, at sizes chosen from the machine's caches.

    python perf/bench.py [--sizes N ...] [--kernels K ...] [--backends B ...] [--seconds 0.4]
                         [--out perf/results] [--full] [--no-gpu] [--no-pypde]
                         [--members 1024] [--member-size 64] [--model-size N] [--real-size N]
                         [--mesh-vertices N]

The users' benchmark -- rdgpu against the peers (numba, py-pde, ...) on the same
Gray-Scott step, sizes from the measured cache -- is ``rdgpu bench`` (`rdgpu.bench`); this
script is the developers' benchmark of every kernel family, the mesh kernels, models,
ensembles, growth and real states.

Writes ``bench.json``, ``bench.md`` and ``bench.png`` (Mcell/s against cells, log-log, one
line per backend, one panel per grid kernel, the last-level cache marked) to ``--out``.

Machine (``perf/machine.py``): the CPU caches are read from sysfs (else ``lscpu -B``, else
``getconf``); the last-level cache (LLC) counts every instance serving this process's CPUs.
Unless ``--sizes`` is given the square grids (multiples of 64) are: one whose working set
(bytes a kernel moves per cell x cells) is at most a quarter of the LLC for every kernel,
one at least 4x the LLC for every kernel, and their geometric mean.  Bandwidth: a triad
``a = b + s c`` on arrays together at least 4x the LLC (and 32 Mi floats), best of repeats,
NumPy on one core (two passes) and OpenCL on all (one); the roofline uses OpenCL's (NumPy's
where OpenCL cannot run).  Bytes are counted the STREAM way, as the kernels' bytes per cell
are: what the code reads and writes, no write-allocate traffic.  The same triad on arrays of
a quarter of the LLC is saved for contrast.  With an NVIDIA GPU (Warp CUDA) or any OpenCL
GPU, their rows (``warp-cuda``, ``opencl-gpu``) use that device's own bandwidth (a device
copy for Warp, the triad for OpenCL) and L2 size.

% of roofline = Mcell/s / (bandwidth / bytes per cell), printed only where the working set
exceeds the device's LLC; a cache-resident row says ``cache``: inside the cache there is no
DRAM roofline (a number there can read well above 100 %).  ``× NumPy`` is computed after all
backends of a case have run.

Rows:

* grid kernels (``--kernels``), float32, periodic, every size and backend;
* py-pde's numba backend on the same Gray-Scott problem (``pde.PDE`` with the same
  expressions, a periodic N² ``CartesianGrid`` with dx = 1, explicit Euler with dt = 1;
  compiled first, then timed; py-pde computes in float64), ``--no-pypde`` to skip;
* mesh (CSR) kernels on a geodesic icosphere of about ``--mesh-vertices`` vertices (0 to
  skip): ``spmv`` ``y = L x`` and ``mesh_gray_scott``, against SciPy; bytes per row: see
  :func:`mesh_bytes`;
* models (``--model-size``, default the middle size; 0 to skip): every built-in model's
  generated fused step (float32, near its steady state) against the hand-written Gray-Scott
  kernel in the same run;
* ensembles (``--members``, 0 to skip): Gray-Scott on ``members`` grids of
  ``member-size²`` in one batch (``Simulation(..., members=M)``) against one grid of the
  same cell count, and the sweep rate in members·steps/s (in the step, and end to end
  through ``rdgpu.sweep`` where it exists: ``--sweep-members``, ``--sweep-steps``); NumPy
  runs ``--numpy-members`` members;
* growth (``--dla-sizes``, none to skip): DLA growth steps per second and SOR sweeps per
  growth step (warm and cold start) and walker steps per second, against the same
  algorithms written the obvious way in NumPy (``perf/dla.py``, ``perf/walkers.py``);
* real states (``--real-size``, 0 to skip; ``perf/real_states.py``): presets from their
  default initial conditions, steps 0-200 against 2000-2200 of the same run.

The slowest rows (NumPy on the real states) run only with ``--full``; a default run takes a
few minutes on a 2-core machine.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import time
import warnings
from pathlib import Path

import numpy as np

try:
    import rdgpu
except ImportError:  # run from a source checkout without installing
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    import rdgpu
sys.path.insert(0, str(Path(__file__).resolve().parent))
import machine  # noqa: E402 - perf/machine.py, next to this file

from rdgpu.core.errors import BackendUnavailableError  # noqa: E402
from rdgpu.domains.boundary import parse_bc  # noqa: E402

#: steps per timed call of the ensemble rows (a whole number of blocked passes)
BURST = 16

# Bytes a kernel must move per cell in float32 (reads + writes of full arrays).
BYTES_PER_CELL = {
    "laplacian": 8,  # read u, write Lu
    "bernoulli": 8,  # read u, write u'
    "gray_scott": 16,  # read u, v; write u', v'
    "sor_sweep": 14,  # two half-sweeps: read c (4) + write half (2) + mask (1), twice
    "levelset_step": 8,  # read phi, write phi'
    "reinit_step": 12,  # read phi, phi0; write phi'
}
PYPDE = "py-pde numba"
PYPDE_BYTES = 32  # float64 u, v read; u', v' written
GPU_LABELS = ("warp-cuda", "opencl-gpu")
CPU_LABELS = ("numpy", "warp", "opencl")


# ---------------------------------------------------------------------------- backends
def _opencl_devices(gpu: bool):
    """``"P:D"`` keys of the OpenCL devices of one kind (GPU or CPU) whose compiler works,
    Oclgrind left out."""
    import pyopencl as cl

    from rdgpu.backends.opencl_backend import list_devices, probe_compiler

    kind = cl.device_type.GPU if gpu else cl.device_type.CPU
    return [key for key, p, d in list_devices()
            if d.type & kind and "oclgrind" not in p.name.lower() and probe_compiler(d) is None]


SPECS: dict[str, str] = {}  # backend label -> the spec rdgpu.get_backend was given


def resolve_backends(names: list[str], gpu: bool) -> dict:
    """``label -> Backend``: ``numpy``; ``warp`` (Warp's CPU device); ``opencl`` (the first
    OpenCL CPU device); with ``gpu``, also ``warp-cuda`` (Warp's ``cuda:0``) and
    ``opencl-gpu`` (the first OpenCL GPU) where they exist.  A backend that is unavailable
    is left out with a message."""
    from rdgpu.backends.warp_backend import cuda_device_count

    wanted = list(names)
    if gpu:
        wanted += [g for g in GPU_LABELS if g not in wanted]
    out = {}
    for label in wanted:
        try:
            if label == "numpy":
                SPECS[label] = "numpy"
            elif label == "warp":
                SPECS[label] = "warp:cpu"
            elif label == "warp-cuda":
                if cuda_device_count() > 0:
                    SPECS[label] = "warp:cuda:0"
            elif label in ("opencl", "opencl-gpu"):
                keys = _opencl_devices(gpu=label == "opencl-gpu")
                if keys:
                    SPECS[label] = f"opencl:{keys[0]}"
                elif label == "opencl":
                    print("opencl: no OpenCL CPU device can compile kernels; left out")
            else:
                raise SystemExit(f"unknown backend {label!r}; allowed: "
                                 f"{', '.join(CPU_LABELS + GPU_LABELS)}")
            if label in SPECS:
                out[label] = rdgpu.get_backend(SPECS[label])
        except (BackendUnavailableError, ImportError) as exc:
            SPECS.pop(label, None)
            print(f"{label}: unavailable ({exc}); left out")
    return out


def measure_memory(backends: dict, caches: machine.Caches, seconds: float) -> dict:
    """``{"cpu": {...}, "<gpu label>": {...}}``: each device's LLC bytes (``llc``) and
    bandwidth in GB/s (``GBps``, measured outside the cache) with the measurement's
    details."""
    memory = {"cpu": dict(llc=caches.llc, **machine.cpu_bandwidth(
        caches.llc, seconds, backends.get("opencl")))}
    for label in GPU_LABELS:
        be = backends.get(label)
        if be is None:
            continue
        l2 = machine.cuda_l2_bytes() if label == "warp-cuda" or "nvidia" in be.device.lower() \
            else 0
        if not l2 and label == "opencl-gpu":
            l2 = int(be.cl_device.global_mem_cache_size)
        l2 = l2 or 64 * machine.MiB
        memory[label] = dict(llc=l2, **machine.gpu_bandwidth(be, l2, seconds))
    return memory


def remeasure(memory: dict, backends: dict, caches: machine.Caches, seconds: float,
              tables: list[list[dict]]) -> None:
    """Measure the bandwidths again (after the rows: other work on the machine comes and
    goes), keep each device's better measurement (both bandwidths saved, ``GBps_runs``)
    and recompute every row's roofline with it."""
    again = measure_memory(backends, caches, seconds)
    for label, mem in memory.items():
        runs = [mem["GBps"], again[label]["GBps"]]
        if runs[1] > runs[0]:
            mem.update(again[label])
        mem["GBps_runs"] = runs
    for rows in tables:
        for r in rows:
            if "bytes_per_cell" in r:
                add_roofline(r, memory_of(r["backend"], memory), r["bytes_per_cell"])


def memory_of(label: str, memory: dict) -> dict:
    """The memory entry (LLC, bandwidth) of the device a backend label runs on."""
    return memory[label] if label in memory else memory["cpu"]


# ---------------------------------------------------------------------------- timing
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


def add_roofline(row: dict, mem: dict, bytes_per_cell: float) -> dict:
    """Fill in ``row``'s working set (``bytes_per_cell`` x ``row["cells"]``) against the
    device's LLC and, only outside the cache, its roofline fraction (else ``None``)."""
    ws = bytes_per_cell * row["cells"]
    roof = mem["GBps"] * 1e9 / bytes_per_cell / 1e6
    in_cache = ws <= mem["llc"]
    row.update(bytes_per_cell=bytes_per_cell, working_set_bytes=ws, llc_bytes=mem["llc"],
               working_set_over_llc=ws / mem["llc"] if mem["llc"] else None,
               in_cache=in_cache, roofline_mcells=roof,
               roofline_fraction=None if in_cache else row["mcells"] / roof)
    return row


def add_ratios(rows: list[dict], keys: tuple[str, ...], base: str = "numpy",
               field: str = "speedup") -> None:
    """``row[field]`` = Mcell/s over that of the ``base`` backend's row with the same
    ``keys`` (``None`` where there is none); run after every backend has been timed."""
    bases = {tuple(r[k] for k in keys): r["mcells"] for r in rows if r["backend"] == base}
    for r in rows:
        b = bases.get(tuple(r[k] for k in keys))
        r[field] = r["mcells"] / b if b else None


def fmt(x, spec: str = ".0f", none: str = "—") -> str:
    """``x`` formatted with ``spec``, or ``none`` for a missing value."""
    return none if x is None or (isinstance(x, float) and math.isnan(x)) else format(x, spec)


def roof_text(r: dict) -> str:
    """The % roofline cell of a row: a number outside the cache, else ``cache``."""
    return "cache" if r.get("in_cache") else fmt(None if r.get("roofline_fraction") is None
                                                  else 100 * r["roofline_fraction"])


def progress(prefix: str, r: dict) -> None:
    print(f"{prefix} {r['backend']:12s} {r['mcells']:9.1f} Mcell/s  "
          f"ws {r['working_set_bytes'] / machine.MiB:8.1f} MiB  roofline {roof_text(r)}"
          f"{'' if r.get('in_cache') else ' %'}", flush=True)


# ---------------------------------------------------------------------------- grid rows
def pypde_case(n: int):
    """A closure advancing py-pde's Gray-Scott (numba backend, explicit Euler, dt = 1) by one
    step on a periodic n² grid with dx = 1: the problem of ``make_case("gray_scott")``.
    Compiled (one step run) before it is returned."""
    import pde

    grid = pde.CartesianGrid([[0, n], [0, n]], [n, n], periodic=True)
    eq = pde.PDE({"u": "0.16*laplace(u) - u*v**2 + 0.035*(1 - u)",
                  "v": "0.08*laplace(v) + u*v**2 - (0.035 + 0.06)*v"})
    u, v = pde.ScalarField(grid, 1.0), pde.ScalarField(grid, 0.0)
    u.data[n // 3: n // 2, n // 3: n // 2], v.data[n // 3: n // 2, n // 3: n // 2] = 0.5, 0.25
    state = pde.FieldCollection([u, v])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # ExplicitSolver's deprecation on older versions
        solver_class = getattr(pde, "EulerSolver", None) or pde.ExplicitSolver
        solver = solver_class(eq, backend="numba", adaptive=False)
        stepper = solver.make_stepper(state, dt=1.0)
    t = [stepper(state, 0.0, 1.0)]

    def step():
        t[0] = stepper(state, t[0], t[0] + 1.0)

    return step


def pypde_device() -> str | None:
    """What py-pde runs on, or ``None`` when py-pde or numba cannot be imported."""
    try:
        import numba
        import pde
    except ImportError:
        return None

    return f"cpu (py-pde {pde.__version__}, numba {numba.__version__}, " \
           f"{numba.get_num_threads()} threads, float64)"


def grid_rows(args, backends: dict, memory: dict) -> list[dict]:
    """Every grid kernel at every size on every backend, py-pde on Gray-Scott; ratios to
    NumPy added once all are timed."""
    rows = []
    host = rdgpu.get_backend("numpy")
    for kernel in args.kernels:
        for n in args.sizes:
            cases = [(label, be, be.device, lambda be=be, k=kernel, n=n: make_case(k, be, n),
                      BYTES_PER_CELL[kernel]) for label, be in backends.items()]
            if kernel == "gray_scott" and args.pypde:
                device = pypde_device()
                if device is None:
                    print("py-pde rows skipped: py-pde (and numba) cannot be imported")
                else:
                    cases.append((PYPDE, host, device, lambda n=n: pypde_case(n), PYPDE_BYTES))
            for label, be, device, build, nbytes in cases:
                t0 = time.perf_counter()
                step = build()
                setup = time.perf_counter() - t0
                seconds = time_case(be, step, args.seconds)
                del step
                row = dict(kernel=kernel, size=n, cells=n * n, backend=label, device=device,
                           dtype="float64" if label == PYPDE else "float32",
                           seconds_per_step=seconds, mcells=n * n / seconds / 1e6,
                           setup_seconds=setup)
                rows.append(add_roofline(row, memory_of(label, memory), nbytes))
                progress(f"{kernel:14s} {n:5d}²", row)
    add_ratios(rows, ("kernel", "size"))
    return rows


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


# ---------------------------------------------------------------------------- model rows
def model_case(model, be, n: int):
    """A float32 stepper of ``model`` on an n² periodic grid (fields near its steady state
    with ±10 % noise, dt half the stability limit, capped by the model's own step) and a
    closure advancing it one step."""
    from rdgpu.domains.grid import Grid

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


def model_rows(args, backends: dict, memory: dict) -> list[dict]:
    """Every built-in model's generated fused step against the hand-written Gray-Scott
    kernel (``backend.gray_scott``), side by side in this run, at ``--model-size``; the
    roofline counts :func:`model_bytes` per cell."""
    from rdgpu.models import MODELS

    n = args.model_size
    rows = []
    for name, be in backends.items():
        mem = memory_of(name, memory)
        cases = [("gray-scott (hand-written)", lambda be=be: make_case("gray_scott", be, n),
                  16)]
        cases += [(m, lambda be=be, m=m: model_case(MODELS[m], be, n), model_bytes(MODELS[m]))
                  for m in args.models]
        hand = None
        for mname, build, nbytes in cases:
            mc = n * n / time_case(be, build(), args.seconds) / 1e6
            hand = hand or mc
            row = dict(kernel="model", model=mname, size=n, cells=n * n, backend=name,
                       device=be.device, mcells=mc, vs_hand=mc / hand)
            rows.append(add_roofline(row, mem, nbytes))
            progress(f"model {mname:26s} {n}²", row)
    return rows


def model_markdown(rows: list[dict]) -> str:
    if not rows:
        return ""
    lines = ["", f"Models: one fused generated step per model (float32, {rows[0]['size']}², "
             "periodic), against the hand-written Gray-Scott kernel in the same run.", "",
             "| model | backend | Mcell/s | × hand-written Gray-Scott | working set / LLC "
             "| % roofline |",
             "|---|---|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['model']} | {r['backend']} | {r['mcells']:.0f} | "
                     f"{r['vs_hand']:.2f} | {fmt(r['working_set_over_llc'], '.1f')} | "
                     f"{roof_text(r)} |")
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------- ensembles
def sweep_params(members: int) -> dict[str, np.ndarray]:
    """One (F, k) per member: the F x k grid of a sweep, ``a x b = members`` points (a the
    largest divisor of ``members`` up to its square root) over Gray-Scott's spots-to-stripes
    range."""
    a = next(d for d in range(math.isqrt(members), 0, -1) if members % d == 0)
    F, k = np.meshgrid(np.linspace(0.02, 0.06, a), np.linspace(0.055, 0.065, members // a),
                       indexing="ij")
    return {"F": F.ravel(), "k": k.ravel()}


def sweep_rate(label: str, members: int, m: int, steps: int) -> tuple[float | None, str]:
    """Members·steps per second, end to end, of ``rdgpu.sweep`` over Gray-Scott's F x k
    (``members`` points in one batch of ``m²`` grids, ``steps`` steps, serial scheduler:
    setup, stepping, copies and classification included), and a note of what ran;
    ``None`` where ``rdgpu.sweep`` is missing or fails."""
    run_sweep = getattr(rdgpu, "sweep", None)
    if not callable(run_sweep):
        return None, "no rdgpu.sweep in this rdgpu"
    a = math.isqrt(members)
    b = members // a
    params = {"F": np.linspace(0.02, 0.06, a), "k": np.linspace(0.055, 0.065, b)}
    t0 = time.perf_counter()
    try:
        run_sweep("gray-scott", params, steps=steps, size=m, dt=1.0, backend=SPECS[label],
                  scheduler="serial", batch=a * b, progress=False)
    except Exception as exc:  # noqa: BLE001 - a sweep that cannot run here: say why
        return None, f"rdgpu.sweep failed: {type(exc).__name__}: {exc}"
    return a * b * steps / (time.perf_counter() - t0), f"rdgpu.sweep {a}×{b}, {steps} steps"


def ensemble_rows(args, backends: dict, memory: dict) -> list[dict]:
    """Gray-Scott on ``--members`` grids of ``--member-size²`` in one batch against one grid
    of the same cell count, per backend (NumPy: ``--numpy-members``); empty, with a
    message, when this rdgpu's ``Simulation`` takes no ``members=``."""
    from rdgpu.simulation.driver import Simulation

    m = args.member_size
    rows = []
    for label, be in backends.items():
        members = args.numpy_members if label == "numpy" else args.members
        if members <= 0:
            continue
        side = math.isqrt(members * m * m)
        common = dict(dt=1.0, backend=be, dtype="float32", seed=0)
        t0 = time.perf_counter()
        try:
            ens = Simulation("gray-scott", {"grid": (m, m), "dx": 1.0, "bc": "periodic"},
                             sweep_params(members), members=members, **common)
        except TypeError as exc:
            if "members" not in str(exc):
                raise
            print(f"ensemble rows skipped: this rdgpu's Simulation takes no members= ({exc})")
            return []
        setup = time.perf_counter() - t0
        one = Simulation("gray-scott", {"grid": (side, side), "dx": 1.0, "bc": "periodic"},
                         **common)
        mem = memory_of(label, memory)
        # BURST steps a call: where the automatic policy blocks (OpenCL, past the LLC) the
        # passes run; a single step by step too, the rate ensembles are compared with first
        t_ens = time_case(be, lambda s=ens: s.stepper.advance(BURST), args.seconds) / BURST
        t_one = time_case(be, lambda s=one: s.stepper.advance(BURST), args.seconds) / BURST
        t_step = time_case(be, lambda s=one: s.stepper.advance(1), args.seconds)
        blocked = getattr(one.stepper, "blocked", None)
        rate, source = (sweep_rate(label, min(members, args.sweep_members), m,
                                   args.sweep_steps) if args.sweep_steps > 0
                        else (None, "not run"))
        ens_row = add_roofline(dict(
            kernel="ensemble", case=f"{members} × {m}²", members=members, size=m,
            cells=members * m * m, backend=label, device=be.device, seconds_per_step=t_ens,
            mcells=members * m * m / t_ens / 1e6, member_steps_per_s=members / t_ens,
            setup_seconds=setup, sweep_member_steps_per_s=rate, sweep_source=source), mem, 16)
        one_row = add_roofline(dict(
            kernel="ensemble-single", case=f"1 × {side}²", members=1, size=side,
            cells=side * side, backend=label, device=be.device, seconds_per_step=t_one,
            mcells=side * side / t_one / 1e6, member_steps_per_s=1 / t_one,
            step_mcells=side * side / t_step / 1e6,
            block_steps=blocked.steps if blocked is not None else 1), mem, 16)
        ens_row["block_steps"] = (ens.stepper.blocked.steps
                                  if getattr(ens.stepper, "blocked", None) else 1)
        ens_row["vs_single"] = ens_row["mcells"] / one_row["step_mcells"]
        ens_row["vs_blocked"] = ens_row["mcells"] / one_row["mcells"]
        rows += [ens_row, one_row]
        progress(f"ensemble {ens_row['case']:14s}", ens_row)
        progress(f"single   {one_row['case']:14s}", one_row)
        print(f"   ensemble / single grid step by step: {ens_row['vs_single']:.2f} (target >= "
              f"0.8); / single grid blocked (K={one_row['block_steps']}): "
              f"{ens_row['vs_blocked']:.2f}; "
              f"{members / t_ens:,.0f} members·steps/s in the step; Simulation(members="
              f"{members}) set up in {setup:.1f} s; sweep: {fmt(rate, ',.0f')} members·steps/s"
              f" ({source})", flush=True)
    return rows


def growth_rows(args, backends: dict) -> list[dict]:
    """Issue 10's growth models against the same algorithms written the obvious way in
    NumPy (``perf/dla.py``, ``perf/walkers.py``): DLA growth steps per second and SOR
    sweeps per growth step (radial, η = 1, warm and cold start) at ``--dla-sizes``, and
    walker steps per second at 256² (1024 walkers mostly walking: sticking 0.02)."""
    import dla as dla_perf
    import walkers as walkers_perf

    rows = []
    for n in args.dla_sizes:
        steps = max(2, args.dla_steps * 256 // n)
        t = time.perf_counter()
        _, sweeps = dla_perf.plain_numpy_dla((n, n), steps=steps)
        plain = steps / (time.perf_counter() - t)
        rows.append(dict(kernel="dla", size=n, backend="plain NumPy", start="warm",
                         rate=plain, sweeps=float(np.mean(sweeps[1:])), vs_plain=1.0))
        for label, be in backends.items():
            if label == "numpy" and n > 256:
                continue  # the reference: ~0.15 growth steps/s at 512²
            for warm in (True, False):
                kw = dict(eta=1.0, geometry="radial", seed=0, backend=be, warm_start=warm)
                rdgpu.dla((n, n), steps=2, **kw)  # compile
                t = time.perf_counter()
                r = rdgpu.dla((n, n), steps=steps, **kw)
                rate = steps / (time.perf_counter() - t)
                rows.append(dict(kernel="dla", size=n, backend=label,
                                 start="warm" if warm else "cold", rate=rate,
                                 sweeps=float(r.sweeps[1:].mean()), vs_plain=rate / plain))
                print(f"dla {n}² {rows[-1]['start']} {label:12s} {rate:8.2f} growth steps/s "
                      f"{rows[-1]['sweeps']:.0f} sweeps/step", flush=True)
    shape, w, stick, limit = (256, 256), 1024, 0.02, args.walker_steps
    _, ws, sec = walkers_perf.plain_numpy_steps(shape, 2000, w, stick, max_steps=limit)
    plain = ws / sec
    rows.append(dict(kernel="walkers", size=256, backend="plain NumPy", walkers=w,
                     rate=plain, vs_plain=1.0))
    for label, be in backends.items():
        rdgpu.random_walk_dla((32, 32), particles=5, walkers=8, backend=be)  # compile
        t = time.perf_counter()
        r = rdgpu.random_walk_dla(shape, particles=2000, walkers=w, sticking=stick,
                                  max_steps=limit, backend=be)
        rate = r.walker_steps / (time.perf_counter() - t)
        rows.append(dict(kernel="walkers", size=256, backend=label, walkers=w, rate=rate,
                         vs_plain=rate / plain))
        print(f"walkers 256² {label:12s} {rate:.3g} walker steps/s", flush=True)
    return rows


def growth_markdown(rows: list[dict]) -> str:
    if not rows:
        return ""
    lines = ["", "DLA by the nutrient field (radial, η = 1, tol 1e-5; warm: each solve "
             "starts from the previous field, cold: from scratch) and random walkers (256², "
             "1024 walkers, sticking 0.02 so they mostly walk), against the same algorithms "
             "written the obvious way in NumPy (`perf/dla.py`, `perf/walkers.py`).", "",
             "| kind | size | backend | start | rate | SOR sweeps / growth step | × plain "
             "NumPy |", "|---|---|---|---|---:|---:|---:|"]
    for r in rows:
        if r["kernel"] == "dla":
            lines.append(f"| DLA | {r['size']}² | {r['backend']} | {r['start']} | "
                         f"{r['rate']:.2f} growth steps/s | {r['sweeps']:.0f} | "
                         f"{r['vs_plain']:.2f} |")
        else:
            lines.append(f"| walkers | {r['size']}² | {r['backend']} | — | "
                         f"{r['rate']:.3g} walker steps/s | — | {r['vs_plain']:.2f} |")
    return "\n".join(lines) + "\n"


def ensemble_markdown(rows: list[dict]) -> str:
    if not rows:
        return ""
    lines = ["", "Ensembles: Gray-Scott (generated step, float32, periodic, dt = 1), many "
             "small grids in one batch, each member its own (F, k) as in a sweep, against "
             "one grid of the same cell count on the same backend (target: ensemble ≥ 0.8 "
             f"× single, step by step). Timed {BURST} steps a call, so where the automatic "
             "temporal blocking is on (OpenCL, fields past the LLC; K in brackets) its "
             "passes run; the single grid also step by step. Members·steps/s: in the timed "
             "step (members ÷ seconds per step), and end to end through `rdgpu.sweep` "
             "(Gray-Scott over F × k in one batch, serial scheduler: setup, stepping, "
             "copies and pattern classification included). Setup: seconds to construct "
             "`Simulation(..., members=M)` with per-member F and k.", "",
             "| backend | ensemble | Mcell/s | single grid | Mcell/s step by step | "
             "ensemble / single step by step | Mcell/s blocked | ensemble / single blocked "
             "| members·steps/s (step) | members·steps/s (sweep) | setup s "
             "| % roofline (ensemble) |",
             "|---|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for ens, one in zip(rows[::2], rows[1::2], strict=True):
        sweep = fmt(ens["sweep_member_steps_per_s"], ",.0f", "—")
        lines.append(f"| {ens['backend']} | {ens['case']} | {ens['mcells']:.0f} "
                     f"(K={ens['block_steps']}) | {one['case']} | {one['step_mcells']:.0f} | "
                     f"{ens['vs_single']:.2f} | {one['mcells']:.0f} (K={one['block_steps']}) | "
                     f"{ens['vs_blocked']:.2f} | "
                     f"{ens['member_steps_per_s']:,.0f} | {sweep} ({ens['sweep_source']}) | "
                     f"{ens['setup_seconds']:.1f} | {roof_text(ens)} |")
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------- mesh rows
MESH_KERNELS = ("spmv", "mesh_gray_scott")


def geodesic_sphere(frequency: int):
    """Unit geodesic sphere: every icosahedron face cut into ``frequency²`` triangles,
    vertices projected to the sphere; ``10 f² + 2`` vertices numbered face by face (each
    new vertex in the order the faces' barycentric grids reach it), ``20 f²`` faces."""
    import trimesh

    from rdgpu.domains.mesh.surface_mesh import SurfaceMesh

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


def mesh_rows(args, backends: dict, memory: dict) -> list[dict]:
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
        found = []
        for name in ("scipy", *backends):
            be = host if name == "scipy" else backends[name]
            seconds = time_case(be, make_mesh_case(kernel, name, be, L, n), args.seconds)
            row = dict(kernel=kernel, size=n, cells=n, backend=name,
                       device="cpu (SciPy, 1 thread)" if name == "scipy" else be.device,
                       seconds_per_step=seconds, mvertices=n / seconds / 1e6,
                       mcells=n / seconds / 1e6, bytes_per_row=per_row,
                       bytes_per_row_upper=upper if kernel == "spmv" else gs_bytes + 8 * L.nnz / n,
                       nnz=L.nnz)
            found.append(add_roofline(row, memory_of(name, memory), per_row))
            progress(f"{kernel:16s} {n:8d}v", row)
        add_ratios(found, ("kernel",), "scipy", "vs_scipy")
        add_ratios(found, ("kernel",))
        rows += found
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
        "| kernel | vertices | backend | Mvertex/s | × SciPy | × NumPy | working set / LLC "
        "| % roofline |",
        "|---|---:|---|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(
            f"| {r['kernel']} | {r['size']} | {r['backend']} | {r['mvertices']:.0f} | "
            f"{fmt(r['vs_scipy'], '.2f')} | {fmt(r['speedup'], '.1f')} | "
            f"{fmt(r['working_set_over_llc'], '.1f')} | {roof_text(r)} |"
        )
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------- output
def _first(values: list[float] | None) -> float | None:
    return values[0] if values else None


def _busy(meta: dict) -> bool:
    """Whether the 1-minute load at start or end exceeded 1.5x the CPUs (this run's own
    threads count too, so only well above that means other work)."""
    loads = [x for x in (_first(meta["load_average"]["start"]),
                         _first(meta["load_average"]["end"])) if x is not None]
    return bool(loads) and max(loads) > 1.5 * (meta["cpus"] or 1)


def header_markdown(meta: dict) -> str:
    """The machine, its caches, the measured bandwidths and the sizes, as Markdown."""
    cpu = meta["memory"]["cpu"]
    lines = [
        f"Machine: {meta['machine']}, {meta['cpus']} CPUs; {meta['caches_text']}. "
        f"Load average (1 min) at start {fmt(_first(meta['load_average']['start']), '.1f')}, "
        f"at end {fmt(_first(meta['load_average']['end']), '.1f')}"
        + (" — other work shared the CPUs: rates are lower and noisier than on an idle machine."
           if _busy(meta) else "."),
        "",
        f"Bandwidth (triad, arrays {cpu['triad_bytes'] / machine.MiB:.0f} MiB in all = "
        f"{cpu['triad_bytes'] / max(cpu['llc'], 1):.0f}× LLC, best of repeats, before and "
        f"after the rows: {' and '.join(f'{x:.1f}' for x in cpu['GBps_runs'])} GB/s; the "
        "better one): NumPy one core "
        f"{cpu['numpy_GBps']:.1f} GB/s, OpenCL all cores {fmt(cpu.get('opencl_GBps'), '.1f')} "
        f"GB/s; the roofline uses **{cpu['GBps']:.1f} GB/s** ({cpu['GBps_from']}; bytes "
        "counted the STREAM way, what the code reads and writes, as the kernels' bytes per "
        "cell are). The same triad inside the cache "
        f"(a quarter of the LLC): NumPy {cpu['cached_numpy_GBps']:.0f}, OpenCL "
        f"{fmt(cpu.get('cached_opencl_GBps'))} GB/s.",
    ]
    for label, mem in meta["memory"].items():
        if label != "cpu":
            lines.append(f"{label}: {meta['devices'][label]}, L2 {mem['llc'] / machine.MiB:.0f}"
                         f" MiB, device {mem['kind']} {mem['GBps']:.0f} GB/s.")
    lines += [
        "",
        "Sizes " + ", ".join(f"{n}²" for n in meta["sizes"])
        + (" (from the caches: cache-resident, mid, working set ≥ 4× LLC)"
           if meta["sizes_auto"] else " (given)")
        + ". float32, periodic, best of repeats. % roofline = Mcell/s ÷ (bandwidth ÷ bytes "
        "per cell), shown only where the working set (bytes per cell × cells) exceeds the "
        "device's LLC; `cache` where it fits (no DRAM roofline applies there). "
        f"{PYPDE}: py-pde's numba backend, same Gray-Scott problem, float64 "
        f"({PYPDE_BYTES} bytes per cell).",
        "",
    ]
    return "\n".join(lines) + "\n"


def grid_markdown(rows: list[dict]) -> str:
    if not rows:
        return ""
    lines = [
        "| kernel | size | backend | Mcell/s | × NumPy | working set / LLC | roofline Mcell/s "
        "| % roofline |",
        "|---|---|---|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(
            f"| {r['kernel']} | {r['size']}² | {r['backend']} | {r['mcells']:.0f} | "
            f"{fmt(r['speedup'], '.1f')} | {fmt(r['working_set_over_llc'], '.2f')} | "
            f"{r['roofline_mcells']:.0f} | {roof_text(r)} |"
        )
    return "\n".join(lines) + "\n"


def plot(rows: list[dict], ensembles: list[dict], memory: dict, path: Path) -> None:
    """Mcell/s against cells, log-log, one panel per grid kernel, one line per backend; the
    CPU LLC (and any GPU's L2) as a vertical line at the cell count whose working set fills
    it; ensembles as stars on the Gray-Scott panel."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    kernels = list(dict.fromkeys(r["kernel"] for r in rows))
    if not kernels:
        return
    labels = list(dict.fromkeys(r["backend"] for r in rows + ensembles))
    colors = {b: plt.get_cmap("tab10")(i % 10) for i, b in enumerate(labels)}
    ncol = min(3, len(kernels))
    nrow = math.ceil(len(kernels) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(5.2 * ncol, 4.2 * nrow), squeeze=False)
    for ax, kernel in zip(axes.flat, kernels, strict=False):
        mine = [r for r in rows if r["kernel"] == kernel]
        for b in dict.fromkeys(r["backend"] for r in mine):
            pts = sorted((r["cells"], r["mcells"]) for r in mine if r["backend"] == b)
            ax.plot(*zip(*pts, strict=True), marker="o", color=colors[b], label=b)
        right = max(r["cells"] for r in mine) * 1.5
        for i, (label, mem) in enumerate(memory.items()):
            if mem.get("llc"):
                name = "CPU" if label == "cpu" else label
                edge = mem["llc"] / BYTES_PER_CELL[kernel]
                style = ("--", ":", "-.")[i % 3]
                ax.axvline(edge, color="0.4", ls=style, lw=1, label=f"{name} LLC filled")
                ax.hlines(mem["GBps"] * 1e3 / BYTES_PER_CELL[kernel], edge, right,
                          color="k", ls=style, lw=1.5, label=f"{name} DRAM roofline")
        if kernel == "gray_scott":
            for r in (e for e in ensembles if e["kernel"] == "ensemble"):
                ax.plot(r["cells"], r["mcells"], marker="*", ms=13, ls="none",
                        color=colors[r["backend"]], label=f"{r['backend']} {r['case']}")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(kernel)
        ax.set_xlabel("cells")
        ax.set_ylabel("Mcell/s")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    for ax in list(axes.flat)[len(kernels):]:
        ax.set_visible(False)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _load() -> list[float] | None:
    """The 1, 5 and 15 minute load averages (None where the OS has none)."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except (AttributeError, OSError):
        return None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=None,
                        help="square grid sizes (default: from the caches, see above)")
    parser.add_argument("--kernels", nargs="*", default=list(BYTES_PER_CELL),
                        choices=list(BYTES_PER_CELL), help="grid kernels (none: no grid rows)")
    parser.add_argument("--backends", nargs="+", default=list(CPU_LABELS),
                        help=f"of {', '.join(CPU_LABELS + GPU_LABELS)}; GPUs found are added "
                        "unless --no-gpu")
    parser.add_argument("--no-gpu", dest="gpu", action="store_false",
                        help="no warp-cuda / opencl-gpu rows even where there is a GPU")
    parser.add_argument("--no-pypde", dest="pypde", action="store_false",
                        help="no py-pde rows")
    parser.add_argument("--full", action="store_true",
                        help="also the slowest rows: NumPy on the real states")
    parser.add_argument("--seconds", type=float, default=0.4, help="timing per case")
    parser.add_argument("--out", default=str(Path(__file__).parent / "results"))
    parser.add_argument("--mesh-vertices", type=int, default=1_000_000,
                        help="vertices of the mesh rows' icosphere (about; 0: no mesh rows)")
    parser.add_argument("--mesh-kernels", nargs="+", default=list(MESH_KERNELS),
                        choices=MESH_KERNELS)
    parser.add_argument("--model-size", type=int, default=None,
                        help="grid size of the model rows (default: the middle size; 0: none)")
    parser.add_argument("--models", nargs="*", default=None,
                        help="models of the model rows (default: every built-in)")
    parser.add_argument("--members", type=int, default=1024,
                        help="members of the ensemble rows (0: none)")
    parser.add_argument("--member-size", type=int, default=64, help="each member's grid side")
    parser.add_argument("--numpy-members", type=int, default=64,
                        help="members of NumPy's ensemble row (0: none)")
    parser.add_argument("--sweep-steps", type=int, default=500,
                        help="steps of the timed rdgpu.sweep (0: no sweep)")
    parser.add_argument("--sweep-members", type=int, default=256,
                        help="members of the timed rdgpu.sweep (at most those of the ensemble)")
    parser.add_argument("--dla-sizes", type=int, nargs="*", default=[256, 512],
                        help="grid sizes of the DLA rows (none: no growth rows)")
    parser.add_argument("--dla-steps", type=int, default=12,
                        help="growth steps timed at 256² (fewer on larger grids)")
    parser.add_argument("--walker-steps", type=int, default=1500,
                        help="swarm steps of the walker rows")
    parser.add_argument("--real-size", type=int, default=1024,
                        help="grid size of the real-state rows (perf/real_states.py; 0: none)")
    args = parser.parse_args(argv)

    caches = machine.cpu_caches()
    print(f"machine: {machine.cpu_name()}, {os.cpu_count()} CPUs; {caches.describe()}",
          flush=True)
    backends = resolve_backends(args.backends, args.gpu)
    print("backends: " + "; ".join(f"{k} = {b.device}" for k, b in backends.items()))
    memory = measure_memory(backends, caches, min(args.seconds, 0.5))
    for label, mem in memory.items():
        print(f"memory {label}: LLC {mem['llc'] / machine.MiB:g} MiB, "
              f"bandwidth {mem['GBps']:.1f} GB/s  {mem}", flush=True)
    sizes_auto = args.sizes is None
    if sizes_auto:
        per_cell = [BYTES_PER_CELL[k] for k in args.kernels] or [16]
        args.sizes = machine.default_sizes(max(m["llc"] for m in memory.values()),
                                           min(per_cell), max(per_cell))
    print(f"sizes: {args.sizes}{' (from the caches)' if sizes_auto else ''}", flush=True)
    t_start = time.perf_counter()
    load_start = _load()
    sections: dict[str, float] = {}

    def section(name: str, fn):
        t0 = time.perf_counter()
        result = fn()
        sections[name] = round(time.perf_counter() - t0, 1)
        return result

    rows = section("grid", lambda: grid_rows(args, backends, memory))
    if args.mesh_vertices > 0 and args.mesh_kernels:
        rows += section("mesh", lambda: mesh_rows(args, backends, memory))
    models = []
    if args.model_size is None:
        args.model_size = sorted(args.sizes)[len(args.sizes) // 2]
    if args.model_size > 0:
        from rdgpu.models import MODELS

        args.models = list(MODELS) if args.models is None else args.models
        models = section("models", lambda: model_rows(
            args, {k: b for k, b in backends.items() if k != "numpy"}, memory))
    ensembles = section("ensembles", lambda: ensemble_rows(args, backends, memory)) \
        if args.members > 0 else []
    growth = section("growth", lambda: growth_rows(args, backends)) if args.dla_sizes else []
    real = []
    if args.real_size > 0:
        import real_states

        real_backends = {k: b for k, b in backends.items() if args.full or k != "numpy"}
        real = section("real_states", lambda: real_states.run(
            args.real_size, real_backends, ["float32", "float64"], early=200, late=2000))
    remeasure(memory, backends, caches, min(args.seconds, 0.5), [rows, models, ensembles])
    print("bandwidth again: " + "; ".join(f"{k} {m['GBps_runs'][1]:.1f} GB/s (using "
                                          f"{m['GBps']:.1f})" for k, m in memory.items()))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    meta = dict(machine=machine.cpu_name(), cpus=os.cpu_count(), caches=caches.as_dict(),
                caches_text=caches.describe(), python=platform.python_version(),
                rdgpu=rdgpu.__version__, numpy=np.__version__, memory=memory,
                devices={n: b.device for n, b in backends.items()}, sizes=args.sizes,
                sizes_auto=sizes_auto, seconds=args.seconds, full=args.full,
                wall_seconds=time.perf_counter() - t_start, section_seconds=sections,
                load_average=dict(start=load_start, end=_load()),
                date=time.strftime("%Y-%m-%d %H:%M"))
    (out / "bench.json").write_text(json.dumps(dict(
        meta=meta, rows=rows, models=models, ensembles=ensembles, growth=growth,
        real_states=real),
        indent=1))
    grid = [r for r in rows if r["kernel"] not in MESH_KERNELS]
    table = header_markdown(meta) + grid_markdown(grid) + mesh_markdown(
        [r for r in rows if r["kernel"] in MESH_KERNELS]) + model_markdown(models) \
        + ensemble_markdown(ensembles) + growth_markdown(growth)
    if real:
        table += "\n" + real_states.markdown(real, 200, 2000)
    (out / "bench.md").write_text(table)
    plot(grid, ensembles, memory, out / "bench.png")
    print(table)
    print(f"wrote {out / 'bench.json'}, {out / 'bench.md'}, {out / 'bench.png'} "
          f"({time.perf_counter() - t_start:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
