"""Row groups ``models`` and ``ensembles``.

* ``models``: every built-in model's generated fused step (float32, periodic, near its
  steady state with ±10 % noise, dt half the stability limit, capped by the model's own
  step) against the hand-written Gray-Scott kernel in the same run, on every backend but
  NumPy; the roofline counts `model_bytes` per cell.
* ``ensembles``: Gray-Scott on ``members`` grids of ``member_size²`` in one batch
  (``Simulation(..., members=M)``, each member its own (F, k) as in a sweep) against one
  grid of the same cell count on the same backend, timed `BURST` steps a call (where the
  automatic temporal blocking is on, its passes run) and the single grid also step by
  step, the two timed in turn (`ROUNDS` rounds, the best each); and the sweep rate in
  members·steps/s, in the step and end to end through `rdgpu.runs.sweep.sweep` (serial
  scheduler; needs the ``dask`` extra).  NumPy runs
  ``numpy_members`` members.
"""

from __future__ import annotations

import math
import time

import numpy as np

from rdgpu.backends.base import Backend
from rdgpu.bench.context import Context
from rdgpu.bench.devices import add_roofline, fmt, memory_of, roof_text, time_case
from rdgpu.bench.rows_kernels import make_case
from rdgpu.domains.grid import Grid
from rdgpu.models import MODELS
from rdgpu.models.model import Model
from rdgpu.runs.sweep import sweep
from rdgpu.simulation.driver import Simulation

__all__ = ["BURST", "ensemble_markdown", "ensembles", "model_bytes", "model_markdown",
           "models", "sweep_params"]

#: steps per timed call of the ensemble rows (a whole number of blocked passes)
BURST = 16
#: rounds of the ensemble rows: the ensemble and its single grid timed in turn, the best
#: round each
ROUNDS = 2


def _model_step(model: Model, be: Backend, n: int):
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


def model_bytes(model: Model) -> int:
    """float32 bytes a step must move per cell: each species read and written once (the
    fused kernel); Allen-Cahn's Bernoulli pass moves its field once more."""
    extra = 8 if model.name == "allen-cahn" else 0
    return 8 * len(model.species) + extra


def models(ctx: Context, n: int, names: list[str] | None = None) -> list[dict]:
    """Every model of ``names`` (default: every built-in) at n², on every backend but
    NumPy (on NumPy alone where it is the only one)."""
    names = list(MODELS) if names is None else names
    labels = [k for k in ctx.backends if k != "numpy"] or list(ctx.backends)
    rows = []
    for label in labels:
        be = ctx.backends[label]
        cases = [("gray-scott (hand-written)", lambda be=be: make_case("gray_scott", be, n)[0],
                  16)]
        cases += [(m, lambda be=be, m=m: _model_step(MODELS[m], be, n), model_bytes(MODELS[m]))
                  for m in names]
        hand = None
        for mname, build, nbytes in cases:
            mc = n * n / time_case(be, build(), ctx.seconds) / 1e6
            hand = hand or mc
            row = dict(kernel="model", model=mname, size=n, cells=n * n, backend=label,
                       device=be.device, mcells=mc, vs_hand=mc / hand)
            rows.append(add_roofline(row, memory_of(label, ctx.memory), nbytes))
            ctx.say(f"  model {mname:26s} {n}² {label:12s} {mc:9.1f} Mcell/s")
    return rows


def model_markdown(rows: list[dict], ctx: Context) -> list[str]:
    """The models' table."""
    lines = [f"Models: one fused generated step per model (float32, {rows[0]['size']}², "
             "periodic), against the hand-written Gray-Scott kernel in the same run.", "",
             ctx.ran_on(sorted({r["backend"] for r in rows})), "",
             "| model | backend | Mcell/s | × hand-written Gray-Scott | working set / LLC "
             "| % roofline |", "|---|---|---:|---:|---:|---:|"]
    lines += [f"| {r['model']} | {r['backend']} | {r['mcells']:.0f} | {r['vs_hand']:.2f} | "
              f"{fmt(r['working_set_over_llc'], '.1f')} | {roof_text(r)} |" for r in rows]
    return lines


def sweep_params(members: int) -> dict[str, np.ndarray]:
    """One (F, k) per member: the F x k grid of a sweep, ``a x b = members`` points (a the
    largest divisor of ``members`` up to its square root) over Gray-Scott's spots-to-stripes
    range."""
    a = next(d for d in range(math.isqrt(members), 0, -1) if members % d == 0)
    F, k = np.meshgrid(np.linspace(0.02, 0.06, a), np.linspace(0.055, 0.065, members // a),
                       indexing="ij")
    return {"F": F.ravel(), "k": k.ravel()}


def _sweep_rate(be: Backend, members: int, m: int, steps: int) -> tuple[float | None, str]:
    """Members·steps per second of `sweep` end to end (setup, stepping, copies and
    classification included), and what ran; None where it cannot run here."""
    a = math.isqrt(members)
    b = members // a
    params = {"F": np.linspace(0.02, 0.06, a), "k": np.linspace(0.055, 0.065, b)}
    t0 = time.perf_counter()
    try:
        sweep("gray-scott", params, steps=steps, size=m, dt=1.0, backend=be.spec,
              scheduler="serial", batch=a * b, progress=False)
    except Exception as exc:  # noqa: BLE001 - a sweep that cannot run here: say why
        return None, f"rdgpu.sweep failed: {type(exc).__name__}: {exc}"
    return a * b * steps / (time.perf_counter() - t0), f"rdgpu.sweep {a}×{b}, {steps} steps"


def _ensemble_pair(ctx: Context, label: str, members: int, m: int, sweep_members: int,
                   sweep_steps: int) -> list[dict]:
    be = ctx.backends[label]
    side = math.isqrt(members * m * m)
    common = dict(dt=1.0, backend=be, dtype="float32", seed=0)
    t0 = time.perf_counter()
    ens = Simulation("gray-scott", {"grid": (m, m), "dx": 1.0, "bc": "periodic"},
                     sweep_params(members), members=members, **common)
    setup = time.perf_counter() - t0
    one = Simulation("gray-scott", {"grid": (side, side), "dx": 1.0, "bc": "periodic"},
                     **common)
    mem = memory_of(label, ctx.memory)
    # in turn, the best of ROUNDS rounds each: a machine whose speed drifts over minutes
    # slows the ensemble and the single grid alike
    t_ens = t_one = t_step = math.inf
    for _ in range(ROUNDS):
        t_ens = min(t_ens, time_case(be, lambda: ens.stepper.advance(BURST), ctx.seconds))
        t_one = min(t_one, time_case(be, lambda: one.stepper.advance(BURST), ctx.seconds))
        t_step = min(t_step, time_case(be, lambda: one.stepper.advance(1), ctx.seconds))
    t_ens, t_one = t_ens / BURST, t_one / BURST
    rate, source = (_sweep_rate(be, min(members, sweep_members), m, sweep_steps)
                    if sweep_steps > 0 and sweep_members > 0
                    else (None, "not run"))
    ens_row = add_roofline(dict(
        kernel="ensemble", case=f"{members} × {m}²", members=members, size=m,
        cells=members * m * m, backend=label, device=be.device, seconds_per_step=t_ens,
        mcells=members * m * m / t_ens / 1e6, member_steps_per_s=members / t_ens,
        setup_seconds=setup, sweep_member_steps_per_s=rate, sweep_source=source,
        block_steps=ens.stepper.blocked.steps if ens.stepper.blocked else 1), mem, 16)
    one_row = add_roofline(dict(
        kernel="ensemble-single", case=f"1 × {side}²", members=1, size=side,
        cells=side * side, backend=label, device=be.device, seconds_per_step=t_one,
        mcells=side * side / t_one / 1e6, member_steps_per_s=1 / t_one,
        step_mcells=side * side / t_step / 1e6,
        block_steps=one.stepper.blocked.steps if one.stepper.blocked else 1), mem, 16)
    ens_row["vs_single"] = ens_row["mcells"] / one_row["step_mcells"]
    ens_row["vs_blocked"] = ens_row["mcells"] / one_row["mcells"]
    ctx.say(f"  ensemble {ens_row['case']:14s} {label:12s} {ens_row['mcells']:9.1f} Mcell/s"
            f"; / single step by step {ens_row['vs_single']:.2f}, / single blocked "
            f"{ens_row['vs_blocked']:.2f}")
    return [ens_row, one_row]


def ensembles(ctx: Context, members: int, member_size: int, numpy_members: int,
              sweep_members: int, sweep_steps: int) -> list[dict]:
    """An ensemble and its single grid per backend (module docstring)."""
    rows = []
    for label in ctx.backends:
        count = numpy_members if label == "numpy" else members
        if count > 0:
            rows += _ensemble_pair(ctx, label, count, member_size, sweep_members,
                                   sweep_steps)
    return rows


def ensemble_markdown(rows: list[dict], ctx: Context) -> list[str]:
    """The ensembles' table."""
    lines = ["Ensembles: Gray-Scott (generated step, float32, periodic, dt = 1), many small "
             "grids in one batch, each member its own (F, k) as in a sweep, against one grid "
             "of the same cell count on the same backend (target: ensemble ≥ 0.9 × single, "
             f"step by step). Timed {BURST} steps a call, so where the automatic temporal "
             "blocking is on (K in brackets) its passes run; the single grid also step by "
             f"step; the ensemble and the single grid timed in turn, the best of {ROUNDS} "
             "rounds each. Members·steps/s: in the timed step, and end to end through "
             "`rdgpu.sweep` "
             "(serial scheduler: setup, stepping, copies and pattern classification "
             "included). Setup: seconds to construct `Simulation(..., members=M)`.", "",
             ctx.ran_on(list(dict.fromkeys(r["backend"] for r in rows))), "",
             "| backend | ensemble | Mcell/s | single grid | Mcell/s step by step | ensemble "
             "/ single step by step | Mcell/s blocked | ensemble / single blocked | "
             "members·steps/s (step) | members·steps/s (sweep) | setup s | % roofline "
             "(ensemble) |", "|---|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for ens, one in zip(rows[::2], rows[1::2], strict=True):
        sweep_rate = fmt(ens["sweep_member_steps_per_s"], ",.0f")
        lines.append(f"| {ens['backend']} | {ens['case']} | {ens['mcells']:.0f} "
                     f"(K={ens['block_steps']}) | {one['case']} | {one['step_mcells']:.0f} | "
                     f"{ens['vs_single']:.2f} | {one['mcells']:.0f} (K={one['block_steps']})"
                     f" | {ens['vs_blocked']:.2f} | {ens['member_steps_per_s']:,.0f} | "
                     f"{sweep_rate} ({ens['sweep_source']}) | {ens['setup_seconds']:.1f} | "
                     f"{roof_text(ens)} |")
    return lines
