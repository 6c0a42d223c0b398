"""Step rates on *real* simulation states, not random fields.

    python perf/real_states.py [--size 1024] [--backends numpy warp opencl]
                               [--dtypes float32 float64] [--early 200] [--late 2000]

A random field never produces subnormal floats; a real run does: a Gray-Scott background
decays geometrically and, without flushing, is mostly subnormal after ~1000 steps, where
x86 arithmetic can be ~100x slower.  Each row here runs a preset from its default initial
condition and times the steps ``[0, early)`` and ``[late, late + early)`` of the same run
(the steps in between run untimed; each window is the best of 5 runs from the same saved
state, so a busy moment of the machine does not count), side by side on every backend,
and reports the rate of each window, their ratio (the target is >= 0.9) and the fraction
of the state that is subnormal at the end (0 when flushing works).

Cases: Gray-Scott stripes and spots (Camphuijsen & Kasim's two parameter sets, presets
gs-seed001-stripes and gs-seed001-spots) on ``size²`` grids, and modified
Allen-Cahn with localized spots on an icosphere of 40 962 vertices (ac-sphere-local-spots:
the field outside the patch starts at 0 and is reached by tiny values).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

try:
    import rdgpu  # noqa: F401
except ImportError:  # a source checkout without installing
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from rdgpu.simulation.driver import Simulation


def cases(size: int) -> list[tuple[str, str, dict | None]]:
    """``(label, preset, domain override)``."""
    return [
        (f"gray-scott stripes {size}²", "gs-seed001-stripes",
         {"grid": (size, size), "dx": 1.0, "bc": "periodic"}),
        (f"gray-scott spots {size}²", "gs-seed001-spots",
         {"grid": (size, size), "dx": 1.0, "bc": "periodic"}),
        # the preset's icosphere(5) has 10 242 vertices: too few to time reliably
        ("allen-cahn local spots, icosphere(6)", "ac-sphere-local-spots",
         {"mesh": "sphere", "subdivisions": 6}),
    ]


def subnormal_fraction(state: dict[str, np.ndarray]) -> float:
    total = bad = 0
    for a in state.values():
        tiny = np.finfo(a.dtype).tiny
        bad += int(np.count_nonzero((a != 0) & (np.abs(a) < tiny)))
        total += a.size
    return bad / max(total, 1)


def timed(sim: Simulation, start: dict[str, np.ndarray], steps: int, repeats: int) -> float:
    """Best time of ``repeats`` runs of ``steps`` steps, each from the state ``start``."""
    best = float("inf")
    for _ in range(repeats):
        sim.stepper.set_state(start)
        sim.stepper.backend.synchronize()
        t0 = time.perf_counter()
        sim.stepper.advance(steps)
        sim.stepper.backend.synchronize()
        best = min(best, time.perf_counter() - t0)
    return best


def measure(preset: str, domain, backend: str, dtype: str, early: int, late: int,
            repeats: int = 5) -> dict:
    sim = Simulation.from_preset(preset, domain=domain, backend=backend, dtype=dtype)
    cells = int(np.prod(sim.shape))
    start = sim.stepper.get_state()
    sim.stepper.advance(2)  # compile and warm up outside the timed windows
    t_early = timed(sim, start, early, repeats)
    sim.stepper.set_state(start)
    sim.stepper.advance(late)
    state = sim.stepper.get_state()
    t_late = timed(sim, state, early, repeats)
    return {
        "cells": cells,
        "early_Mcells": cells * early / t_early / 1e6,
        "late_Mcells": cells * early / t_late / 1e6,
        "late_over_early": t_early / t_late,
        "subnormal_fraction": subnormal_fraction(state),
        "finite": bool(all(np.isfinite(a).all() for a in state.values())),
    }


def markdown(rows: list[dict], early: int, late: int) -> str:
    lines = [
        f"Rates on real states: steps [0, {early}) and [{late}, {late + early}) of one run "
        "from the preset's default initial condition (target: late/early >= 0.9).",
        "",
        "| case | dtype | backend | Mcell/s first | Mcell/s late | late/early | subnormal at end |",
        "|---|---|---|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(
            f"| {r['case']} | {r['dtype']} | {r['backend']} | {r['early_Mcells']:.0f} | "
            f"{r['late_Mcells']:.0f} | {r['late_over_early']:.2f} | "
            f"{100 * r['subnormal_fraction']:.1f}% |"
        )
    return "\n".join(lines) + "\n"


def run(size: int, backends: list[str] | dict, dtypes: list[str], early: int, late: int,
        verbose: bool = True) -> list[dict]:
    """Every case, dtype and backend; ``backends`` names (``"warp"``) or ``{label: backend}``
    (a name or a ``Backend``), the label going into the rows."""
    named = backends if isinstance(backends, dict) else {b: b for b in backends}
    rows = []
    for label, preset, domain in cases(size):
        for dtype in dtypes:
            for backend, spec in named.items():
                r = {"case": label, "preset": preset, "dtype": dtype, "backend": backend,
                     **measure(preset, domain, spec, dtype, early, late)}
                rows.append(r)
                if verbose:
                    print(f"{label:38s} {dtype:8s} {backend:7s} {r['early_Mcells']:8.0f} "
                          f"{r['late_Mcells']:8.0f} Mcell/s  late/early {r['late_over_early']:.2f}"
                          f"  subnormal {100 * r['subnormal_fraction']:.1f}%", flush=True)
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--backends", nargs="+", default=["numpy", "warp", "opencl"])
    parser.add_argument("--dtypes", nargs="+", default=["float32", "float64"])
    parser.add_argument("--early", type=int, default=200)
    parser.add_argument("--late", type=int, default=2000)
    parser.add_argument("--out", default=str(Path(__file__).parent / "results"))
    args = parser.parse_args(argv)
    if args.late <= args.early:
        parser.error("--late must be larger than --early")
    rows = run(args.size, args.backends, args.dtypes, args.early, args.late)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "real_states.json").write_text(json.dumps(
        {"size": args.size, "early": args.early, "late": args.late, "rows": rows}, indent=1))
    md = markdown(rows, args.early, args.late)
    (out / "real_states.md").write_text(md)
    print(md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
