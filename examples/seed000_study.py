"""Seed 000's spots on icospheres: pinned, transient or stable?  A convergence study.

    python examples/seed000_study.py               # everything: ~6-9 min on a shared 2-core CPU
    python examples/seed000_study.py --figure-only # rebuild figure and table from the JSON
    python examples/seed000_study.py --levels 4    # a subset (merged into the JSON)
    python examples/seed000_study.py --parts isometry spheres   # only those parts

The modified Allen-Cahn equation ``u_t = Δ_Γ u − (u³ − u + b)/ε²`` (Dascal, Pai & Kimmel)
on the unit icosphere of 4, 5 and 6 subdivisions (h = mean edge length 0.0755, 0.0378,
0.0189), ε/h ∈ :data:`RATIOS`, b ∈ :data:`BS` (issue 11's seven values and ±0.05),
random initial data uniform in [−1, 1] (seed 0), OpenCL, float64, explicit Strang
splitting with ``dt = min(ε²/2, dt_limit/2)``.

Time is in units of ε² (the natural time of the reaction; the interface is ~4 ε wide and
a front driven by b moves ~2|b| ε per ε²).  Every run (:func:`rdgpu.analysis.pinning.run_case`)
lasts to ``T = 10 000 ε²`` (or until the field is uniform) and is sampled at
:data:`rdgpu.analysis.pinning.SAMPLES` (× ε²): pattern class
(:func:`rdgpu.analysis.classify_pattern`, threshold 0), number of phase components
(:func:`rdgpu.analysis.phase_components`, both phases), interface width in vertices
(:func:`rdgpu.analysis.isometry.interface_width`) and the largest change of ``u`` since the last
sample.  A run's verdict:

* ``uniform``: one phase is gone (u > 0 everywhere or nowhere); the time is the first
  sample at which it is (uniform is final: the favoured phase's constant is stable);
* ``frozen``: not uniform and ``max |u(T) − u(T/2)| < 1e-6`` (the interfaces are pinned by
  the mesh: a discrete equilibrium that the continuous equation does not have);
* ``coarsening``: still changing at T ("not by T").

Results go to ``docs/data/seed000_study.json`` (with the wall time of every run), the figure
to ``docs/img/seed000_study.png``, and a markdown table to stdout.  The other parts:
``presets`` measures every ``ac-sphere-*`` preset (class, components, interface width at its
steps and at 3× its steps); ``isometry`` runs seed 000's isometry experiment
(:mod:`rdgpu.analysis.isometry`, figure ``docs/img/seed000_isometry.png``); ``spheres`` renders the
pinned and the resolved spot presets side by side (``docs/img/seed000_spheres.png``).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a clone without installing

from rdgpu.analysis import classify_pattern, phase_components  # noqa: E402
from rdgpu.analysis.isometry import interface_width  # noqa: E402
from rdgpu.analysis.pinning import FROZEN_TOL, SAMPLES, run_case, table  # noqa: E402
from rdgpu.domains.mesh.surface_mesh import SurfaceMesh  # noqa: E402

RATIOS = (0.1, 0.15, 0.25, 0.5, 1.0, 2.0)
BS = (-0.3, -0.2, -0.1, -0.05, 0.0, 0.05, 0.1, 0.2, 0.3)
LEVELS = (4, 5, 6)
JSON_PATH = ROOT / "docs" / "data" / "seed000_study.json"
FIG_PATH = ROOT / "docs" / "img" / "seed000_study.png"


def run_study(levels: tuple[int, ...], ratios: tuple[float, ...], bs: tuple[float, ...],
              results: dict[str, Any]) -> dict[str, Any]:
    """Run every (level, ε/h, b) of the grid, updating ``results["runs"]`` (keyed
    ``"L/ratio/b"``) and writing the JSON after each level."""
    runs = results.setdefault("runs", {})
    for level in levels:
        mesh = SurfaceMesh.icosphere(level)
        for ratio in ratios:
            for b in bs:
                r = run_case(mesh, ratio, b)
                r["level"] = level
                runs[f"{level}/{ratio}/{b}"] = r
                ttu = r["uniform_at"]
                print(f"level {level} ε/h {ratio:<4} b {b:+.2f}: {r['verdict']:<10} "
                      f"{r['final_class']:<15} comps {r['final_components']:<5} "
                      + (f"uniform at {ttu['t_eps2']:.0f} ε² ({ttu['step']} steps)"
                         if ttu else "") + f"  [{r['seconds']:.1f} s]", flush=True)
        save(results)
    return results


def measure_presets(names: tuple[str, ...] | None = None, factor: int = 3) -> dict[str, Any]:
    """Every ``ac-sphere-*`` preset (or ``names``) as the CLI runs it (OpenCL, float64):
    class, components and interface width at its ``steps`` and at ``factor`` × its steps,
    the largest change of u between the two, and the wall time of its steps."""
    from rdgpu.models import PRESETS
    from rdgpu.simulation.driver import Simulation

    names = names or tuple(n for n in PRESETS if n.startswith("ac-sphere-"))
    out = {}
    for name in names:
        p = PRESETS[name]
        sim = Simulation.from_preset(p, backend="opencl", dtype="float64")
        st = sim.stepper
        t0 = time.perf_counter()
        st.advance(p.steps)
        u1 = st.get_state()["u"]
        seconds = time.perf_counter() - t0
        st.advance((factor - 1) * p.steps)
        u2 = st.get_state()["u"]
        eps = float(sim.params["eps"])
        row: dict[str, Any] = {"steps": p.steps, "t_eps2": p.steps * p.dt / eps**2,
                               "eps_over_h": eps / float(sim.domain.mean_edge_length),
                               "b": float(sim.params["b"]), "seconds": seconds,
                               f"max_change_to_x{factor}": float(np.max(np.abs(u2 - u1)))}
        for tag, u in (("at_steps", u1), (f"at_x{factor}", u2)):
            comps = phase_components(u, sim.domain, 0.0)
            uniform = (u > 0).all() or (u <= 0).all()
            row[tag] = {"class": classify_pattern(u, sim.domain, 0.0),
                        "high": int(len(comps["high"])), "low": int(len(comps["low"])),
                        "width": None if uniform else interface_width(u, sim.domain)}
        out[name] = row
        print(f"{name}: {row}", flush=True)
    return out


#: the isometry experiment's tube: radius 1, 96 vertices around, near-equilateral triangles,
#: length ~8; bent by π/2 (bend radius 5.1: lengths along the axis scaled by 1 ± 0.2)
#: and π (radius 2.5: ± 0.4)
ISO_TUBE = {"radius": 1.0, "n_around": 96, "length": 8.0}
ISO_ANGLES = (0.5 * np.pi, np.pi)
#: (b, time in ε², phase compared): spots, inverted spots, stripes twice
ISO_CASES = ((-0.05, 8.0, "low"), (0.05, 8.0, "high"), (0.0, 30.0, "high"),
             (0.0, 100.0, "high"))
ISO_FIG = ROOT / "docs" / "img" / "seed000_isometry.png"


def iso_tube(radius: float, n_around: int, length: float) -> SurfaceMesh:
    """The tube of :data:`ISO_TUBE`: rings ``(2π r/n) √3/2`` apart (equilateral triangles)."""
    from rdgpu.analysis.isometry import cylinder

    dz = 2.0 * np.pi * radius / n_around * np.sqrt(3.0) / 2.0
    n_along = int(length / dz) + 1
    return cylinder(radius, (n_along - 1) * dz, n_around, n_along)


def isometry(render: bool = True) -> dict[str, Any]:
    """Seed 000's Figs. 12/15: overlaps (same data, straight vs bent; different data,
    straight vs straight) for :data:`ISO_CASES` at :data:`ISO_ANGLES`; the figure pair of
    the first case at the first angle."""
    from rdgpu.analysis.isometry import bend, isometry_experiment

    tube = iso_tube(**ISO_TUBE)
    rows = []
    pair = None
    for angle in ISO_ANGLES:
        bent = bend(tube, angle)
        for b, t, phase in ISO_CASES:
            r = isometry_experiment(tube, bent, ratio=1.0, b=b, t_eps2=t, phase=phase)
            if pair is None:
                pair = (bent, r)
            rows.append({"angle": float(angle), "b": b, "t_eps2": r["t_eps2"],
                         "steps": r["steps"], "phase": phase,
                         **{k: r[k] for k in ("eps", "dt", "dice_same", "dice_baseline",
                                              "jaccard_same", "jaccard_baseline")}})
            print(f"isometry: {rows[-1]}", flush=True)
    out = {"tube": {**ISO_TUBE, "vertices": tube.n_vertices,
                    "h": float(tube.mean_edge_length)}, "rows": rows}
    if render and pair is not None:
        iso_figure(tube, *pair)
    return out


def iso_figure(tube: SurfaceMesh, bent: SurfaceMesh, r: dict[str, Any],
               path: Path = ISO_FIG) -> Path:
    """Straight and bent tube side by side, same initial data (smooth shading)."""
    import imageio.v3 as iio

    from rdgpu.io.output import render_mesh

    views = []
    for mesh, u in ((tube, r["u_straight"]), (bent, r["u_bent"])):
        c = np.asarray(mesh.vertices).mean(axis=0)
        cam = [(c[0], c[1] - 22.0, c[2]), tuple(c), (1.0, 0.0, 0.0)]
        views.append(render_mesh(mesh, u, camera=cam, vmin=-1, vmax=1,
                                 window_size=(480, 480)))
    path.parent.mkdir(parents=True, exist_ok=True)
    iio.imwrite(path, np.concatenate(views, axis=1))
    return path


SPHERES_FIG = ROOT / "docs" / "img" / "seed000_spheres.png"


def spheres(names: tuple[str, ...] = ("ac-sphere-spots", "ac-sphere-resolved-spots"),
            path: Path = SPHERES_FIG) -> Path:
    """Each preset's field at its final step (OpenCL, float64), rendered side by side with
    the same camera (smooth shading)."""
    import imageio.v3 as iio

    from rdgpu.io.output import render_mesh
    from rdgpu.models import PRESETS
    from rdgpu.simulation.driver import Simulation

    views = []
    for name in names:
        p = PRESETS[name]
        sim = Simulation.from_preset(p, backend="opencl", dtype="float64")
        u = sim.run(p.steps, snapshot_every=0, progress=False).fields["u"]
        views.append(render_mesh(sim.domain, u, vmin=-1, vmax=1, window_size=(480, 480)))
    path.parent.mkdir(parents=True, exist_ok=True)
    iio.imwrite(path, np.concatenate(views, axis=1))
    return path


def save(results: dict[str, Any]) -> None:
    JSON_PATH.parent.mkdir(parents=True, exist_ok=True)
    JSON_PATH.write_text(json.dumps(results, indent=1) + "\n")


_COLOURS = {"frozen": "#4c72b0", "coarsening": "#dd8452", "uniform": "#dddddd"}


def figure(results: dict[str, Any], path: Path = FIG_PATH) -> Path:
    """The map over (ε/h, b) per level: colour = verdict, text = time to uniform (ε²) or the
    final class and number of components."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    runs = results["runs"]
    levels = sorted({r["level"] for r in runs.values()})
    fig, axes = plt.subplots(1, len(levels), figsize=(5.2 * len(levels), 4.6), squeeze=False)
    for ax, level in zip(axes[0], levels, strict=True):
        rows = [r for r in runs.values() if r["level"] == level]
        ratios = sorted({r["ratio"] for r in rows})
        bs = sorted({r["b"] for r in rows})
        for i, ratio in enumerate(ratios):
            for j, b in enumerate(bs):
                r = runs.get(f"{level}/{ratio}/{b}")
                if r is None:
                    continue
                ax.add_patch(plt.Rectangle((j - 0.5, i - 0.5), 1, 1,
                                           color=_COLOURS[r["verdict"]]))
                if r["verdict"] == "uniform":
                    text = f"{r['uniform_at']['t_eps2']:.0f}"
                else:
                    short = {"spots": "S", "inverted-spots": "IS", "stripes": "St",
                             "uniform": "U"}[r["final_class"]]
                    text = f"{short}\n{r['final_components']}"
                ax.text(j, i, text, ha="center", va="center", fontsize=7)
        ax.set_xlim(-0.5, len(bs) - 0.5)
        ax.set_ylim(-0.5, len(ratios) - 0.5)
        ax.set_xticks(range(len(bs)), [f"{b:+.2f}" for b in bs])
        ax.set_yticks(range(len(ratios)), [str(x) for x in ratios])
        ax.set_xlabel("b")
        ax.set_ylabel("ε / h")
        ax.set_title(f"icosphere({level}), {rows[0]['level_vertices']} vertices")
    fig.legend(handles=[Patch(color=c, label=k) for k, c in _COLOURS.items()], loc="lower center",
               ncol=3, frameon=False)
    fig.suptitle("seed 000 on icospheres: verdict at T = 10 000 ε²; number = time to uniform (ε²),"
                 " else class (S spots, IS inverted, St stripes) and components", fontsize=9)
    fig.tight_layout(rect=(0, 0.06, 1, 0.95))
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--levels", type=int, nargs="+", default=list(LEVELS))
    ap.add_argument("--ratios", type=float, nargs="+", default=list(RATIOS))
    ap.add_argument("--bs", type=float, nargs="+", default=list(BS))
    ap.add_argument("--figure-only", action="store_true",
                    help="rebuild the figure and table from the JSON without running")
    parts = ["study", "presets", "isometry", "spheres"]
    ap.add_argument("--parts", nargs="+", default=parts, choices=parts, help="what to run")
    args = ap.parse_args(argv)
    results = json.loads(JSON_PATH.read_text()) if JSON_PATH.exists() else {}
    if not args.figure_only and "study" in args.parts:
        results["settings"] = {"samples_eps2": list(SAMPLES), "frozen_tol": FROZEN_TOL,
                               "init": "uniform random in [-1, 1], seed 0",
                               "backend": "opencl", "dtype": "float64",
                               "dt": "min(eps^2/2, dt_limit/2)"}
        t0 = time.perf_counter()
        run_study(tuple(args.levels), tuple(args.ratios), tuple(args.bs), results)
        results["settings"]["last_wall_s"] = time.perf_counter() - t0
        save(results)
    if not args.figure_only and "presets" in args.parts:
        results["presets"] = measure_presets()
        save(results)
    if not args.figure_only and "isometry" in args.parts:
        results["isometry"] = isometry()
        save(results)
    if not args.figure_only and "spheres" in args.parts:
        print(f"spheres: {spheres()}")
    print(table(results))
    print(f"figure: {figure(results)}")


if __name__ == "__main__":
    main()
