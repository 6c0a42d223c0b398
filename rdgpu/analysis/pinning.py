"""Seed 000's pinning study: are a mesh's Allen-Cahn spots pinned, transient or stable?

One run (`run_case`) of the modified Allen-Cahn equation ``u_t = Δ_Γ u − (u³ − u +
b)/ε²`` (Dascal, Pai & Kimmel) on a surface mesh, ε a multiple of the mean edge length h,
from random data uniform in [−1, 1], sampled at times in units of ε² (the natural time of
the reaction): pattern class (`rdgpu.analysis.classify_pattern`, threshold 0),
number of phase components (`rdgpu.analysis.phase_components`, both phases),
interface width in vertices (`rdgpu.analysis.isometry.interface_width`) and the
largest change of ``u`` since the last sample.  A run's verdict:

* ``uniform``: one phase is gone (u > 0 everywhere or nowhere); the time is the first
  sample at which it is (uniform is final: the favoured phase's constant is stable);
* ``frozen``: not uniform and ``max |u(T) − u(T/2)| < frozen_tol`` (the interfaces are
  pinned by the mesh: a discrete equilibrium that the continuous equation does not have);
* ``coarsening``: still changing at T ("not by T").

`table` prints a grid of runs (level, ε/h, b) as markdown.  The whole study, its
figure and the JSON are ``examples/seed000_study.py``'s.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from rdgpu.analysis.isometry import interface_width
from rdgpu.analysis.patterns import classify_pattern, phase_components
from rdgpu.domains.mesh.surface_mesh import SurfaceMesh
from rdgpu.models.library import MODELS

__all__ = ["FROZEN_TOL", "run_case", "SAMPLES", "study_dt", "table", "verdict_cell"]

#: sample times in units of ε²; the last is the final time T
SAMPLES = (1, 2, 3, 5, 7, 10, 15, 20, 30, 50, 70, 100, 150, 200, 300, 500, 700, 1000,
           1500, 2000, 3000, 5000, 7000, 10000)
#: the largest change of u between T/2 and T of a ``frozen`` run
FROZEN_TOL = 1e-6


def study_dt(mesh: SurfaceMesh, eps: float) -> float:
    """The study's step: ε²/2 (the presets' step) or half the explicit limit if smaller."""
    return min(0.5 * eps * eps, 0.5 * MODELS["allen-cahn"].dt_limit(mesh))


def _sample(u: np.ndarray, mesh: SurfaceMesh) -> dict[str, Any]:
    """The measures of one sample of a run with both phases."""
    comps = phase_components(u, mesh, 0.0)
    return {"class": classify_pattern(u, mesh, 0.0),
            "components": int(len(comps["high"]) + len(comps["low"])),
            "width": interface_width(u, mesh)}


def run_case(mesh: SurfaceMesh, ratio: float, b: float, *, samples: tuple[float, ...] = SAMPLES,
             backend: str = "opencl", dtype: Any = np.float64, seed: int = 0,
             frozen_tol: float = FROZEN_TOL) -> dict[str, Any]:
    """One run of the study: ε = ``ratio`` × mean edge, random data in [−1, 1] (``seed``);
    sampled at ``samples`` (units of ε², increasing; the last is T).  Returns the samples
    and the verdict (see the module docstring)."""
    h = float(mesh.mean_edge_length)
    eps = ratio * h
    dt = study_dt(mesh, eps)
    st = MODELS["allen-cahn"].stepper(mesh, {"b": b, "eps": eps}, dt=dt, backend=backend,
                                      dtype=dtype)
    u = np.random.default_rng(seed).uniform(-1.0, 1.0, mesh.n_vertices)
    st.set_state({"u": u})
    t_final = float(samples[-1])
    records: list[dict[str, Any]] = []
    half: np.ndarray | None = None
    uniform_at: dict[str, float] | None = None
    t0 = time.perf_counter()
    for s in samples:
        target = int(round(s * eps * eps / dt))
        st.advance(max(target - st.steps_done, 0))
        new = st.get_state()["u"]
        rec = {"t_eps2": st.steps_done * dt / eps**2, "step": st.steps_done,
               "max_change": float(np.max(np.abs(new - u)))}
        u = new
        if half is None and s >= t_final / 2:
            half = u.copy()
        if (u > 0).all() or (u <= 0).all():
            rec.update({"class": "uniform", "components": 1, "width": None})
            records.append(rec)
            uniform_at = {"t_eps2": rec["t_eps2"], "step": rec["step"]}
            break
        rec.update(_sample(u, mesh))
        records.append(rec)
    if uniform_at is not None:
        verdict = "uniform"
    else:
        change = float(np.max(np.abs(u - half))) if half is not None else float("inf")
        verdict = "frozen" if change < frozen_tol else "coarsening"
    return {"level_vertices": mesh.n_vertices, "h": h, "ratio": ratio, "b": b, "eps": eps,
            "dt": dt, "dt_eps2": dt / eps**2, "T_eps2": t_final,
            "T_steps": int(round(t_final * eps * eps / dt)), "verdict": verdict,
            "uniform_at": uniform_at, "final_class": records[-1]["class"],
            "final_components": records[-1]["components"], "samples": records,
            "seconds": time.perf_counter() - t0}


def verdict_cell(r: dict[str, Any]) -> str:
    """A table cell: the verdict and its time."""
    if r["verdict"] == "uniform":
        return f"uniform @ {r['uniform_at']['t_eps2']:.0f}"
    return f"{r['verdict']} ({r['final_class']}, {r['final_components']})"


def table(results: dict[str, Any]) -> str:
    """Markdown: one table per level, rows ε/h, columns b, of ``results["runs"]`` (runs of
    `run_case` with their ``level``, keyed ``"level/ratio/b"``)."""
    runs = results["runs"]
    out = []
    for level in sorted({r["level"] for r in runs.values()}):
        rows = [r for r in runs.values() if r["level"] == level]
        ratios = sorted({r["ratio"] for r in rows})
        bs = sorted({r["b"] for r in rows})
        n = rows[0]["level_vertices"]
        out.append(f"\n**icosphere({level})**, {n} vertices, h = {rows[0]['h']:.4f}\n")
        out.append("| ε/h | " + " | ".join(f"b = {b:+.2f}" for b in bs) + " |")
        out.append("|---|" + "---|" * len(bs))
        for ratio in ratios:
            cells = [verdict_cell(runs[f"{level}/{ratio}/{b}"]) if f"{level}/{ratio}/{b}" in runs
                     else "—" for b in bs]
            out.append(f"| {ratio} | " + " | ".join(cells) + " |")
    return "\n".join(out)
