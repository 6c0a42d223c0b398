"""Presets: runs that reproduce the patterns of the seed papers, as data (a model name,
parameter values, a domain spec, an initial condition, the pattern class it should give).
``rdgpu presets`` lists them; ``rdgpu run MODEL --preset NAME`` runs one."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..backends.base import Backend
from ..domains import Grid
from .library import MODELS

__all__ = ["PRESETS", "Preset", "build_domain"]


def build_domain(spec: Mapping[str, Any]) -> Any:
    """A domain from a preset's dict: ``{"grid": (ny, nx), "dx": 1.0, "bc": "periodic"}``
    (``(nx,)`` 1-D, ``(nz, ny, nx)`` 3-D with ``"dz"``),
    ``{"mesh": "sphere", "subdivisions": 4, "radius": 1.0}``, ``{"mesh": "torus", "R": 1,
    "r": 0.3, "n_major": 96, "n_minor": 48}`` or ``{"mesh": "path/to/file.obj"}``."""
    spec = dict(spec)
    if "grid" in spec:
        shape = spec["grid"]
        shape = (int(shape),) * 2 if np.ndim(shape) == 0 else tuple(int(n) for n in shape)
        return Grid(shape, dx=float(spec.get("dx", 1.0)), dy=spec.get("dy"),
                    bc=spec.get("bc", "periodic"), dz=spec.get("dz"))
    if "mesh" in spec:
        from ..mesh import SurfaceMesh

        kind = spec["mesh"]
        if kind == "sphere":
            return SurfaceMesh.icosphere(int(spec.get("subdivisions", 4)),
                                         float(spec.get("radius", 1.0)))
        if kind == "torus":
            return SurfaceMesh.torus(
                float(spec.get("R", 1.0)), float(spec.get("r", 0.3)),
                int(spec.get("n_major", 96)), int(spec.get("n_minor", 48)),
            )
        return SurfaceMesh.load(kind, repair=bool(spec.get("repair", False)))
    raise ValueError(f"a domain spec has a 'grid' or a 'mesh' key, got {sorted(spec)}")



# ---------------------------------------------------------------------------- presets
@dataclass
class Preset:
    """A run that reproduces a pattern from a seed paper.

    ``model``: a key of :data:`MODELS`; ``params``: values or field specs
    (:func:`param_field`); ``domain``: a :func:`build_domain` spec; ``init``: the initial
    condition spec of the simulation driver; ``expect``: the pattern class it should give
    (``"spots"``, ``"inverted-spots"``, ``"stripes"``, ``"uniform"`` — what
    :func:`rdgpu.analysis.classify_pattern` measures — or ``"spirals"``); ``classify``:
    how to measure it (``field`` and ``threshold`` for ``classify_pattern``);
    ``options``: extra keyword arguments of ``model.stepper`` (e.g. ``method``)."""

    name: str
    model: str
    params: dict[str, Any]
    dt: float
    steps: int
    domain: dict[str, Any]
    init: dict[str, Any]
    source: str
    expect: str
    snapshot_every: int = 0
    description: str = ""
    classify: dict[str, Any] = field(default_factory=dict)
    seed: int = 0
    options: dict[str, Any] = field(default_factory=dict)

    def build_domain(self) -> Any:
        return build_domain(self.domain)

    def get_model(self) -> Any:
        return MODELS[self.model]

    def stepper(self, *, backend: Backend | str | None = None, dtype: Any = np.float64,
                domain: Any = None, seed: int | None = None, **kwargs) -> Any:
        """The preset's stepper (fields at zero: the driver sets the initial state)."""
        domain = self.build_domain() if domain is None else domain
        opts = {**self.options, **kwargs}
        return self.get_model().stepper(
            domain, self.params, dt=self.dt, backend=backend, dtype=dtype,
            seed=self.seed if seed is None else seed, **opts,
        )


PRESETS: dict[str, Preset] = {}


def _add(p: Preset) -> None:
    if p.model not in MODELS:
        raise ValueError(f"preset {p.name!r}: unknown model {p.model!r}")
    PRESETS[p.name] = p


# --- Camphuijsen & Kasim 2016: Gray-Scott on 300², dt = dx = 1
# (u = 0.5 everywhere, v = 0.25 in a square)
_SEED001_INIT = {"kind": "square", "values": {"u": 0.5, "v": 0.0},
                 "inside": {"u": 0.5, "v": 0.25}, "size": 0.1, "noise": 0.05}
_add(Preset(
    "gs-seed001-stripes", "gray-scott",
    {"Du": 0.16, "Dv": 0.08, "F": 0.035, "k": 0.060}, dt=1.0, steps=30000,
    domain={"grid": (300, 300), "dx": 1.0, "bc": "periodic"}, init=_SEED001_INIT,
    source="Camphuijsen & Kasim 2016 §3, Fig. 3", expect="stripes",
    snapshot_every=500, classify={"field": "v", "threshold": None},
    description="the four star-shaped fronts of the seed's t = 1300 figure grow into a "
    "labyrinth that fills the 300² torus (class stable from ~25 000 steps)",
))
_add(Preset(
    "gs-seed001-spots", "gray-scott",
    {"Du": 0.16, "Dv": 0.08, "F": 0.030, "k": 0.055}, dt=1.0, steps=20000,
    domain={"grid": (300, 300), "dx": 1.0, "bc": "periodic"}, init=_SEED001_INIT,
    source="Camphuijsen & Kasim 2016 §3, Fig. 5", expect="spots",
    snapshot_every=500, classify={"field": "v", "threshold": None},
    description="the square grows into a waffle and then a lattice of ~470 isolated spots "
    "(islands of low v, high u) in a connected sea (class stable from ~5 000 steps)",
))

# --- Pearson 1993 (Science 261, 189), his set-up: Du = 2e-5, Dv = 1e-5 on a 2.5 × 2.5
# periodic square of 256² cells (dx = 2.5/256), dt = 1, a 20 × 20 central square of
# (u, v) = (1/2, 1/4) in (1, 0), ±1 % noise.  (F, k) are representative points of each class
# (R. Munafo's catalogue of Pearson's map, mrob.com/pub/comp/xmorphia).  Pearson ran 200 000
# steps; the classes below are what classify_pattern(v, threshold=None) measured here after
# 60 000 steps (float32, OpenCL); "chaos" is no classify_pattern class (never steady).
_PEARSON = {
    # letter: (F, k, measured class, Pearson's description)
    "alpha": (0.010, 0.047, "chaos", "spatio-temporal chaos of wavelets and short-lived "
              "spirals"),
    "beta": (0.014, 0.039, "chaos", "chaos with localised flickering red/blue regions"),
    "gamma": (0.022, 0.051, "stripes", "stripes with endless local rearrangements"),
    "delta": (0.030, 0.055, "spots", "hexagonal lattice of holes (isolated low-v spots)"),
    "epsilon": (0.018, 0.055, "inverted-spots", "chaotic spots that split and die"),
    "zeta": (0.025, 0.060, "inverted-spots", "pulsating spots (Pearson's ζ; "
             "(0.022, 0.061) dies out with his initial square)"),
    "eta": (0.034, 0.063, "inverted-spots", "spots and worms that settle"),
    "theta": (0.030, 0.057, "stripes", "stripes and loops"),
    "iota": (0.046, 0.0594, "spots", "negative spots (holes) with molecule-like clusters"),
    "kappa": (0.050, 0.063, "stripes", "worms growing into labyrinths"),
    "lambda": (0.026, 0.061, "inverted-spots", "solitons dividing into a hexagonal lattice"),
    "mu": (0.046, 0.065, "stripes", "worms growing from their ends into parallel stripes"),
    "pi": (0.062, 0.061, "spots", "a few stationary negative spots (negatons)"),
}
for _letter, (_F, _k, _cls, _desc) in _PEARSON.items():
    _add(Preset(
        f"gs-pearson-{_letter}", "gray-scott",
        {"Du": 2e-5, "Dv": 1e-5, "F": _F, "k": _k}, dt=1.0, steps=60000,
        domain={"grid": (256, 256), "dx": 2.5 / 256, "bc": "periodic"},
        init={"kind": "square", "values": {"u": 1.0, "v": 0.0},
              "inside": {"u": 0.5, "v": 0.25}, "size": 20 / 256, "noise": 0.01},
        source=f"Pearson 1993, class {_letter} (F, k from Munafo's map)", expect=_cls,
        snapshot_every=1000, classify={"field": "v", "threshold": None},
        description=f"Pearson class {_letter}: {_desc}",
    ))

# --- Dascal et al.: modified Allen-Cahn on the unit sphere (icosphere, 5 subdivisions: 10 242
# vertices, mean edge h = 0.0378).  The pattern class depends on ε/h: with ε ≪ h the
# interfaces are pinned by the mesh (the seed's regime: dt = 0.9 explicit means its edges
# were long compared with ε), which is what keeps spots from shrinking away.
# Global patterns: ε = 0.15 h, dt = ε²/2 (the splitting is accurate), random data in
# [-1, 1]; measured: b = -0.25 spots, 0 stripes, +0.25 inverted spots; the field decays to
# a constant from |b| ≈ 0.30 (b = -0.28: 85 spots; -0.30: uniform or a few spots by seed),
# below 2/(3√3) ≈ 0.385 where u³ − u + b loses its second stable root.
_AC_MESH = {"mesh": "sphere", "subdivisions": 5, "radius": 1.0}
_AC_EPS_GLOBAL = 0.0057
_AC_EPS_LOCAL = 0.0113
for _name, _b, _cls in (("spots", -0.25, "spots"), ("inverted-spots", 0.25, "inverted-spots"),
                        ("stripes", 0.0, "stripes"), ("uniform", -0.35, "uniform")):
    _add(Preset(
        f"ac-sphere-{_name}", "allen-cahn", {"b": _b, "eps": _AC_EPS_GLOBAL},
        dt=0.5 * _AC_EPS_GLOBAL**2, steps=3000, domain=dict(_AC_MESH),
        init={"kind": "uniform", "values": {"u": 0.0}, "noise": 1.0},
        source="Dascal et al. §4.1, Figs. 5-9", expect=_cls, snapshot_every=100,
        classify={"field": "u", "threshold": 0.0},
        description=f"modified Allen-Cahn, b = {_b}, ε = {_AC_EPS_GLOBAL} (0.15 mean edge), "
        "random initial data on the unit sphere" + (
            "; |b| past the measured ~0.30 threshold: decays to a constant"
            if _name == "uniform" else ""),
    ))
# Localized patterns (Dascal et al. §4.2, Figs. 13-14): random data in a patch (0 elsewhere);
# ε = 0.3 h.  b = ±0.08: the favoured phase takes the rest of the sphere, the pattern stays
# in the patch; b = 0: u = 0 is an unstable equilibrium that the fronts invade everywhere.
for _name, _b, _cls in (("local-spots", -0.08, "spots"),
                        ("local-inverted-spots", 0.08, "inverted-spots"),
                        ("local-spreads", 0.0, "stripes")):
    _add(Preset(
        f"ac-sphere-{_name}", "allen-cahn", {"b": _b, "eps": _AC_EPS_LOCAL},
        dt=0.5 * _AC_EPS_LOCAL**2, steps=3000, domain=dict(_AC_MESH),
        init={"kind": "patch", "values": {"u": 0.0}, "patch": {"u": "random"},
              "radius": 0.3},
        source="Dascal et al. §4.2, Figs. 13-14", expect=_cls, snapshot_every=100,
        classify={"field": "u", "threshold": 0.0},
        description=f"modified Allen-Cahn, b = {_b}, ε = {_AC_EPS_LOCAL} (0.3 mean edge), "
        "random data in a patch of radius 0.6 around a random vertex: " + (
            "the pattern spreads over the whole sphere (stripes everywhere: every point "
            "far from the patch leaves u = 0, both phases appear there)" if _b == 0 else
            "the pattern stays in the patch"),
    ))

# --- Quillen 2025: Brusselator, FitzHugh-Nagumo, Barkley (periodic unless said otherwise)
_add(Preset(
    "brusselator-spots", "brusselator", {"Du": 2.0, "Dv": 22.0, "a": 5.0, "b": 6.6},
    dt=0.005, steps=20000, domain={"grid": (200, 200), "dx": 1.0, "bc": "periodic"},
    init={"kind": "uniform", "values": {"u": 5.0, "v": 1.32}, "noise": 0.05},
    source="Quillen 2025 §1.1-1.2 (onset b_c = (1 + a√(Du/Dv))² ≈ 6.29)", expect="spots",
    snapshot_every=500, classify={"field": "u", "threshold": None},
    description="just past the Turing onset: a hexagonal lattice of spots",
))
_add(Preset(
    "brusselator-stripes", "brusselator", {"Du": 2.0, "Dv": 22.0, "a": 5.0, "b": 8.0},
    dt=0.005, steps=20000, domain={"grid": (200, 200), "dx": 1.0, "bc": "periodic"},
    init={"kind": "uniform", "values": {"u": 5.0, "v": 1.6}, "noise": 0.05},
    source="Quillen 2025 §1.1-1.2", expect="stripes",
    snapshot_every=500, classify={"field": "u", "threshold": None},
    description="further past onset: a labyrinth of stripes",
))
_add(Preset(
    "brusselator-seed004-fig1", "brusselator",
    {"Du": 2.0, "Dv": 22.0, "a": {"kind": "sine", "mean": 5.0, "amplitude": 1.0, "axis": "x"},
     "b": {"kind": "sine", "mean": 9.0, "amplitude": 1.0, "axis": "y"}},
    dt=0.0025, steps=20000, domain={"grid": (400, 400), "dx": 1.0, "bc": "periodic"},
    init={"kind": "uniform", "values": {"u": 0.025, "v": 0.025}, "noise": 0.025},
    source="Quillen 2025 Fig. 1", expect="stripes",
    snapshot_every=500, classify={"field": "u", "threshold": None},
    description="α varies sinusoidally along x (5 ± 1), β along y (9 ± 1): stripes and spots "
    "side by side; u, v start small and random in [0, 0.05) as the seed advises",
))
_add(Preset(
    "fitzhugh-nagumo-stripes", "fitzhugh-nagumo",
    {"Du": 1.0, "Dv": 10.0, "alpha": 0.01, "beta": 1.0}, dt=0.01, steps=20000,
    domain={"grid": (200, 200), "dx": 1.0, "bc": ("neumann", "periodic")},
    init={"kind": "uniform", "values": {"u": 0.0, "v": 0.0}, "noise": 0.05},
    source="Quillen 2025 §1.8, Fig. 8 (periodic left/right, Neumann top/bottom)",
    expect="stripes", snapshot_every=500, classify={"field": "u", "threshold": None},
    description="a labyrinth of worms",
))
_add(Preset(
    "fitzhugh-nagumo-spots", "fitzhugh-nagumo",
    {"Du": 1.0, "Dv": 10.0, "alpha": 0.05, "beta": 1.0}, dt=0.01, steps=20000,
    domain={"grid": (200, 200), "dx": 1.0, "bc": "periodic"},
    init={"kind": "uniform", "values": {"u": 0.0, "v": 0.0}, "noise": 0.05},
    source="Quillen 2025 §1.8 (α raised to 0.05 breaks the u ↔ −u symmetry)", expect="spots",
    snapshot_every=500, classify={"field": "u", "threshold": None},
    description="isolated spots of low u",
))
_add(Preset(
    "barkley-spirals", "barkley", {"Du": 1.0, "a": 0.75, "b": 0.02, "eps": 0.02},
    dt=0.01, steps=20000, domain={"grid": (200, 200), "dx": 0.5, "bc": "periodic"},
    init={"kind": "patch", "values": {"u": 0.0, "v": 0.0},
          "patch": {"u": [0.0, 1.0], "v": [0.0, 0.6]}, "radius": 0.3},
    source="Quillen 2025 §1.9, eq. 51; Barkley 1991", expect="spirals",
    snapshot_every=200, classify={"fields": ["u", "v"], "center": [0.5, 0.355]},
    description="random excitations in a patch break into rotating spirals (measured with "
    "rdgpu.analysis.spiral_tips(u, v, center=(0.5, a/2 - b)): 6 tips, steady); dt = 0.01 "
    "respects both the diffusion limit and the reaction stiffness (~ε)",
))

# --- Chattopadhyay: Turing's spots (eq. 2.15) on 64²
_add(Preset(
    "turing-seed003-spots", "turing",
    {"Du": 0.25, "Dv": 0.0625, "s": 0.05, "beta": {"kind": "random", "low": 11.9, "high": 12.1}},
    dt=0.5, steps=8000, domain={"grid": (64, 64), "dx": 1.0, "bc": "periodic"},
    init={"kind": "uniform", "values": {"u": 4.0, "v": 4.0}},
    source="Chattopadhyay eq. 2.15, Fig. 2.4 (after Turing 1952, Turk 1991)", expect="spots",
    snapshot_every=100, classify={"field": "v", "threshold": None},
    description="valleys of b (= v) form ~100 isolated spots where a (= u) is high. "
    "D_a = 0.25 (the 1-D example's value) reproduces the seed's description; the 2-D "
    "text's D_a = 25 gives the opposite (peaks of b in a b = 0 sea, 'inverted-spots') and "
    "needs dt ≤ 0.01. The seed's Δ-per-iteration form is dt = 1, which is unstable in 2-D "
    "with the 5-point stencil (the limit for D_a = 0.25 is exactly 1), hence dt = 0.5",
))
