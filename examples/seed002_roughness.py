"""Seed 002 §4.2, measured: spots and stripes on flat and rough surfaces.

The seed (Realistic pattern formations on surfaces by adding arbitrary roughness) grows
Turing spots and stripes on graph surfaces ``z = h(x, y)`` of random waves (eqs. 6-7:
frequencies up to ``M`` along x and ``N`` along y, scaled so ``max|h|`` is the amplitude)
and concludes that "the number of spots increases as the frequencies and the amplitude
increase" and that the patterns deform.  Its reaction terms were lost in conversion; this
script uses the BVAM system of Barrio, Varea, Aragón & Maini (1999), the Barrio-type model
of the seed's reference [31] (Li & Ling 2020), at the origin-centred steady state (0, 0)
(``rdgpu.models.MODELS["bvam"]``):

    u_t = D δ Δ_Γ u + α u (1 − r1 v²) + v (1 − r2 u)
    v_t =   δ Δ_Γ v + β v (1 + (α r1/β) u v) + u (γ + r2 v)

with D = 0.516, α = 0.899, β = −0.91, γ = −α; spots: r1 = 0.02, r2 = 0.2 (the quadratic
term wins: hexagonal spots of high u); stripes: r1 = 3.5, r2 = 0 (cubic only: stripes).
δ = 6.6e-4 puts the fastest linear mode at wavelength 0.256 (growth rate 0.013), about
8 wavelengths across the flat square ``[0, 2)²`` (``rdgpu.analysis.dispersion``).

Every run starts from the same random data, u and v uniform in [−0.5, 0.5), on the same
``n × n`` periodic grid; the surfaces of one column share their wave coefficients (one
``seed``) and differ only by the amplitude, so each column is the same geometry made
steeper.  Amplitudes are fractions of the side L = 2.  Time stepping: IMEX Euler (the
diffusion implicit), ``dt = 0.5`` (the seed's), to t = 800 (spots, the seed's) and
t = 2000 (stripes; the seed's 4000 doubles the cost and the flat stripes are formed by 2000).

Measures (``rdgpu.analysis``) of the final u: :func:`spot_statistics` (number of spots of
high u, coefficient of variation of their surface areas, mean principal-axis ratio of
each spot on the surface) and :func:`stripe_orientation` (the stripes' mean direction and
coherence); on the stripe runs also the number of high-u pieces (a stripe that breaks
becomes several).

Writes ``docs/data/seed002_roughness.md`` and ``.json`` (the table) and
``docs/img/seed002_roughness.png`` (the mosaic: rows amplitude, columns frequency, spots
left and stripes right, each panel labelled with its measures).

    python examples/seed002_roughness.py            # 7 + 7 runs at 128² (~8 min, 2 busy cores)
    python examples/seed002_roughness.py --quick    # 64², 2 amplitudes × 2 frequencies

The runs and their measures are :mod:`rdgpu.analysis.rough_patterns`'s
(:func:`~rdgpu.analysis.rough_patterns.experiment`); each run is :class:`rdgpu.Simulation`
on the graph surface (``{"grid": (n, n), "dx": dx, "height": h}``, method ``imex``,
float64, ``--backend``, default opencl).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rdgpu.analysis.rough_patterns import DT, PATTERNS, SIDE, experiment  # noqa: E402
from rdgpu.models import MODELS  # noqa: E402

FULL = {"n": 128, "amplitudes": (0.0, 0.05, 0.1),
        "frequencies": ((5, 5), (5, 15), (15, 15))}
QUICK = {"n": 64, "amplitudes": (0.0, 0.05), "frequencies": ((5, 5), (15, 15)),
         "time_scale": 0.5}


def _fmt(x: float, digits: int = 2) -> str:
    return "—" if isinstance(x, float) and math.isnan(x) else f"{x:.{digits}f}"


def summary(rows: list[dict]) -> list[str]:
    """One line per rough run: its measures against the flat run's (ratios), so the claim
    "spots multiply and deform as amplitude and frequency rise" is read off the numbers."""
    out = ["Against the flat run of the same pattern (ratios rough/flat):", ""]
    for pattern in PATTERNS:
        flat = [r for r in rows if r["pattern"] == pattern and r["amplitude"] == 0.0]
        if not flat:
            continue
        f = flat[0]
        for r in rows:
            if r["pattern"] != pattern or r["amplitude"] == 0.0:
                continue
            out.append(
                f"- {pattern}, amplitude {r['amplitude']:g}, (M, N) = ({r['M']}, {r['N']}): "
                f"count ×{r['count'] / max(f['count'], 1):.2f}, area ×{r['area'] / f['area']:.2f}, "
                f"spots/area ×{r['density'] / f['density']:.2f}, size CV "
                f"{_fmt(f['size_spread'])} → {_fmt(r['size_spread'])}, elongation "
                f"{_fmt(f['elongation'])} → {_fmt(r['elongation'])}, coherence "
                f"{f['coherence']:.2f} → {r['coherence']:.2f}")
    return out


def write_table(rows: list[dict], config: dict[str, Any], backend: str, path: Path) -> None:
    """The markdown table (and the JSON beside it)."""
    n = config["n"]
    lines = [
        "# Seed 002 §4.2: spots and stripes on rough surfaces, measured",
        "",
        f"BVAM (Barrio et al. 1999), {n}×{n} periodic grid over [0, {SIDE:g})², IMEX Euler "
        f"dt = {DT}, backend `{backend}`; amplitude = max|h| / side; measures of the final u "
        "by `rdgpu.analysis` (spots: high-u regions of ≥ 2 cells, midrange threshold; "
        "areas on the surface; min cells/λ: the flat wavelength 0.256 over dx·√(1 + slope²), "
        "the resolution where the surface is steepest). Written by "
        "`examples/seed002_roughness.py`.",
        "",
        "| pattern | amplitude | (M, N) | max slope | min cells/λ | area | t | spots | "
        "spots/area | size CV | elongation | coherence | angle (°) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['pattern']} | {r['amplitude']:g} | ({r['M']}, {r['N']}) | "
            f"{r['max_slope']:.2f} | {r['cells_per_wavelength']:.1f} | {r['area']:.2f} | "
            f"{r['t']:g} | {r['count']} | {r['density']:.2f} | "
            f"{_fmt(r['size_spread'])} | {_fmt(r['elongation'])} | {r['coherence']:.3f} | "
            f"{_fmt(r['angle_deg'], 0)} |")
    lines += ["", *summary(rows)]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n")
    data = [{k: v for k, v in r.items() if k != "u"} for r in rows]
    path.with_suffix(".json").write_text(json.dumps(
        {"model": "bvam", "params": dict(MODELS["bvam"].defaults),
         "patterns": {k: v[0] for k, v in PATTERNS.items()},
         "n": n, "side": SIDE, "dt": DT, "backend": backend, "rows": data}, indent=1,
        default=float) + "\n")


def write_figure(rows: list[dict], config: dict[str, Any], path: Path) -> None:
    """The mosaic: rows amplitude, columns frequency; spots left, stripes right."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    amps, freqs = config["amplitudes"], config["frequencies"]
    cols = [(p, f) for p in PATTERNS for f in freqs]
    fig, axes = plt.subplots(len(amps), len(cols), figsize=(2.2 * len(cols), 2.4 * len(amps)),
                             squeeze=False)
    for i, amp in enumerate(amps):
        for j, (pattern, freq) in enumerate(cols):
            ax = axes[i, j]
            ax.set_xticks([])
            ax.set_yticks([])
            match = [r for r in rows if r["pattern"] == pattern and r["amplitude"] == amp and
                     (amp == 0.0 or (r["M"], r["N"]) == tuple(freq))]
            r = match[0]
            ax.imshow(r["u"], origin="lower", cmap="viridis", interpolation="nearest")
            label = (f"n={r['count']} cv={_fmt(r['size_spread'])} e={_fmt(r['elongation'])}"
                     if pattern == "spots" else
                     f"coh={r['coherence']:.2f} pieces={r['count']}")
            ax.set_xlabel(label, fontsize=7)
            if i == 0:
                ax.set_title(f"{pattern} (M,N)={tuple(freq)}", fontsize=8)
            if j == 0:
                ax.set_ylabel(f"amplitude {amp:g}", fontsize=8)
    fig.suptitle("BVAM u on the parameter plane [0, 2)² (rows: amplitude, max|h|/side; "
                 "columns: max frequencies (M, N))", fontsize=9)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="64², 2 amplitudes × 2 frequencies, "
                    "half the run time (about a minute)")
    ap.add_argument("--backend", default="opencl", help="rdgpu backend (default opencl)")
    ap.add_argument("--n", type=int, default=None, help="grid side (default 128; 64 quick): "
                    "the steepest surfaces need more (see the table's min cells/λ)")
    ap.add_argument("--seed", type=int, default=2)
    ap.add_argument("--out", type=Path, default=ROOT / "docs",
                    help="writes data/seed002_roughness.{md,json}, img/seed002_roughness.png")
    args = ap.parse_args(argv)
    config = dict(QUICK if args.quick else FULL)
    if args.n is not None:
        if args.n < 16:
            raise SystemExit(f"--n must be at least 16 cells, got {args.n}")
        config["n"] = args.n
    rows = experiment(config, args.backend, args.seed)
    write_table(rows, config, args.backend, args.out / "data" / "seed002_roughness.md")
    write_figure(rows, config, args.out / "img" / "seed002_roughness.png")
    print(f"wrote {args.out / 'data' / 'seed002_roughness.md'} and "
          f"{args.out / 'img' / 'seed002_roughness.png'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
