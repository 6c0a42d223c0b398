"""The built-in models, each its equations (py-pde's spelling) and the defaults and run
settings of the papers it comes from (README, References).  New models are added the same
way, here or in a user's script with `rdgpu.define_model`."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from rdgpu.models.allen_cahn import AllenCahn
from rdgpu.models.model import Model

__all__ = ["MODELS"]


def _cbrt(x: float) -> float:
    return math.copysign(abs(x) ** (1.0 / 3.0), x)


def _meinhardt_steady(p) -> tuple[float, ...]:
    """The homogeneous state of the stripe model: g = (β/2 + ρ0)/α, s = g + ρ1/γ,
    r = 2c s g²/β."""
    g = (0.5 * p["beta"] + p["rho0"]) / p["alpha"]
    s = g + p["rho1"] / p["gamma"]
    return (g, g, 2.0 * p["c"] * s * g * g / p["beta"], s, s)


GRAY_SCOTT = Model(
    "gray-scott",
    # u*v*v, not u*v**2 (= u*(v*v)): the operation order of the hand-written kernel
    # (rdgpu/families/gray_scott), so the two agree bit for bit
    {"u": "Du*laplace(u) - u*v*v + F*(1 - u)",
     "v": "Dv*laplace(v) + u*v*v - (F + k)*v"},
    {"Du": 0.16, "Dv": 0.08, "F": 0.035, "k": 0.060},
    description="Gray-Scott u_t = Du Δu − uv² + F(1 − u), v_t = Dv Δv + uv² − (F + k)v",
    source="Camphuijsen & Kasim 2016; Pearson 1993; equations §3",
    steady_guess=lambda p: (1.0, 0.0),
    default_dt=1.0, default_time=10000.0,
    # v stays below ~0.5 in every pattern-forming regime: [0, 0.5] keeps the contrast while a
    # field that decayed to uniform (u = 1, v = 0) still shows as uniform
    value_range={"u": (0.0, 1.0), "v": (0.0, 0.5)},
)

GRAY_SCOTT_FLOW = Model(
    "gray-scott-flow",
    {"u": "Du*laplace(u) - u*v*v + F*(1 - u)",
     "v": "Dv*laplace(v) + u*v*v - (F + k)*v - advect(v, Vx, Vy)"},
    {"Du": 0.2, "Dv": 0.1, "F": 0.030, "k": 0.060, "Vx": 0.04, "Vy": 0.0},
    description="Gray-Scott with the activator v carried by a uniform flow (Vx, Vy), "
    "upwinded: u_t = Du Δu − uv² + F(1 − u), v_t = Dv Δv + uv² − (F + k)v − V·∇v. The "
    "differential flow lines the labyrinth up across the flow; at V = 0 it is isotropic",
    source="Rovinsky & Menzinger 1992 (differential-flow instability); Pearson 1993",
    steady_guess=lambda p: (1.0, 0.0),
    default_dt=1.0, default_time=20000.0,
    value_range={"u": (0.0, 1.0), "v": (0.0, 0.5)},
)

BRUSSELATOR = Model(
    "brusselator",
    {"u": "Du*laplace(u) + a - (b + 1)*u + u**2*v",
     "v": "Dv*laplace(v) + b*u - u**2*v"},
    {"Du": 2.0, "Dv": 22.0, "a": 5.0, "b": 9.0},
    description="Brusselator u_t = Du Δu + a − (b+1)u + u²v, v_t = Dv Δv + bu − u²v "
    "(Quillen's α, β are a, b); Turing unstable for b > (1 + a√(Du/Dv))²",
    source="Quillen 2025 §1.1, Fig. 1; equations §3",
    steady_guess=lambda p: (p["a"], p["b"] / p["a"]),
    default_dt=0.005, default_time=100.0,
)

FITZHUGH_NAGUMO = Model(
    "fitzhugh-nagumo",
    {"u": "Du*laplace(u) + u - u**3 - v + alpha",
     "v": "Dv*laplace(v) + beta*(u - v)"},
    {"Du": 1.0, "Dv": 10.0, "alpha": 0.01, "beta": 1.0},
    description="FitzHugh-Nagumo u_t = Du Δu + u − u³ − v + α, v_t = Dv Δv + β(u − v)",
    source="Quillen 2025 §1.8, Fig. 8; equations §3",
    steady_guess=lambda p: (_cbrt(p["alpha"]), _cbrt(p["alpha"])),
    default_dt=0.01, default_time=200.0,
)

SCHNAKENBERG = Model(
    "schnakenberg",
    {"u": "Du*laplace(u) + a - u + u**2*v",
     "v": "Dv*laplace(v) + b - u**2*v"},
    {"Du": 1.0, "Dv": 40.0, "a": 0.1, "b": 0.9},
    description="Schnakenberg u_t = Du Δu + a − u + u²v, v_t = Dv Δv + b − u²v; steady "
    "state u = a + b, v = b/(a + b)²",
    source="Schnakenberg 1979; equations §3",
    steady_guess=lambda p: (p["a"] + p["b"], p["b"] / (p["a"] + p["b"]) ** 2),
    default_time=100.0,
)

BVAM = Model(
    "bvam",
    {"u": "D*delta*laplace(u) + alpha*u*(1 - r1*v*v) + v*(1 - r2*u)",
     "v": "delta*laplace(v) + beta*v*(1 + alpha*r1/beta*u*v) + u*(gamma + r2*v)"},
    {"D": 0.516, "delta": 6.6e-4, "alpha": 0.899, "beta": -0.91, "gamma": -0.899,
     "r1": 0.02, "r2": 0.2},
    description="BVAM (Barrio, Varea, Aragón & Maini 1999) about the steady state (0, 0): "
    "u_t = Dδ Δu + αu(1 − r1 v²) + v(1 − r2 u), v_t = δ Δv + βv(1 + (α r1/β) uv) + "
    "u(γ + r2 v); spots for r1 = 0.02, r2 = 0.2 (the quadratic term wins), stripes for "
    "r1 = 3.5, r2 = 0 (cubic only). δ = 6.6e-4 puts the fastest linear mode at wavelength "
    "0.256: about 8 across the square [0, 2)² of seed 002's experiments",
    source="Barrio et al. 1999 (Bull. Math. Biol. 61); Li & Ling 2020 (seed 002 ref. 31); "
    "seed 002 §4",
    steady_guess=lambda p: (0.0, 0.0),
    spacing=2.0 / 128, default_dt=0.5, default_time=800.0, default_method="imex",
)

BARKLEY = Model(
    "barkley",
    {"u": "Du*laplace(u) + u*(1 - u)*(u - (v + b)/a)/eps",
     "v": "u - v"},
    {"Du": 1.0, "a": 0.75, "b": 0.02, "eps": 0.02},
    description="Barkley u_t = Du Δu + u(1 − u)(u − (v + b)/a)/ε, v_t = u − v (v does not "
    "diffuse): excitable medium, spirals. Stiff: explicit Euler also needs dt ≲ ε",
    source="Quillen 2025 §1.9, eq. 51; Barkley 1991; equations §3",
    steady_guess=lambda p: (0.0, 0.0),
    spacing=0.5, default_dt=lambda p: 0.5 * float(np.max(p["eps"])), default_time=200.0,
    value_range={"u": (0.0, 1.0), "v": (0.0, 1.0)},
    # an excited half meeting a refractory half: a broken wave that curls into spirals
    # (random excitations, as in the preset, die out on small domains)
    default_init={"kind": "halves", "values": {"u": 0.0, "v": 0.0}, "x_low": {"u": 1.0},
                  "y_low": {"v": 0.5}},
)

TURING = Model(
    "turing",
    {"u": "Du*laplace(u) + s*(16 - u*v)",
     "v": "Dv*laplace(v) + s*(u*v - v - beta)"},
    {"Du": 0.25, "Dv": 0.0625, "s": 0.05, "beta": 12.0},
    description="Turing's 1952 spot model as in Chattopadhyay eq. 2.15 (u = a, v = b): "
    "u_t = Du Δu + s(16 − uv), v_t = Dv Δv + s(uv − v − β); β is usually a random field "
    "12 ± 0.1; steady state u = 16/(16 − β), v = 16 − β; v is clamped at 0 after each "
    "step (as in Turk 1991; without it v goes negative and the run blows up)",
    source="Chattopadhyay (Chattopadhyay) eq. 2.15, after Turing 1952 / Turk 1991; equations §3",
    steady_guess=lambda p: (16.0 / (16.0 - p["beta"]), 16.0 - p["beta"]),
    bounds={"v": (0.0, None)},
    default_dt=0.5, default_time=4000.0,
    # u = v = 4 is (just) linearly stable at β = 12: the spots grow from β's randomness
    default_fields={"beta": {"kind": "random", "low": 11.9, "high": 12.1}},
)

COMPLEX_GINZBURG_LANDAU = Model(
    "complex-ginzburg-landau",
    # A = u + iv in Chaté & Manneville's form A_t = A + (1 + i b1)ΔA − (b3 − i)|A|²A:
    # the real and imaginary parts, coupled by cross-diffusion through b1
    {"u": "u + laplace(u) - b1*laplace(v) - (u**2 + v**2)*(b3*u + v)",
     "v": "v + b1*laplace(u) + laplace(v) - (u**2 + v**2)*(b3*v - u)"},
    {"b1": 0.0, "b3": 0.56},
    description="complex Ginzburg-Landau A_t = A + (1 + i b1)ΔA − (b3 − i)|A|²A for "
    "A = u + iv (Quillen's eq. 62, Chaté & Manneville's form): u_t = u + Δu − b1 Δv − "
    "|A|²(b3 u + v), v_t = v + b1 Δu + Δv − |A|²(b3 v − u). Rescaling A by √b3 gives "
    "eq. 61, A_t = A + (1 + iα)ΔA − (1 + iβ)|A|²A, with α = b1, β = −1/b3 (eq. 69); the "
    "uniform oscillation |A|² = 1/b3 is Benjamin-Feir unstable for b1 > b3",
    source="Quillen 2025 §4, eqs. 60-69, Fig. 12 (b1 = 0, b3 = 0.56); Chaté & Manneville "
    "1996; Aranson & Kramer 2002",
    steady_guess=lambda p: (0.0, 0.0),
    # explicit Euler on the 5-point grid: dt ≤ dx²/(4(1 + b1²)) from the cross-diffusion
    default_dt=lambda p: 0.16 / (1.0 + float(np.max(np.abs(p["b1"]))) ** 2),
    # and 0.65 of the limit anywhere: Euler's growth of the rotation |A|²iA with the fastest
    # diffusion modes diverged at 0.7 (grid, dx = 1; the disc mesh) and 0.9 (a 3-D grid)
    dt_share=0.65,
    default_time=500.0,
    value_range={"u": (-1.5, 1.5), "v": (-1.5, 1.5)},
    default_init={"kind": "uniform", "values": {"u": 0.0, "v": 0.0}, "noise": 0.1},
)

SWIFT_HOHENBERG = Model(
    "swift-hohenberg",
    # (1 + Δ)²u = u + 2Δu + ΔΔu
    {"u": "(r - 1)*u - 2*laplace(u) - laplace(laplace(u)) + g*u**2 - u**3"},
    {"r": 0.2, "g": 0.0},
    description="Swift-Hohenberg u_t = r u − (1 + Δ)²u + g u² − u³, written as "
    "(r − 1)u − 2Δu − ΔΔu + g u² − u³; the most unstable wavenumber is k_c = 1 "
    "(σ = r − (1 − k²)², eq. 72); stripes for g = 0, hexagons with a quadratic term "
    "(g ≈ 1, r small). Stiff: run it with method 'imex' (the bilaplacian implicit)",
    source="Quillen 2025 §5, eqs. 71-73, Fig. 13 (r = 0.2, γ_u = 0); Swift & Hohenberg "
    "1977",
    steady_guess=lambda p: (0.0,),
    # eight cells per wavelength 2π
    spacing=math.pi / 4, default_dt=0.5, default_time=500.0, default_method="imex",
    value_range={"u": (-1.0, 1.0)},
    default_init={"kind": "uniform", "values": {"u": 0.0}, "noise": 0.1},
)

MEINHARDT_STRIPES = Model(
    "meinhardt-stripes",
    # g1, g2: two self-enhancing loops that share the inhibitor r; s1 (made where g1 is)
    # helps g2 and s2 helps g1 nearby, so that g1 and g2 regions alternate in stripes
    {"g1": "Dg*laplace(g1) + c*s2*g1**2/r - alpha*g1 + rho0",
     "g2": "Dg*laplace(g2) + c*s1*g2**2/r - alpha*g2 + rho0",
     "r": "c*s2*g1**2 + c*s1*g2**2 - beta*r",
     "s1": "Ds*laplace(s1) + gamma*(g1 - s1) + rho1",
     "s2": "Ds*laplace(s2) + gamma*(g2 - s2) + rho1"},
    {"Dg": 0.009, "Ds": 0.2, "c": 0.01, "alpha": 0.04, "beta": 0.06, "gamma": 0.04,
     "rho0": 0.001, "rho1": 0.001},
    description="Meinhardt's five-chemical stripe model (Chattopadhyay eq. 2.16): "
    "g1_t = Dg Δg1 + c s2 g1²/r − α g1 + ρ0, g2_t = Dg Δg2 + c s1 g2²/r − α g2 + ρ0, "
    "r_t = c s2 g1² + c s1 g2² − β r, s1_t = Ds Δs1 + γ(g1 − s1) + ρ1, "
    "s2_t = Ds Δs2 + γ(g2 − s2) + ρ1 (the seed prints r_t with a minus sign and its "
    "parameter list is garbled). Parameters: those of Turk's implementation of the model "
    "(c = 0.01, α = 0.04, β = 0.06, γ = 0.04, Dg = 0.009, Ds = 0.2, dt = dx = 1) with the "
    "seed's basal productions ρ0 = ρ1 = 0.001 (without them the stripes never settle); "
    "homogeneous state g1 = g2 = (β/2 + ρ0)/α = 0.775, s1 = s2 = g + ρ1/γ = 0.8, "
    "r = 2c s g²/β = 0.16017",
    source="Meinhardt 1982 (Models of Biological Pattern Formation, ch. 12) via Turk 1991 "
    "(SIGGRAPH '91) and his stripes code; Chattopadhyay eq. 2.16, Figs. 2.5-2.6",
    steady_guess=lambda p: _meinhardt_steady(p),
    default_dt=1.0, default_time=20000.0,
    default_init={"kind": "uniform", "values": {"g1": 0.775, "g2": 0.775, "r": 0.1601667,
                                                "s1": 0.8, "s2": 0.8},
                  "noise": {"g1": 0.01}},
)

ALLEN_CAHN = AllenCahn()

#: every model by its command-line name
CAHN_HILLIARD = Model(
    "cahn-hilliard",
    {"u": "M*laplace(u**3 - u - g*laplace(u))"},
    {"M": 1.0, "g": 1.0},
    description="Cahn-Hilliard phase separation u_t = M Δμ, μ = u³ − u − γΔu (the "
    "chemical potential stored by a pre-pass each step): from a noisy mixture at mean 0 "
    "the two phases ±1 separate into a labyrinth that coarsens as t^(1/3); mass is "
    "conserved",
    source="Cahn & Hilliard 1958; py-pde's CahnHilliardPDE (interface_width = γ)",
    steady_guess=lambda p: (0.0,),
    default_dt=0.02, default_time=400.0,
    value_range={"u": (-1.0, 1.0)},
    default_init={"kind": "uniform", "values": {"u": 0.0}, "noise": 0.1},
)

KELLER_SEGEL = Model(
    "keller-segel",
    {"u": "Du*laplace(u) - div(chi*u*grad(v)) + r*u*(1 - u)",
     "v": "Dv*laplace(v) + u - v"},
    {"Du": 1.0, "Dv": 1.0, "chi": 6.0, "r": 1.0},
    description="chemotaxis with logistic growth u_t = Du Δu − ∇·(χ u ∇v) + r u(1 − u), "
    "v_t = Dv Δv + u − v: cells u climb the gradient of the chemical v they secrete "
    "(the flux in divergence form, face-averaged); aggregates form where χ > "
    "(√(Du r) + √Dv)², held apart by the growth term",
    source="Keller & Segel 1970; Painter & Hillen 2011 (logistic chemotaxis)",
    steady_guess=lambda p: (1.0, 1.0),
    spacing=0.25, default_dt=0.005, default_time=100.0,
    value_range={"u": (0.0, 3.0), "v": (0.0, 2.0)},
    default_init={"kind": "uniform", "values": {"u": 1.0, "v": 1.0}, "noise": 0.05},
)

MODELS: dict[str, Any] = {
    m.name: m
    for m in (GRAY_SCOTT, GRAY_SCOTT_FLOW, ALLEN_CAHN, BRUSSELATOR, FITZHUGH_NAGUMO,
              SCHNAKENBERG, BVAM, BARKLEY, TURING, COMPLEX_GINZBURG_LANDAU, SWIFT_HOHENBERG,
              MEINHARDT_STRIPES, CAHN_HILLIARD, KELLER_SEGEL)
}
