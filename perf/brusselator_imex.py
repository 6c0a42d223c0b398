"""Issue 22's implicit goal for the Brusselator: 256² (default parameters, initial condition
and seed) to t = 100 with ``imex`` at 10x the default explicit step against explicit Euler
at its default step, wall time and accuracy; and where an IMEX step's time goes.

    python perf/brusselator_imex.py [--backend opencl] [--size 256] [--repeats 2]
                                    [--out perf/results/brusselator_imex.md]

Accuracy: RMS and max error of ``u`` at t = 10 against RK4 at dt = 0.0025 in float64
(checked against RK4 at dt = 0.00125: the reference's own error is printed). At t = 100
every run has selected its own pattern from the noise (docs/models.md), so the end state
measures pattern selection, not a step's accuracy; t = 10 is before that.

Wall times: each run is a fresh ``Simulation`` (compiled and warmed by 10 steps first), the
runs interleaved ``repeats`` times; the table gives the best of them.  The profile times
the solve of ``v`` and its two transforms inside the steps (as they run, caches and all),
and the floor they set: an IMEX step costs at least an explicit pass and two transforms.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from rdgpu.bench.machine import machine_record  # noqa: E402
from rdgpu.domains import Grid  # noqa: E402
from rdgpu.simulation import Simulation  # noqa: E402

MODEL = "brusselator"


def run(method: str, dt: float, t_end: float, *, backend: str, size: int,
        dtype: str = "float32") -> tuple[float, dict[str, np.ndarray]]:
    """Wall seconds from t = 10 dt to ``t_end`` (warm) and the final fields."""
    sim = Simulation(MODEL, Grid((size, size)), dt=dt, backend=backend, dtype=dtype,
                     options={"method": method}, seed=1)
    n = int(round(t_end / dt))
    sim.run(10, progress=False)
    start = time.perf_counter()
    res = sim.run(n - 10, progress=False)
    return time.perf_counter() - start, res.fields


def _machine() -> str:
    m = machine_record(None)
    return f"{m['cpu']}, {m['cores']} cores"


def errors(a: np.ndarray, ref: np.ndarray) -> tuple[float, float]:
    d = np.asarray(a, dtype=np.float64) - ref
    return float(np.sqrt(np.mean(d * d))), float(np.max(np.abs(d)))


def _timed(obj: object, name: str, spent: dict[str, float], key: str) -> None:
    """Wrap ``obj.name`` (an instance attribute, this stepper's own) to add its seconds to
    ``spent[key]``."""
    f = getattr(obj, name)

    def timed(*args, **kwargs):
        t = time.perf_counter()
        try:
            return f(*args, **kwargs)
        finally:
            spent[key] = spent.get(key, 0.0) + time.perf_counter() - t
    setattr(obj, name, timed)


def profile_step(backend: str, size: int, dt: float, steps: int = 200) -> dict[str, float]:
    """Microseconds per step of euler and imex (a stepper alone, warm, best of 3), and
    where an IMEX step's time goes, measured inside the steps (the solve of ``v`` and
    its two transforms timed as they run)."""
    from rdgpu.backends.registry import get_backend
    from rdgpu.models import MODELS

    be = get_backend(backend)
    grid = Grid((size, size))
    model = MODELS[MODEL]
    out: dict[str, float] = {}
    spent: dict[str, float] = {}
    for method, h in (("euler", dt / 10), ("imex", dt)):
        st = model.stepper(grid, None, dt=h, backend=be, dtype=np.float32, method=method)
        rng = np.random.default_rng(0)
        st.set_state({"u": 5 + 0.1 * rng.random((size, size)),
                      "v": 1.8 + 0.1 * rng.random((size, size))})
        st.advance(10)
        st.get_state()
        if method == "imex":
            direct = next(iter(s for ss in st._solvers.values() for s in ss)).transform  # noqa: SLF001
            _timed(direct, "step", spent, "solve")
            for name in ("forward", "inverse"):
                _timed(direct.solver, name, spent, "transforms")
        best, parts = math.inf, {}
        for _ in range(3):
            spent.clear()
            t = time.perf_counter()
            st.advance(steps)
            st.get_state()
            sec = time.perf_counter() - t
            if sec < best:
                best, parts = sec, dict(spent)
        out[f"{method} step"] = best / steps * 1e6
    solve, ffts = parts["solve"] / steps * 1e6, parts["transforms"] / steps * 1e6
    out["imex: the solve of v (download, transforms, upload)"] = solve
    out["imex: its two transforms (r2c, c2r)"] = ffts
    out["imex: the rest of the solve (the download, which waits for the explicit pass; "
        "symmetry test, products, upload)"] = solve - ffts
    out["imex: the rest of the step (launching the explicit pass, Python)"] = \
        out["imex step"] - solve
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--backend", default="opencl")
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--out", default="perf/results/brusselator_imex.md")
    a = ap.parse_args(argv)
    explicit_dt = Simulation(MODEL, Grid((a.size, a.size))).dt
    runs = {"euler": explicit_dt, "imex": 10 * explicit_dt, "bdf2": 10 * explicit_dt,
            "imex-cn": 10 * explicit_dt}
    best: dict[str, float] = {}
    for _ in range(a.repeats):
        for name, dt in runs.items():
            method = name.split()[0]
            try:
                t, _ = run(method, dt, 100.0, backend=a.backend, size=a.size)
            except Exception as exc:  # a diverging step is a result, not a crash
                print(f"{name}: {type(exc).__name__}: {str(exc).splitlines()[0]}",
                      file=sys.stderr)
                t = float("nan")
            best[name] = min(best.get(name, float("inf")), t)
            print(f"{name} dt={dt:g}: {t:.2f} s", file=sys.stderr, flush=True)
    ref = run("rk4", 0.0025, 10.0, backend="numpy", size=a.size, dtype="float64")[1]["u"]
    ref2 = run("rk4", 0.00125, 10.0, backend="numpy", size=a.size, dtype="float64")[1]["u"]
    acc = {}
    for name, dt in runs.items():
        try:
            acc[name] = errors(run(name.split()[0], dt, 10.0, backend=a.backend,
                                   size=a.size)[1]["u"], ref)
        except Exception:  # diverged: reported in the table
            acc[name] = (float("nan"), float("nan"))
    prof = profile_step(a.backend, a.size, 10 * explicit_dt)
    lines = [f"# Brusselator {a.size}² to t = 100: imex against explicit Euler", "",
             f"Machine: {_machine()}; backend {a.backend}, float32; "
             f"`python perf/brusselator_imex.py --backend {a.backend}`; best of "
             f"{a.repeats} interleaved runs.", "",
             "| method | dt | × explicit step | wall to t = 100 (s) | speed-up over euler "
             "| RMS error of u at t = 10 | max error |", "|---|---:|---:|---:|---:|---:|---:|"]
    for name, dt in runs.items():
        rms, mx = acc[name]
        lines.append(f"| {name} | {dt:g} | {dt / explicit_dt:.0f} | {best[name]:.2f} | "
                     f"{best['euler'] / best[name]:.2f} | {rms:.3g} | {mx:.3g} |")
    r_rms, r_max = errors(ref2, ref)
    lines += ["", f"Reference: RK4, dt = 0.0025, float64, NumPy; its difference from dt = "
              f"0.00125: RMS {r_rms:.2g}, max {r_max:.2g}.", "",
              "One IMEX step (µs; a stepper alone, warm):", "", "| part | µs |", "|---|---:|"]
    lines += [f"| {k} | {v:.0f} |" for k, v in prof.items()]
    euler, ffts = prof["euler step"], prof["imex: its two transforms (r2c, c2r)"]
    lines += ["", f"The floor on this CPU: an IMEX step at 10× the explicit step is at least "
              f"an explicit pass ({euler:.0f} µs) and the two host transforms of the solve "
              f"({ffts:.0f} µs), so it can be at most {10 * euler / (euler + ffts):.1f}× "
              f"faster than Euler ({10 * euler / prof['imex step']:.1f}× measured here)."]
    text = "\n".join(lines) + "\n"
    print(text)
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
