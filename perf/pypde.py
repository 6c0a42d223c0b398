"""Gray-Scott through py-pde's API: ``backend="numba"`` against ``backend="rdgpu:..."``.

    python perf/pypde.py [--size 2048] [--backends numba rdgpu:opencl rdgpu:warp]
                         [--solver euler|euler-adaptive|rk4|rkf45|adams-bashforth|
                                   implicit|crank-nicolson]
                         [--numba-steps 10] [--rdgpu-steps 400] [--out perf/results]

One ``pde.PDE`` (seed 001's Gray-Scott, periodic ``CartesianGrid`` of ``size²`` unit
cells, float64) solved by each backend in the same process with one py-pde solver:
``euler`` (fixed ``dt = 1``, the default), ``euler-adaptive`` (py-pde's default when
``solve`` gets no ``dt``: step doubling, tolerance 1e-4), ``rk4`` (``RungeKuttaSolver`` at
``dt = 1``), ``rkf45`` (adaptive ``RungeKuttaSolver``), ``adams-bashforth``, ``implicit``
or ``crank-nicolson`` (``dt = 1``; the last two py-pde's fixed-point iterations).
Per backend one ``Controller.run`` over three intervals of ``m`` steps of ``dt = 1`` (an
adaptive solver takes the steps it needs) with a ``CallbackTracker`` at each interval
that notes the wall clock and the solver's step count: the first interval holds the
compilation (py-pde's numba jit, rdgpu's kernel build), the rate is the accepted steps ×
``size²`` of the last two intervals over their time (Mcell/s; for rdgpu each interval
includes one upload and one download, as trackers make it).  A ``DataTracker`` keeps
the state at t = 10; every backend's is compared with the first backend's (max |Δ|, to
round-off).  Writes ``pypde.md`` (``euler``) or ``pypde_<solver>.md`` in ``--out``.
The default size is 2048² (what the issue names, 64 MiB per float64 field: far beyond
a 32 MiB LLC); ``--size 0`` takes the largest size ``rdgpu bench --rows kernels`` picks
(`rdgpu.bench.context.kernel_sizes`) for the measured last-level cache instead.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

try:
    import rdgpu
except ImportError:  # run from a source checkout without installing
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    import rdgpu
import pde  # noqa: E402

import rdgpu.pypde  # noqa: E402,F401 - registers backend "rdgpu"
from rdgpu.bench.context import kernel_sizes  # noqa: E402
from rdgpu.bench.machine import MiB, effective_llc, triad_sweep  # noqa: E402
from rdgpu.core.hardware import cpu_caches  # noqa: E402


def measured_llc() -> int:
    """The effective last-level cache (`rdgpu.bench.machine`: a triad sweep), else the
    OS-reported one, else 32 MiB."""
    return effective_llc(triad_sweep(2048 * MiB))["llc"] or cpu_caches().llc or 32 * MiB

EQUATIONS = {"u": "0.16*laplace(u) - u*v**2 + 0.035*(1 - u)",
             "v": "0.08*laplace(v) + u*v**2 - (0.035 + 0.06)*v"}
DT = 1.0
FIRST_STEPS = 10


def initial_state(n: int) -> pde.FieldCollection:
    """u = 1, v = 0, with a noisy square of u = 0.5, v = 0.25 in the middle."""
    grid = pde.CartesianGrid([[0.0, n], [0.0, n]], [n, n], periodic=True)
    rng = np.random.default_rng(1)
    u, v = np.ones((n, n)), np.zeros((n, n))
    a, b = n // 2 - n // 10, n // 2 + n // 10
    u[a:b, a:b], v[a:b, a:b] = 0.5, 0.25
    u += 0.05 * rng.random((n, n))
    v += 0.05 * rng.random((n, n))
    return pde.FieldCollection([pde.ScalarField(grid, u, label="u"),
                                pde.ScalarField(grid, v, label="v")])


#: ``--solver`` → (py-pde solver class name, adaptive)
SOLVERS = {"euler": ("EulerSolver", False), "euler-adaptive": ("EulerSolver", True),
           "rk4": ("RungeKuttaSolver", False), "rkf45": ("RungeKuttaSolver", True),
           "adams-bashforth": ("AdamsBashforthSolver", False),
           "implicit": ("ImplicitSolver", False), "crank-nicolson": ("CrankNicolsonSolver", False)}


def make_solver(eq: pde.PDE, backend: str, solver: str):
    name, adaptive = SOLVERS[solver]
    cls = getattr(pde, name)
    if name in ("AdamsBashforthSolver", "ImplicitSolver", "CrankNicolsonSolver"):
        return cls(eq, backend=backend)
    return cls(eq, backend=backend, adaptive=adaptive)


def measure(eq: pde.PDE, state, backend: str, interval: int, solver: str,
            dt: float = DT) -> dict:
    """One ``Controller.run`` over ``3 · interval`` time units with a ``CallbackTracker``
    every ``interval`` (module doc)."""
    cells = state.grid.num_cells
    stepper = make_solver(eq, backend, solver)
    stamps: list[tuple[float, int]] = []
    clock = pde.CallbackTracker(
        lambda s, t: stamps.append((time.perf_counter(), stepper.info.get("steps", 0))),
        interrupts=interval * dt)
    early = pde.DataTracker(lambda s: s.data.copy(), interrupts=[FIRST_STEPS * dt])
    t0 = time.perf_counter()
    pde.Controller(stepper, t_range=3 * interval * dt, tracker=[clock, early]).run(
        state, dt=dt)
    wall = time.perf_counter() - t0
    steps = stamps[3][1] - stamps[1][1]
    return {"backend": backend, "wall_s": wall, "first_s": stamps[1][0] - t0,
            "steps": steps, "mcells": steps * cells / (stamps[3][0] - stamps[1][0]) / 1e6,
            "result": early.data[-1]}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=2048)
    parser.add_argument("--backends", nargs="+",
                        default=["numba", "rdgpu:opencl", "rdgpu:warp"])
    parser.add_argument("--solver", choices=sorted(SOLVERS), default="euler")
    parser.add_argument("--dt", type=float, default=DT,
                        help="the (initial) time step; py-pde's fixed-point iterations "
                             "converge for dt < 1/(8·0.16) only")
    parser.add_argument("--numba-steps", type=int, default=10,
                        help="steps per tracker interval with numba (>= 10)")
    parser.add_argument("--rdgpu-steps", type=int, default=400,
                        help="steps per tracker interval with rdgpu (>= 10)")
    parser.add_argument("--out", type=Path, default=Path(__file__).parent / "results")
    args = parser.parse_args(argv)
    n = args.size
    if n <= 0:
        n = kernel_sizes(measured_llc(), 16, 32)[-1]
    eq = pde.PDE(EQUATIONS, bc="periodic")
    state = initial_state(n)
    rows = []
    for name in args.backends:
        interval = args.numba_steps if name == "numba" else args.rdgpu_steps
        row = measure(eq, state, name, max(interval, FIRST_STEPS), args.solver, args.dt)
        rows.append(row)
        print(f"{name:14s} {row['mcells']:9.1f} Mcell/s  first call {row['first_s']:.2f} s",
              flush=True)
    ref = rows[0]
    lines = [
        "# Gray-Scott through py-pde's API: numba against rdgpu (perf/pypde.py)", "",
        f"`python perf/pypde.py --size {n} --backends {' '.join(args.backends)} "
        f"--solver {args.solver} --dt {args.dt:g} --numba-steps {args.numba_steps} --rdgpu-steps "
        f"{args.rdgpu_steps}`; py-pde {pde.__version__}, rdgpu "
        f"{getattr(rdgpu, '__version__', '?')}, float64, {n}² periodic, solver "
        f"{args.solver} (dt = {args.dt}{', initial' if SOLVERS[args.solver][1] else ''}), "
        "trackers every m time units. The machine: "
        f"{cpu_caches().llc // MiB} MiB LLC (as reported), "
        "2 cores shared with other jobs (rates are indicative).", "",
        "| backend | Mcell/s | × numba | steps timed | to the first interval (s) | "
        f"max abs diff at t = {FIRST_STEPS * args.dt:g} vs {ref['backend']} |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    base = next((r["mcells"] for r in rows if r["backend"] == "numba"), None)
    for r in rows:
        diff = float(np.abs(r["result"] - ref["result"]).max())
        speed = f"{r['mcells'] / base:.0f}" if base else "—"
        lines.append(f"| {r['backend']} | {r['mcells']:.1f} | {speed} | "
                     f"{r['steps']} | {r['first_s']:.2f} | {diff:.1e} |")
    args.out.mkdir(parents=True, exist_ok=True)
    name = "pypde.md" if args.solver == "euler" else f"pypde_{args.solver}.md"
    (args.out / name).write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
