"""Presets: runs that reproduce the patterns of the seed papers, as data (a model name,
parameter values, a domain spec, an initial condition, the pattern class it should give).
``rdgpu presets`` lists them; ``rdgpu run MODEL --preset NAME`` runs one."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.backends.base import Backend
from rdgpu.domains.specs import build_domain as _build_any
from rdgpu.models.library import MODELS

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain

__all__ = ["PRESETS", "Preset", "build_domain"]


def build_domain(spec: Mapping[str, Any]) -> Domain:
    """A domain from a preset's dict (`rdgpu.domains.specs.build_domain`):
    ``{"grid": (ny, nx), "dx": 1.0, "bc": "periodic"}`` (``(nx,)`` 1-D, ``(nz, ny, nx)``
    3-D with ``"dz"``; ``"height"``: a graph surface), ``{"mesh": "sphere", "subdivisions":
    4, "radius": 1.0}``, ``{"mesh": "disc", "radius": 30, "rings": 50}`` (``"roughen"``:
    a rough copy), ``{"mesh": "path/to/file.obj"}``..."""
    return _build_any(spec)


# ---------------------------------------------------------------------------- presets
@dataclass
class Preset:
    """A run that reproduces a pattern from a seed paper.

    Attributes
    ----------
    name : str
        Its key in `PRESETS`.
    model : str
        A key of `MODELS`.
    params : dict
        Parameter values over the model's defaults: numbers or field specs
        (`param_field`).
    dt : float
        The time step (model time units).
    steps : int
        The run's length in steps (what ``Simulation.run()`` does without ``steps``).
    domain : dict
        A `build_domain` spec (e.g. ``{"grid": (300, 300), "dx": 1.0, "bc": "periodic"}``).
    init : dict
        The initial condition spec of the simulation driver.
    source : str
        The paper, section and figure it reproduces.
    expect : str
        The pattern class it should give (``"spots"``, ``"inverted-spots"``,
        ``"stripes"``, ``"uniform"`` — what `rdgpu.analysis.classify_pattern` measures —
        or ``"spirals"``, ``"chaos"``).
    snapshot_every : int
        Steps between the run's snapshots (default 0: the last state only).
    description : str
        What the run shows (default ``""``).
    classify : dict
        How to measure the class: ``field`` and ``threshold`` for ``classify_pattern``
        (default ``{}``).
    seed : int
        Seed of the initial condition's noise and of random parameter fields (default 0).
    options : dict
        Extra keyword arguments of ``model.stepper``, e.g. ``{"method": "imex"}``
        (default ``{}``).
    """

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

    def build_domain(self) -> Domain:
        return build_domain(self.domain)

    def get_model(self) -> Any:
        return MODELS[self.model]

    def stepper(self, *, backend: Backend | str | None = None, dtype: Any = np.float64,
                domain: Domain | None = None, seed: int | None = None, **kwargs) -> Any:
        """The preset's stepper (fields at zero: the driver sets the initial state).

        Parameters
        ----------
        backend : str or Backend, optional
            As `rdgpu.get_backend` takes it (default ``None``: the default backend).
        dtype : numpy dtype
            float64 (default) or float32.
        domain : Domain, optional
            Replaces the preset's domain (default ``None``: built from ``domain``).
        seed : int, optional
            Seed of random parameter fields (default ``None``: the preset's ``seed``).
        **kwargs
            More keyword arguments of the model's ``stepper`` (`Model.stepper`), over the
            preset's ``options``.

        Returns
        -------
        object
            The model's ``stepper`` bound to the domain with the preset's ``params`` and
            ``dt`` (a `rdgpu.integrators.ModelStepper` for a model of equations).
        """
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
    "gs-masked-disc", "gray-scott",
    {"Du": 0.16, "Dv": 0.08, "F": 0.035, "k": 0.060}, dt=1.0, steps=12000,
    domain={"grid": (256, 256), "dx": 1.0, "bc": "periodic"},
    init={"kind": "square", "values": {"u": 1.0, "v": 0.0}, "inside": {"u": 0.5, "v": 0.25},
          "size": 0.1, "noise": 0.05},
    source="Camphuijsen & Kasim 2016 §3 (the labyrinth's F, k) on a disc: a masked grid",
    expect="stripes", snapshot_every=1000, classify={"field": "v", "threshold": None},
    options={"mask": "(x - Lx/2)**2 + (y - Ly/2)**2 < (0.45*Lx)**2"},
    description="the labyrinth grown from a central square inside a disc cut from the grid "
    "by a mask (mask=): zero flux across its edge, where the stripes meet the wall at right "
    "angles; the corners outside stay as they started",
))
_add(Preset(
    "gs-differential-flow", "gray-scott-flow",
    {"Vx": 0.04, "Vy": 0.0}, dt=1.0, steps=20000,
    domain={"grid": (256, 256), "dx": 1.0, "bc": "periodic"},
    init={"kind": "square", "values": {"u": 1.0, "v": 0.0}, "inside": {"u": 0.5, "v": 0.25},
          "size": 0.1, "noise": 0.05},
    source="Rovinsky & Menzinger 1992 (differential-flow instability) on Pearson's "
    "Gray-Scott", expect="stripes", snapshot_every=500,
    classify={"field": "v", "threshold": None},
    description="the activator v drifts right at 0.04 cells a step (upwind advect): the "
    "labyrinth that F = 0.030, k = 0.060 grows isotropically lines up across the flow",
))
_add(Preset(
    "cahn-hilliard-coarsening", "cahn-hilliard",
    {"M": 1.0, "g": 1.0}, dt=0.02, steps=25000,
    domain={"grid": (256, 256), "dx": 1.0, "bc": "periodic"},
    init={"kind": "uniform", "values": {"u": 0.0}, "noise": 0.1},
    source="Cahn & Hilliard 1958 (py-pde's CahnHilliardPDE, interface width 1)",
    expect="stripes", snapshot_every=1000, classify={"field": "u", "threshold": 0.0},
    description="a noisy mixture at mean 0 separates into the phases ±1, a bicontinuous "
    "labyrinth that coarsens (t = 500); the mean of u stays 0 to round-off",
))
_add(Preset(
    "keller-segel-aggregates", "keller-segel",
    {"Du": 1.0, "Dv": 1.0, "chi": 6.0, "r": 1.0}, dt=0.005, steps=20000,
    domain={"grid": (256, 256), "dx": 0.25, "bc": "periodic"},
    init={"kind": "uniform", "values": {"u": 1.0, "v": 1.0}, "noise": 0.05},
    source="Keller & Segel 1970; Painter & Hillen 2011 (chemotaxis with logistic growth)",
    expect="inverted-spots", snapshot_every=1000, classify={"field": "u", "threshold": None},
    description="cells climb the gradient of the chemical they secrete (div(chi*u*grad(v))): "
    "the uniform state breaks into aggregates, kept apart by logistic growth",
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
# vertices, mean edge h = 0.0378).  The pattern depends on ε/h (examples/seed000_study.py,
# docs/seed000.md).  With ε ≪ h (the seed's regime: dt = 0.9 explicit means its edges were
# long compared with ε) the interfaces are pinned by the mesh: a discrete equilibrium
# reached within a few hundred ε², with interfaces under one vertex wide, that the
# continuous equation does not have.  That is what keeps these spots from shrinking away.
# Global patterns: ε = 0.15 h, dt = ε²/2, random data in [-1, 1]; measured: b = -0.25 spots,
# 0 stripes, +0.25 inverted spots, all frozen (u at step 9000 equals u at step 3000 to
# 4e-14, OpenCL float64); the field decays to a constant from |b| ≈ 0.30 (b = -0.28: 85
# spots; -0.30: uniform or a few spots by seed), below 2/(3√3) ≈ 0.385 where u³ − u + b
# loses its second stable root.
_AC_MESH = {"mesh": "sphere", "subdivisions": 5, "radius": 1.0}
_AC_EPS_GLOBAL = 0.0057
_AC_EPS_LOCAL = 0.0113
_AC_PINNED = ("pinned by the mesh: the interfaces are under one vertex wide and the field "
              "is frozen (identical at steps 3000 and 9000); with ε resolved (ε/h ≥ 0.5) ")
_AC_RESOLVED_FATE = {True: "the same b makes the field uniform within 1-10 ε²",
                     False: "b = 0 coarsens by curvature, uniform after 70-5000 ε² or later"}
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
            if _name == "uniform" else "; " + _AC_PINNED + _AC_RESOLVED_FATE[_b != 0]
            + " (docs/seed000.md)"),
    ))
# Localized patterns (Dascal et al. §4.2, Figs. 13-14): random data in a patch (0 elsewhere);
# ε = 0.3 h.  b = ±0.08: the favoured phase takes the rest of the sphere, the pattern stays
# in the patch; b = 0: u = 0 is an unstable equilibrium that the fronts invade everywhere.
# Also pinned: u at step 9000 equals u at step 3000 (interfaces 0.4-0.7 vertices wide).
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
            "the pattern stays in the patch") + "; pinned by the mesh (frozen: identical "
        "at steps 3000 and 9000)",
    ))
# Resolved patterns: icosphere(6) (40 962 vertices, h = 0.01889), ε = h (the interface
# tanh profile spans ~4 ε, several vertices), dt = 4.8e-5 (just under half the explicit
# limit 9.73e-5; ε²/2 would exceed it).  Measured (docs/seed000.md): with b = ∓0.05 the
# random data separate into stripes by 3 ε², break into spots by 4 ε² (~90 of them), and
# the spots then shrink and vanish one by one: uniform by ~25 ε² (~190 steps).  Resolved
# spots are transient for every b ≠ 0 measured; these presets stop at 8 ε² (60 steps),
# while 29 (b < 0) or 47 (b > 0) spots exist.  b = 0 coarsens by curvature (stripes to ~2000 ε²).
_AC_MESH_FINE = {"mesh": "sphere", "subdivisions": 6, "radius": 1.0}
_AC_EPS_RESOLVED = 0.0189
_AC_DT_RESOLVED = 4.8e-5
for _name, _b, _cls, _steps, _secs, _what in (
        ("resolved-spots", -0.05, "spots", 60, 0.03,
         "29 spots of u < 0 (seed 0), 2.5 vertices inside |u| < 0.9 per crossing edge"),
        ("resolved-inverted-spots", 0.05, "inverted-spots", 60, 0.03,
         "47 inverted spots (islands of u > 0, seed 0)"),
        ("resolved-stripes", 0.0, "stripes", 745, 0.2,
         "a few coarse bands of each phase (3 + 4 components), still coarsening")):
    _add(Preset(
        f"ac-sphere-{_name}", "allen-cahn", {"b": _b, "eps": _AC_EPS_RESOLVED},
        dt=_AC_DT_RESOLVED, steps=_steps, domain=dict(_AC_MESH_FINE),
        init={"kind": "uniform", "values": {"u": 0.0}, "noise": 1.0},
        source="Dascal et al. §4.1 with the interface resolved (docs/seed000.md)",
        expect=_cls, snapshot_every=max(_steps // 20, 1),
        classify={"field": "u", "threshold": 0.0},
        description=f"modified Allen-Cahn, b = {_b}, ε = {_AC_EPS_RESOLVED} (1.0 mean edge of "
        f"icosphere(6)), random data in [-1, 1]; at step {_steps} "
        f"(t = {_steps * _AC_DT_RESOLVED / _AC_EPS_RESOLVED**2:.0f} ε²; {_secs} s of stepping "
        f"on OpenCL on a 2-core CPU, 1.5-2 s for the whole CLI run): {_what}. " + (
            "Transient: the spots shrink and the field is uniform by ~25 ε² (~190 steps)"
            if _b != 0 else "Transient: curvature flow makes it uniform by ~2000 ε²"),
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
    "brusselator-noise", "brusselator", {"Du": 2.0, "Dv": 22.0, "a": 5.0, "b": 9.0},
    dt=0.005, steps=8000, domain={"grid": (256, 256), "dx": 1.0, "bc": "periodic"},
    init={"kind": "uniform", "values": {"u": 5.0, "v": 1.8}},
    source="Quillen 2025 §1.1 (the Brusselator); Itô noise as py-pde's noise=",
    expect="stripes", snapshot_every=1000, classify={"field": "u", "threshold": None},
    options={"noise": {"u": 1e-4}},
    description="from the exact homogeneous steady state (u, v) = (a, b/a), which no "
    "deterministic run leaves: additive noise on u (variance 1e-4, Euler-Maruyama) starts "
    "the Turing instability",
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

# --- Chattopadhyay: Turing's 1-D model (eq. 2.14, Fig. 2.3): a ring of 60 cells
_add(Preset(
    "turing-seed003-1d", "turing",
    {"Du": 0.25, "Dv": 0.0625, "s": 0.03125,
     "beta": {"kind": "random", "low": 11.95, "high": 12.05}},
    dt=1.0, steps=20000, domain={"grid": (60,), "dx": 1.0, "bc": "periodic"},
    init={"kind": "uniform", "values": {"u": 4.0, "v": 4.0}},
    source="Chattopadhyay eq. 2.14, Fig. 2.3 (after Turing 1952, Turk 1991)",
    expect="stripes", snapshot_every=500, classify={"field": "v", "threshold": None},
    description="a line of 60 cells closed into a ring (Turing's 1952 set-up), a = b = 4, "
    "β = 12 ± 0.05, s = 1/32, D_a = 0.25, D_b = 0.0625, one step per iteration (dt = 1) as "
    "in the seed: b forms 7 peaks by step 4000 (the figure's first frame) that stay put "
    "through step 20 000 (its last); 7 is the least stable mode of the ring "
    "(rdgpu.analysis.dispersion: m = 7, wavelength 60/7 ≈ 8.6 cells)",
))

# --- Chattopadhyay: Meinhardt's five-chemical stripes (eq. 2.16) on 80², periodic
_MEINHARDT_REST = {"g1": 0.775, "g2": 0.775, "r": 0.1601667, "s1": 0.8, "s2": 0.8}
_add(Preset(
    "meinhardt-seed003-rings", "meinhardt-stripes", {}, dt=1.0, steps=20000,
    domain={"grid": (80, 80), "dx": 1.0, "bc": "periodic"},
    init={"kind": "square", "values": dict(_MEINHARDT_REST), "inside": {"g1": 0.8},
          "size": 0.05},
    source="Chattopadhyay eq. 2.16, Fig. 2.5; Meinhardt 1982; parameters of Turk 1991",
    expect="stripes", snapshot_every=500, classify={"field": "g1", "threshold": None},
    description="a small perturbation at the centre (g1 raised by 0.025 in 4 × 4 cells) "
    "of the homogeneous state: stripes of g1 and g2 alternate in concentric rings that "
    "fill the 80² grid and then stay put",
))
_add(Preset(
    "meinhardt-seed003-random", "meinhardt-stripes", {}, dt=1.0, steps=30000,
    domain={"grid": (80, 80), "dx": 1.0, "bc": "periodic"},
    init={"kind": "uniform", "values": dict(_MEINHARDT_REST), "noise": {"g1": 0.01}},
    source="Chattopadhyay eq. 2.16, Fig. 2.6; Meinhardt 1982; parameters of Turk 1991",
    expect="stripes", snapshot_every=500, classify={"field": "g1", "threshold": None},
    description="random noise (±0.01 in g1) everywhere: a labyrinth of alternating g1 and "
    "g2 stripes, formed by ~5000 steps, then a few local rearrangements (under 1 % of the "
    "cells change after 15 000 steps)",
))

# --- Quillen 2025: complex Ginzburg-Landau (§4, eq. 62), A = u + iv from small noise.
# Measured with rdgpu.analysis.phase_defects (vortices of the phase of u + iv): at the
# seed's b1 = 0, b3 = 0.56 (α = 0, β = −1/b3 ≈ −1.79 in eq. 61) spirals form and break up
# again, a statistically steady spiral-defect turbulence (71-105 defects per 128², under
# 10 % of them found again 50 time units later); at b3 = 1 the spirals freeze (24-26
# defects per 128² that stay put from t ~ 200); past the Benjamin-Feir line (b1 > b3) the
# phase turbulence is full of defects (134-168 per 128²).  At the presets' 200², t = 500:
# 217, 52 and 332 defects.
_CGL_INIT = {"kind": "uniform", "values": {"u": 0.0, "v": 0.0}, "noise": 0.1}
_CGL_CLASSIFY = {"fields": ["u", "v"], "center": [0.0, 0.0]}
_add(Preset(
    "cgl-seed004-fig12", "complex-ginzburg-landau", {"b1": 0.0, "b3": 0.56},
    dt=0.1, steps=5000, domain={"grid": (200, 200), "dx": 1.0, "bc": "neumann"},
    init=dict(_CGL_INIT), source="Quillen 2025 §4, eq. 62, Fig. 12", expect="spirals",
    snapshot_every=100, classify=dict(_CGL_CLASSIFY),
    description="the seed's b1 = 0, b3 = 0.56 with Neumann sides (Fig. 12 is on a mesh "
    "with a Neumann boundary): amplitude holes at the phase defects, spirals that keep "
    "breaking up and forming (spiral-defect turbulence; measured: the number of defects "
    "fluctuates around a steady mean and the defects move)",
))
_add(Preset(
    "cgl-frozen-spirals", "complex-ginzburg-landau", {"b1": 0.0, "b3": 1.0},
    dt=0.1, steps=5000, domain={"grid": (200, 200), "dx": 1.0, "bc": "periodic"},
    init=dict(_CGL_INIT), source="Quillen 2025 §4, eq. 62; Chaté & Manneville 1996 "
    "(frozen states)", expect="spirals", snapshot_every=100, classify=dict(_CGL_CLASSIFY),
    description="b1 = 0, b3 = 1 (α = 0, β = −1): spirals whose cores stop moving once "
    "their shock lines meet (a 'vortex glass'); measured: the defects stop moving by t ~ 100",
))
_add(Preset(
    "cgl-defect-turbulence", "complex-ginzburg-landau", {"b1": 2.0, "b3": 0.5},
    dt=0.04, steps=10000, domain={"grid": (200, 200), "dx": 1.0, "bc": "periodic"},
    init=dict(_CGL_INIT), source="Quillen 2025 §4, eqs. 62, 69; Aranson & Kramer 2002 "
    "(defect turbulence)", expect="spirals", snapshot_every=100,
    classify=dict(_CGL_CLASSIFY),
    description="b1 = 2, b3 = 0.5 (α = 2, β = −2: 1 + αβ = −3, Benjamin-Feir unstable): "
    "defect turbulence, ~150 defects per 128² created and annihilated in pairs; dt below "
    "the explicit limit dx²/(4(1 + b1²)) = 0.05 of the cross-diffusion",
))

# --- Quillen 2025: Swift-Hohenberg (§5, eqs. 71-73) on a periodic square of 16 wavelengths
# (128² cells of dx = π/4: eight per wavelength 2π), implicit (IMEX) steps of dt = 0.5, 35×
# the explicit limit 0.0141 of the bilaplacian
_SH_DOMAIN = {"grid": (128, 128), "dx": 3.141592653589793 / 4, "bc": "periodic"}
_add(Preset(
    "sh-seed004-stripes", "swift-hohenberg", {"r": 0.2, "g": 0.0}, dt=0.5, steps=1000,
    domain=dict(_SH_DOMAIN), init={"kind": "uniform", "values": {"u": 0.0}, "noise": 0.1},
    source="Quillen 2025 §5, eq. 73, Fig. 13 (r = 0.2, γ_u = 0)", expect="stripes",
    snapshot_every=20, classify={"field": "u", "threshold": 0.0},
    options={"method": "imex"},
    description="random data grow into a labyrinth of stripes of wavenumber k ≈ 1 (the "
    "peak of σ = r − (1 − k²)²); the seed's figure is a disk with a natural boundary, "
    "here a periodic square",
))
_add(Preset(
    "sh-hexagons", "swift-hohenberg", {"r": 0.1, "g": 1.0}, dt=0.5, steps=1000,
    domain=dict(_SH_DOMAIN), init={"kind": "uniform", "values": {"u": 0.0}, "noise": 0.1},
    source="Quillen 2025 §5, eq. 73 (quadratic term γ_u = 1)", expect="inverted-spots",
    snapshot_every=20, classify={"field": "u", "threshold": 0.0},
    options={"method": "imex"},
    description="the quadratic term breaks u ↔ −u: a hexagonal lattice of u > 0 spots "
    "(compact islands of high u: classify_pattern's 'inverted-spots') of spacing "
    "4π/√3 ≈ 7.3 (k = 1)",
))

# --- Quillen 2025 Fig. 7: Gray-Scott with F (α) varying along x and k (β) along y
_add(Preset(
    "gs-seed004-fig7", "gray-scott",
    {"Du": 0.2, "Dv": 0.1, "F": "0.037 + 0.0185*sin(2*pi*x/Lx)",
     "k": "0.06 + 0.0075*sin(2*pi*y/Ly)"},
    dt=1.0, steps=20000, domain={"grid": (400, 400), "dx": 1.0, "bc": "periodic"},
    init={"kind": "spots", "values": {"u": 1.0, "v": 0.0}, "inside": {"u": 0.5, "v": 0.25},
          "count": 40, "radius": 4},
    source="Quillen 2025 Fig. 7 (α_m = 0.037 ± α_m/2 horizontally, β_m = 0.06 ± β_m/8 "
    "vertically, Du = 0.2, Dv = Du/2, n = 400, dx = dt = 1, periodic)",
    expect="inverted-spots",
    snapshot_every=500, classify={"field": "v", "threshold": None},
    description="F and k given as expressions of x and y (F high at the left, k high at "
    "the top): v fills the quarter where F is high and k low (99 % of it above 0.1), worms "
    "and spots cover 37 % and 62 % of the two mixed quarters, and sparse spots 13 % of the "
    "quarter where F is low and k high; the whole field classifies as 'inverted-spots'. "
    "40 seeds of (u, v) = (0.5, 0.25) (the seed suggests 'a few pixels set to high "
    "values' of v; v = 1 blows up with dt = 1)",
))

# --- Gray-Scott in 3-D: 64³ periodic cells of dx = 1, Du = 0.16, Dv = 0.08, dt = 0.5.  The
# 7-point diffusion limit is 1/(2·0.16·3) ≈ 1.04, but at dt = 1 the checkerboard mode of u
# is amplified by 1 − 12·0.16 − (v² + F) < −1 where v is high: u grows a grid-scale
# checkerboard (amplitude 0.08 measured); dt = 0.5 keeps it at round-off
_add(Preset(
    "gs-3d-labyrinth", "gray-scott", {"Du": 0.16, "Dv": 0.08, "F": 0.035, "k": 0.060},
    dt=0.5, steps=24000, domain={"grid": (64, 64, 64), "dx": 1.0, "bc": "periodic"},
    init={"kind": "square", "values": {"u": 1.0, "v": 0.0}, "inside": {"u": 0.5, "v": 0.25},
          "size": 0.2, "noise": 0.05},
    source="Camphuijsen & Kasim 2016 §3 parameters (their 2-D stripes) on a 3-D grid",
    expect="stripes", snapshot_every=500, classify={"field": "v", "threshold": None},
    description="the central cube grows into a labyrinth of sheets: both phases (v above "
    "and below its midrange) one connected region each, v high in 39 % of the cells, and "
    "every plane through the box cuts the sheets into stripes",
))
_add(Preset(
    "gs-3d-blobs", "gray-scott", {"Du": 0.16, "Dv": 0.08, "F": 0.030, "k": 0.068},
    dt=0.5, steps=24000, domain={"grid": (64, 64, 64), "dx": 1.0, "bc": "periodic"},
    init={"kind": "spots", "values": {"u": 1.0, "v": 0.0}, "inside": {"u": 0.5, "v": 0.25},
          "count": 10, "radius": 3},
    source="Gray-Scott near the edge of Pearson 1993's self-replicating spots (F = 0.030, "
    "k = 0.068, chosen here by measurement) on a 3-D grid", expect="inverted-spots",
    snapshot_every=500, classify={"field": "v", "threshold": None},
    description="ten seed balls divide (3-D 'mitosis') until round blobs of high v, about "
    "8 cells across, fill the box at one blob per ~2100 cells and stop dividing (measured: "
    "120 blobs at 64³ from ~15 000 steps, v high in 10 % of the cells, the low phase one "
    "connected sea, a few blobs stretched into short worms); at F = 0.026, k = 0.061 "
    "(Pearson's λ) the blobs instead keep growing into shells and breaking up",
))

# --- Quillen 2025 §6 (Fig. 13): Swift-Hohenberg on a triangulated disc, natural boundary
_add(Preset(
    "swift-hohenberg-disc", "swift-hohenberg", {"r": 0.2, "g": 0.0},
    dt=0.5, steps=600, domain={"mesh": "disc", "radius": 30.0, "rings": 50},
    init={"kind": "uniform", "values": {"u": 0.0}, "noise": 0.1},
    source="Quillen 2025 §6, eq. 73, Fig. 13 (r = 0.2, γ_u = 0, a disc with the natural "
    "(Neumann) boundary)", expect="stripes", snapshot_every=50,
    classify={"field": "u", "threshold": 0.0},
    # the disc is in the model's lengths (its wavelength 2π), not in cells of π/4
    options={"method": "imex", "lengths": "model"},
    description="a disc of radius 30 (about 10 wavelengths 2π across; 7651 vertices, edges "
    "≈ 0.67, SurfaceMesh.disc) from small noise: stripes of wavelength 2π that meet the "
    "boundary at right angles, with a few defects, by t = 300",
))

# --- seed 002 §5 (Fig. 14 b): a pattern on a closed rough surface (heat-filtered sphere)
_add(Preset(
    "gray-scott-rough-sphere", "gray-scott", {"Du": 0.16, "Dv": 0.08, "F": 0.035, "k": 0.065},
    dt=1.0, steps=15000,
    domain={"mesh": "sphere", "subdivisions": 5, "radius": 25.0,
            "roughen": {"amplitude": 1.5, "filter_steps": 6, "seed": 3}},
    init={"kind": "spots", "values": {"u": 1.0, "v": 0.0}, "inside": {"u": 0.5, "v": 0.25}},
    source="Rough closed surfaces by random nodal values and heat filters (seed 002 §5, "
    "Fig. 14 b); Gray-Scott spots (Pearson 1993)", expect="inverted-spots",
    snapshot_every=500, classify={"field": "v", "threshold": None},
    description="a sphere of radius 25 (icosphere(5), 10 242 vertices) roughened by "
    "SurfaceMesh.roughen (bumps up to 1.5 along the normals, 6 heat-filter steps): "
    "seeded spots of high v divide until they tile the bumpy surface",
))

# --- seed 002 §4.3 (Fig. 12): animal coats on random-wave surfaces, BVAM spots and stripes
# on the square [0, 2)² (128², periodic), the seed's dt = 0.5 and run lengths; amplitude
# 0.1 of the side is the seed's "scale 0.1" (docs/data/seed002_roughness.md)
_BVAM_INIT = {"kind": "uniform", "values": {"u": 0.0, "v": 0.0}, "noise": 0.5}
_BVAM_STRIPES = {"r1": 3.5, "r2": 0.0}


def _rough_square(amplitude: float, frequency: tuple[int, int], seed: int = 3) -> dict:
    return {"grid": (128, 128), "dx": 2.0 / 128, "height": {
        "kind": "random-waves", "amplitude": amplitude, "max_frequency": list(frequency),
        "seed": seed}}


for _name, _what, _amp, _freq, _coat in (
        ("bvam-cheetah", "spots", 0.2, (5, 15), "cheetah (Fig. 12 d: spots, M = 5, N = 15, "
         "scale 0.1)"),
        ("bvam-genet", "spots", 0.1, (15, 15), "genet (Fig. 12 b: spots, M = N = 15; "
         "at the seed's scale 0.1 the steepest slopes leave under 3 cells per wavelength at "
         "128², so scale 0.05)"),
        ("bvam-angelfish", "stripes", 0.1, (5, 5), "emperor angelfish (Fig. 12 a: stripes, "
         "M = N = 5, scale 0.05)")):
    _add(Preset(
        _name, "bvam", dict(_BVAM_STRIPES) if _what == "stripes" else {},
        dt=0.5, steps=1600 if _what == "spots" else 4000, domain=_rough_square(_amp, _freq),
        init=dict(_BVAM_INIT), options={"method": "imex"},
        source="Seed 002 §4.3, Fig. 12; BVAM (Barrio et al. 1999)",
        expect="inverted-spots" if _what == "spots" else "stripes", snapshot_every=200,
        classify={"field": "u", "threshold": None},
        description=f"the {_coat}: BVAM {_what} on the random-wave surface of max|h| = "
        f"{_amp:g} (the side is 2; rdgpu.surfaces.random_waves, seed 3), shown on the "
        "parameter plane; irregular where the surface is steep (docs/data/"
        "seed002_roughness.md measures how)",
    ))
