"""Regenerate the README gallery: ``docs/gallery/*.png`` and ``docs/gallery/gallery.md``.

    python examples/gallery.py                    # every picture, OpenCL backend
    python examples/gallery.py --only gs-seed001-spots ac-sphere-spots
    python examples/gallery.py --backend warp     # another backend (same classes)

Every picture is made by the command line itself: the script calls ``rdgpu.cli.main`` with
the arguments that ``gallery.md`` shows next to the picture (run from the repository
root), so the table's command is the one that made the image.  Two things happen after
the command:

* the script also passes ``--data TMP.npz`` (a temporary file, not shown in the table, no
  influence on the run) and measures the final field's pattern with
  ``rdgpu.analysis.classify_pattern`` (``spiral_tips`` for the Barkley spirals): the
  table's "measured" column;
* the PNG is made small for the repository (≤ 60 kB): a grid picture (≤ 256 colours, one
  per entry of the colour map) is re-encoded as a palette PNG, pixel for pixel the same,
  or, where that is still too large (the 256² and 300² Gray-Scott grids), with 64 (or 32)
  of the map's colours at full resolution, or else (the 400² grid) downscaled to 256²; a
  mesh rendering (pyvista, 800 × 800) is downscaled to 256 × 256 with 256 colours.  The
  table says which.

About two minutes on a 2-core CPU with the OpenCL backend (PoCL).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a clone without installing

from rdgpu.analysis import classify_pattern, fractal_dimension, spiral_tips  # noqa: E402
from rdgpu.cli.app import main as rdgpu_main  # noqa: E402
from rdgpu.io.output import load_npz  # noqa: E402
from rdgpu.models import PRESETS  # noqa: E402

OUT = Path("docs/gallery")  # relative to the repository root, as in the commands
MESH_SIZE = 256
MAX_BYTES = 60_000

#: (preset, caption, extra command-line options)
ENTRIES: list[tuple[str, str, list[str]]] = [
    ("gs-seed001-stripes", "Gray-Scott stripes: the labyrinth of Camphuijsen & Kasim 2016 "
                           "(F = 0.035, "
     "k = 0.060, 300², dt = dx = 1)", []),
    ("gs-seed001-spots", "Gray-Scott spots: Camphuijsen & Kasim's second parameter set (F = 0.030, "
     "k = 0.055)", []),
    ("gs-differential-flow", "Gray-Scott with the activator v carried by a uniform flow to "
     "the right (upwind advect, 0.04 cells a step): the labyrinth lines up across the flow",
     []),
    ("gs-masked-disc", "Gray-Scott labyrinth on a disc cut from the grid by a mask "
     "(mask=): zero flux across its edge, the stripes meeting the wall at right angles; the "
     "cells outside grey", []),
    ("cahn-hilliard-coarsening", "Cahn-Hilliard phase separation, laplace(u**3 - u - "
     "g*laplace(u)) (the chemical potential stored by a pre-pass): a noisy mixture "
     "coarsened into a labyrinth at t = 500, its mass conserved", []),
    ("keller-segel-aggregates", "Keller-Segel chemotaxis with logistic growth, "
     "div(chi*u*grad(v)) in flux form: cells u gathered into aggregates (islands of "
     "high u: inverted spots in rdgpu's classes)", []),
    ("gs-pearson-alpha", "Pearson α (F = 0.010, k = 0.047): spatio-temporal chaos", []),
    ("gs-pearson-delta", "Pearson δ (F = 0.030, k = 0.055): hexagonal lattice of spots", []),
    ("gs-pearson-theta", "Pearson θ (F = 0.030, k = 0.057): stripes and loops", []),
    ("gs-pearson-kappa", "Pearson κ (F = 0.050, k = 0.063): worms grown into a labyrinth",
     []),
    ("gs-pearson-lambda", "Pearson λ (F = 0.026, k = 0.061): solitons in a hexagonal "
     "lattice (inverted spots)", []),
    ("gs-pearson-mu", "Pearson μ (F = 0.046, k = 0.065): worms into parallel stripes", []),
    ("ac-sphere-spots", "Modified Allen-Cahn on the sphere, b = −0.25: spots (islands of "
     "u < 0)", []),
    ("ac-sphere-stripes", "Modified Allen-Cahn, b = 0: stripes (both phases connected "
     "into a labyrinth)", []),
    ("ac-sphere-inverted-spots", "Modified Allen-Cahn, b = +0.25: inverted spots", []),
    ("ac-sphere-local-spots", "Modified Allen-Cahn, b = −0.08, random data in a patch: "
     "the spots stay localized (seed 12 puts the patch in view)", ["--seed", "12"]),
    ("ac-sphere-local-spreads", "Modified Allen-Cahn, b = 0, random data in a patch: the "
     "pattern spreads over the sphere", []),
    ("brusselator-spots", "Brusselator just past the Turing onset (a = 5, b = 6.6): spots",
     []),
    ("brusselator-stripes", "Brusselator further past onset (b = 8): stripes", []),
    ("brusselator-noise", "Brusselator (b = 9) from its exact homogeneous steady state, "
     "which no deterministic run leaves: Itô noise on u (variance 1e-4, Euler-Maruyama, "
     "Philox numbers) starts the Turing labyrinth", []),
    ("brusselator-seed004-fig1", "Brusselator with a and b varying across the domain "
     "(Quillen 2025, Fig. 1): stripes and spots side by side", []),
    ("fitzhugh-nagumo-stripes", "FitzHugh-Nagumo (α = 0.01): a labyrinth of worms", []),
    ("fitzhugh-nagumo-spots", "FitzHugh-Nagumo (α = 0.05): spots", []),
    ("barkley-spirals", "Barkley's excitable medium: rotating spirals (field u)", []),
    ("turing-seed003-spots", "Turing's 1952 spot model, Chattopadhyay eq. 2.15 on 64² "
     "(field b; D_a = 0.25)", ["--scale", "4"]),
    ("ac-sphere-resolved-spots", "Modified Allen-Cahn with the interface resolved (ε = h, "
     "b = −0.05, icosphere(6)) at 8 ε², while its spots exist: they are transient "
     "(docs/seed000.md)", []),
    ("bvam-cheetah", "Cheetah: BVAM spots on a random-wave surface, M = 5, N = 15, "
     "amplitude 0.1 of the side (seed 002 Fig. 12 d; the parameter plane)", []),
    ("bvam-genet", "Genet: BVAM spots on a random-wave surface, M = N = 15, amplitude 0.05 "
     "of the side (seed 002 Fig. 12 b)", []),
    ("bvam-angelfish", "Emperor angelfish: BVAM stripes on a random-wave surface, M = N = "
     "5, amplitude 0.05 of the side (seed 002 Fig. 12 a)", []),
    ("gray-scott-rough-sphere", "Gray-Scott spots on a closed rough surface: a sphere "
     "roughened by heat-filtered random displacements (seed 002 §5, Fig. 14 b)", []),
    ("swift-hohenberg-disc", "Swift-Hohenberg stripes on a triangulated disc, natural "
     "boundary (Quillen 2025 §6, Fig. 13)", []),
]


#: the growth systems of seed 001 and seed 003 §4.2 (not presets): name -> (caption,
#: source, the arguments after ``rdgpu run``); "measured" is their fractal dimension
#: (mass-radius about the seed cell for radial growth, box counting for the slab's) or the
#: front's inside fraction
GROWTH_ENTRIES: dict[str, tuple[str, str, list[str]]] = {
    "dla-eta0-radial": ("DLA by the nutrient field, η = 0: a compact bulk", "seed 001 §1, eq. 2",
                        ["dla", "--param", "eta=0", "--param", "geometry=radial", "--size",
                         "96", "--steps", "1500"]),
    "dla-eta1-radial": ("DLA, η = 1: ordinary diffusion-limited aggregation",
                        "seed 001 §1, eq. 2",
                        ["dla", "--param", "eta=1", "--param", "geometry=radial", "--size",
                         "128", "--steps", "3000"]),
    "dla-eta2-radial": ("DLA, η = 2: sparser, more linear growth", "seed 001 §1, eq. 2",
                        ["dla", "--param", "eta=2", "--param", "geometry=radial", "--size",
                         "128", "--steps", "3000"]),
    "dla-eta1-seed001": ("DLA, η = 1, the seed's set-up: grown up from the bottom row "
                         "towards c = 1 at the top", "seed 001 §1, eq. 2",
                         ["dla", "--param", "eta=1", "--size", "128", "--steps", "3000"]),
    "walkers-sticking1": ("Random walkers, sticking 1: 4000 particles, 64 walkers in flight",
                          "seed 001 §2", ["random-walk-dla", "--param", "sticking=1",
                                          "--param", "walkers=64", "--size", "256",
                                          "--steps", "4000"]),
    "walkers-sticking01": ("Random walkers, sticking 0.1: denser, not thinner", "seed 001 §2",
                           ["random-walk-dla", "--param", "sticking=0.1", "--param",
                            "walkers=64", "--size", "256", "--steps", "4000"]),
    "turing-front": ("A level-set front driven by Turing's spots (β = Δu): the region "
                     "φ < 0 in black", "seed 003 §4.2", ["turing-front", "--scale", "4"]),
}


def growth_command(name: str, backend: str) -> list[str]:
    argv = ["run", *GROWTH_ENTRIES[name][2], "--backend", backend]
    if "--scale" not in argv:
        argv += ["--scale", "1"]
    return argv + ["--out", str(OUT / f"{name}.png")]


def growth_measure(name: str, data: Path) -> str:
    z = np.load(data)
    if name == "turing-front":
        return f"{z['mask'].mean():.0%} inside the front"
    mask = z["mask"]
    if "geometry=radial" in GROWTH_ENTRIES[name][2] or name.startswith("walkers"):
        d = fractal_dimension(mask, center=(mask.shape[0] // 2, mask.shape[1] // 2))
        return f"D = {d.dimension:.2f} (mass-radius, {int(mask.sum())} cells)"
    d = fractal_dimension(mask, method="box")
    return f"D = {d.dimension:.2f} (box counting, {int(mask.sum())} cells)"


def command(name: str, extra: list[str], backend: str) -> list[str]:
    p = PRESETS[name]
    argv = ["run", p.model, "--preset", name, "--backend", backend]
    if "grid" in p.domain and "--scale" not in extra:
        argv += ["--scale", "1"]
    return argv + extra + ["--out", str(OUT / f"{name}.png")]


def measure(name: str, data: Path) -> str:
    p = PRESETS[name]
    res = load_npz(data)
    if p.expect == "spirals":
        tips = spiral_tips(res.fields["u"], res.fields["v"], res.domain,
                           center=p.classify["center"])
        return f"{tips} spiral tips"
    c = p.classify
    found = classify_pattern(res.fields[c["field"]], res.domain, threshold=c["threshold"])
    if p.expect == "chaos":  # never steady: the class of this instant only
        return f"chaos ({found} at the last step)"
    return found


def shrink(path: Path, mesh: bool) -> str:
    """Make the PNG small (see the module docstring); what was done, for the table."""
    import io

    from PIL import Image

    img = Image.open(path).convert("RGB")

    def encode(picture) -> bytes:
        buf = io.BytesIO()
        picture.save(buf, format="PNG", optimize=True)
        return buf.getvalue()

    def palette(picture, colours: int):
        return picture.quantize(colours, method=Image.Quantize.MEDIANCUT,
                                dither=Image.Dither.NONE)

    if mesh:
        img = img.resize((MESH_SIZE, MESH_SIZE), Image.Resampling.LANCZOS)
        data, note = encode(palette(img, 256)), f"rendering downscaled to {MESH_SIZE}²"
    else:
        exact = palette(img, 256)
        if not np.array_equal(np.asarray(exact.convert("RGB")), np.asarray(img)):
            raise RuntimeError(f"{path}: more than 256 colours, not re-encoded losslessly")
        data, note = encode(exact), "pixel for pixel"
        for colours in (64, 32):
            if len(data) <= MAX_BYTES:
                break
            data, note = encode(palette(img, colours)), f"{colours} colours of the map"
        if len(data) > MAX_BYTES:  # the 400² grid: fewer pixels
            small = img.resize((MESH_SIZE, MESH_SIZE), Image.Resampling.LANCZOS)
            data, note = encode(palette(small, 64)), f"downscaled to {MESH_SIZE}², 64 colours"
    path.write_bytes(data)
    return note


def write_table(rows: list[tuple[str, str, str, str, str]]) -> Path:
    intro = (
        "The source papers' patterns as rdgpu reproduces them. Each image is the PNG that "
        "the command beside it writes (run from the repository root, OpenCL backend); "
        "[`examples/gallery.py`](../../examples/gallery.py) regenerates them all through "
        "that command-line code path, then makes the PNGs small: grid pictures keep every "
        "pixel (with 64 or 32 of the colour map's 256 colours where the lossless PNG is "
        f"over {MAX_BYTES // 1000} kB; the 400² grid is downscaled), mesh renderings "
        f"(800 × 800) are downscaled to {MESH_SIZE}²; each caption says which. "
        "\"Measured\" is the class `rdgpu.analysis.classify_pattern` gives the final field "
        "(the number of spiral tips for Barkley; for the growth systems, the cluster's fractal "
        "dimension or the front's inside fraction); `rdgpu presets` lists what each preset "
        "should give."
    )
    lines = ["# Gallery", "", *textwrap.wrap(intro, 90), "",
             "| image | pattern (source) | measured | command |", "|---|---|---|---|"]
    for name, caption, note, measured, cmd in rows:
        src = (PRESETS[name].source if name in PRESETS else GROWTH_ENTRIES[name][1])
        src = src.replace("|", "\\|")
        lines.append(f"| ![{name}]({name}.png) | {caption} ({src}; picture: {note}) | "
                     f"{measured} | `{cmd}` |")
    path = ROOT / OUT / "gallery.md"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def run_and_measure(argv_run: list[str], measure_data) -> tuple[int, str]:
    """Run ``rdgpu`` with a temporary ``--data`` file: (exit status, what
    ``measure_data(path)`` says of that file; "" when the run failed)."""
    with tempfile.TemporaryDirectory() as tmp:
        data = Path(tmp) / "run.npz"
        code = rdgpu_main(argv_run + ["--data", str(data), "--quiet"])
        return code, (measure_data(data) if code == 0 else "")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--backend", default="opencl", help="rdgpu backend (default opencl)")
    parser.add_argument("--only", nargs="+", metavar="PRESET",
                        help="only these presets (gallery.md keeps the others' rows)")
    args = parser.parse_args(argv)

    import os

    os.chdir(ROOT)
    (ROOT / OUT).mkdir(parents=True, exist_ok=True)
    previous = _previous_rows()
    rows = []
    for name, caption, extra in ENTRIES:
        argv_run = command(name, extra, args.backend)
        shown = "rdgpu " + " ".join(argv_run)
        if args.only and name not in args.only:
            if name in previous:
                rows.append(previous[name])
            continue
        t0 = time.perf_counter()
        code, measured = run_and_measure(argv_run, lambda data, n=name: measure(n, data))
        if code != 0:
            print(f"{shown}: exit status {code}", file=sys.stderr)
            return code
        png = ROOT / OUT / f"{name}.png"
        note = shrink(png, mesh="mesh" in PRESETS[name].domain)
        size = png.stat().st_size
        print(f"{name}: {measured}, {size / 1000:.1f} kB, {time.perf_counter() - t0:.1f} s",
              flush=True)
        if size > MAX_BYTES:
            print(f"warning: {png} is {size} bytes (> {MAX_BYTES})", file=sys.stderr)
        rows.append((name, caption, note, measured, shown))
    for name, (caption, _, _) in GROWTH_ENTRIES.items():
        argv_run = growth_command(name, args.backend)
        shown = "rdgpu " + " ".join(argv_run)
        if args.only and name not in args.only:
            if name in previous:
                rows.append(previous[name])
            continue
        code, measured = run_and_measure(argv_run,
                                         lambda data, n=name: growth_measure(n, data))
        if code != 0:
            print(f"{shown}: exit status {code}", file=sys.stderr)
            return code
        note = shrink(ROOT / OUT / f"{name}.png", mesh=False)
        print(f"{name}: {measured}", flush=True)
        rows.append((name, caption, note, measured, shown))
    print(f"wrote {write_table(rows)}")
    return 0


def _previous_rows() -> dict[str, tuple[str, str, str, str, str]]:
    """Rows of an existing gallery.md, by preset (kept by --only)."""
    path = ROOT / OUT / "gallery.md"
    captions = {name: caption for name, caption, _ in ENTRIES}
    captions.update({name: entry[0] for name, entry in GROWTH_ENTRIES.items()})
    rows = {}
    if not path.exists():
        return rows
    for line in path.read_text(encoding="utf-8").splitlines():
        if not line.startswith("| ![") or "; picture: " not in line:
            continue
        name = line[len("| !["):line.index("]")]
        cells = [c.strip() for c in line.strip().strip("|").split(" | ")]
        if name in captions and len(cells) == 4:
            note = cells[1].rsplit("; picture: ", 1)[1].rstrip(")")
            rows[name] = (name, captions[name], note, cells[2], cells[3].strip("`"))
    return rows


if __name__ == "__main__":
    sys.exit(main())
