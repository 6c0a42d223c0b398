"""Row groups ``real-states`` and ``blocking``.

* ``real-states``: step rates on *real* simulation states, not random fields.  A random
  field never produces subnormal floats; a real run does: a Gray-Scott background decays
  geometrically and, without flushing, is mostly subnormal after ~1000 steps, where x86
  arithmetic can be ~100x slower.  Each row runs a preset from its default initial
  condition and times the steps ``[0, early)`` and ``[late, late + early)`` of the same run
  (each window the best of `REPEATS` runs from the same saved state), and reports both
  rates, their ratio (target >= 0.9) and the fraction of the state that is subnormal at the
  end (0 when flushing works).  Cases: Gray-Scott stripes and spots (presets
  gs-seed001-stripes, gs-seed001-spots) on ``size²`` grids, and modified Allen-Cahn with
  localized spots on an icosphere (ac-sphere-local-spots).  NumPy runs only with ``--full``.
* ``blocking``: temporal blocking of the fused Gray-Scott step against the single-step
  roofline (the triad bandwidth ÷ the bytes a step moves per cell), on every backend that
  runs blocked passes, on a grid whose state is ``factor`` x the effective LLC, from the
  problem's real state (`rdgpu.bench.problem.real_state`): the single step, the blocked
  passes for every K in ``steps`` and band height B in ``rows``, and the compute ceiling
  (the single step on a grid whose state fills half the LLC); a backend without blocked
  passes (Warp) gets its single step and compute ceiling for comparison, NumPy nothing.
"""

from __future__ import annotations

import math
import time

import numpy as np

from rdgpu.backends.base import Backend
from rdgpu.bench.context import Context
from rdgpu.bench.devices import time_case
from rdgpu.bench.problem import TILE, bytes_per_cell, real_state, stepper
from rdgpu.integrators.blocking import BlockedEuler
from rdgpu.simulation.driver import Simulation

__all__ = ["REPEATS", "blocking", "blocking_markdown", "blocking_shapes", "real_state_cases",
           "real_states", "real_states_markdown", "subnormal_fraction"]

REPEATS = 5


def real_state_cases(size: int, subdivisions: int) -> list[tuple[str, str, dict]]:
    """``(label, preset, domain override)`` of the real-state rows."""
    return [
        (f"gray-scott stripes {size}²", "gs-seed001-stripes",
         {"grid": (size, size), "dx": 1.0, "bc": "periodic"}),
        (f"gray-scott spots {size}²", "gs-seed001-spots",
         {"grid": (size, size), "dx": 1.0, "bc": "periodic"}),
        (f"allen-cahn local spots, icosphere({subdivisions})", "ac-sphere-local-spots",
         {"mesh": "sphere", "subdivisions": subdivisions}),
    ]


def subnormal_fraction(state: dict[str, np.ndarray]) -> float:
    """The fraction of the values of ``state`` that are subnormal."""
    total = bad = 0
    for a in state.values():
        tiny = np.finfo(a.dtype).tiny
        bad += int(np.count_nonzero((a != 0) & (np.abs(a) < tiny)))
        total += a.size
    return bad / max(total, 1)


def _timed(sim: Simulation, start: dict[str, np.ndarray], steps: int, repeats: int) -> float:
    """Best seconds of ``repeats`` runs of ``steps`` steps, each from the state ``start``."""
    st = sim.stepper
    best = math.inf
    for _ in range(repeats):
        st.set_state(start)
        st.backend.synchronize()
        t0 = time.perf_counter()
        st.advance(steps)
        st.backend.synchronize()
        best = min(best, time.perf_counter() - t0)
    return best


def _measure(preset: str, domain: dict, be: Backend, dtype: str, early: int,
             late: int) -> dict:
    sim = Simulation.from_preset(preset, domain=domain, backend=be, dtype=dtype)
    cells = int(np.prod(sim.shape))
    start = sim.stepper.get_state()
    sim.stepper.advance(2)  # compile and warm up outside the timed windows
    t_early = _timed(sim, start, early, REPEATS)
    sim.stepper.set_state(start)
    sim.stepper.advance(late)
    state = sim.stepper.get_state()
    t_late = _timed(sim, state, early, REPEATS)
    return {"cells": cells, "early_Mcells": cells * early / t_early / 1e6,
            "late_Mcells": cells * early / t_late / 1e6, "late_over_early": t_early / t_late,
            "subnormal_fraction": subnormal_fraction(state),
            "finite": bool(all(np.isfinite(a).all() for a in state.values()))}


def real_states(ctx: Context, size: int, subdivisions: int, early: int, late: int,
                dtypes: tuple[str, ...] = ("float32", "float64")) -> list[dict]:
    """Every case, dtype and backend (NumPy only with ``ctx.full``)."""
    rows = []
    for label, preset, domain in real_state_cases(size, subdivisions):
        for dtype in dtypes:
            for name, be in ctx.backends.items():
                if name == "numpy" and not ctx.full:
                    continue
                r = {"case": label, "preset": preset, "dtype": dtype, "backend": name,
                     "early": early, "late": late,
                     **_measure(preset, domain, be, dtype, early, late)}
                rows.append(r)
                ctx.say(f"  {label:38s} {dtype:8s} {name:7s} {r['early_Mcells']:8.0f} "
                        f"{r['late_Mcells']:8.0f} Mcell/s  late/early "
                        f"{r['late_over_early']:.2f}  subnormal "
                        f"{100 * r['subnormal_fraction']:.1f}%")
    return rows


def real_states_markdown(rows: list[dict], ctx: Context) -> list[str]:
    """The real states' table."""
    early, late = rows[0]["early"], rows[0]["late"]
    lines = [f"Rates on real states: steps [0, {early}) and [{late}, {late + early}) of one "
             "run from the preset's default initial condition (target: late/early ≥ 0.9).",
             "", ctx.ran_on(list(dict.fromkeys(r["backend"] for r in rows))), "",
             "| case | dtype | backend | Mcell/s first | Mcell/s late | late/early | "
             "subnormal at end |", "|---|---|---|---:|---:|---:|---:|"]
    lines += [f"| {r['case']} | {r['dtype']} | {r['backend']} | {r['early_Mcells']:.0f} | "
              f"{r['late_Mcells']:.0f} | {r['late_over_early']:.2f} | "
              f"{100 * r['subnormal_fraction']:.1f}% |" for r in rows]
    return lines


def _rate(st, cells: int, steps: int, seconds: float) -> float:
    return cells * steps / time_case(st.backend, lambda: st.advance(steps), seconds) / 1e6


def _blocking_rows(ctx: Context, label: str, be: Backend, shape: tuple[int, int],
                   small: tuple[int, int], ks: list[int], bands: list[int]) -> list[dict]:
    dtype, roof = "float32", ctx.memory["cpu"]["GBps"] * 1e9 / bytes_per_cell("float32") / 1e6
    steps = int(np.lcm.reduce([*ks, 2]))
    st = stepper(shape, dtype, be, 1)
    u, v = real_state(shape, dtype)
    st.set_state({"u": u, "v": v})
    base = dict(kernel="blocking", backend=label, device=be.device, roofline_mcells=roof,
                subnormal_fraction=subnormal_fraction({"u": u, "v": v}))
    rows = [dict(base, config="single step", shape=shape,
                 mcells=_rate(st, math.prod(shape), steps, ctx.seconds))]
    for k in ks:
        for b in bands:
            st.blocked = BlockedEuler(st, k, b)
            rows.append(dict(base, config=f"blocked K={k} B={b}", shape=shape,
                             mcells=_rate(st, math.prod(shape), steps, ctx.seconds)))
    st.blocked = None
    ceiling = stepper(small, dtype, be, 1)
    cu, cv = real_state(small, dtype)
    ceiling.set_state({"u": cu, "v": cv})
    rows.append(dict(base, config="compute ceiling: single step in the LLC", shape=small,
                     mcells=_rate(ceiling, math.prod(small), steps, ctx.seconds)))
    for r in rows:
        r["x_roofline"] = r["mcells"] / roof
        ctx.say(f"  blocking {label:8s} {r['config']:40s} {r['mcells']:9.0f} Mcell·steps/s "
                f"{r['x_roofline']:.2f} × roofline")
    return rows


def blocking_shapes(llc: int, factor: float,
                    nx: int) -> tuple[tuple[int, int], tuple[int, int]]:
    """The grid whose float32 Gray-Scott state is ``factor`` x ``llc`` (``nx`` columns,
    rows a multiple of the real state's tile), and the compute ceiling's (state in half
    ``llc``, at most as many rows)."""
    nbytes, edge = bytes_per_cell("float32"), TILE[2]
    ny = edge * max(1, math.ceil(factor * llc / nbytes / nx / edge))
    small = edge * max(1, int(llc / 2 / nbytes / nx // edge))
    return (ny, nx), (min(small, ny), nx)


def blocking(ctx: Context, shape: tuple[int, int], small: tuple[int, int], ks: list[int],
             bands: list[int]) -> list[dict]:
    """The blocking rows of every backend that runs blocked passes (module docstring) on
    ``shape``, the compute ceiling on ``small``; a backend that does not block gets its
    single step and compute ceiling (NumPy nothing) and a ``"not run"`` row saying why."""
    rows = []
    for label, be in ctx.backends.items():
        why = be.blocked_pass_support()
        if why is not None and label != "numpy":
            rows += _blocking_rows(ctx, label, be, shape, small, [], [])
        rows += ([] if why is None else
                 [dict(kernel="blocking", backend=label, config="not run", note=why)])
        if why is None:
            rows += _blocking_rows(ctx, label, be, shape, small, ks, bands)
    return rows


def blocking_markdown(rows: list[dict], ctx: Context) -> list[str]:
    """The blocking table: Mcell·steps/s and × the single-step roofline."""
    run = [r for r in rows if r["config"] != "not run"]
    lines = ["Temporal blocking: Gray-Scott float32, periodic, from the problem's real state, "
             "against the single-step roofline (triad ÷ 16 bytes/cell).", "",
             ctx.ran_on(list(dict.fromkeys(r["backend"] for r in rows)))]
    if run:
        lines += ["", "| backend | kernel | grid | Mcell·steps/s | × roofline |",
                  "|---|---|---|---:|---:|",
                  f"| — | roofline (triad ÷ 16 B/cell) | — | {run[0]['roofline_mcells']:.0f} "
                  "| 1.00 |"]
        lines += [f"| {r['backend']} | {r['config']} | {r['shape'][0]} × {r['shape'][1]} | "
                  f"{r['mcells']:.0f} | {r['x_roofline']:.2f} |" for r in run]
    lines += [""] + [f"* {r['backend']}: no blocked passes: {r['note']}" for r in rows
                     if r not in run]
    return lines
