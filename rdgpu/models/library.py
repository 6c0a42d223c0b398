"""The built-in models, each its equations (py-pde's spelling) and the defaults and run
settings of the papers it comes from (README, References).  New models are added the same
way, here or in a user's script with :func:`rdgpu.define_model`."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .allen_cahn import AllenCahn
from .model import Model

__all__ = ["MODELS"]


def _cbrt(x: float) -> float:
    return math.copysign(abs(x) ** (1.0 / 3.0), x)


GRAY_SCOTT = Model(
    "gray-scott",
    # u*v*v, not u*v**2 (= u*(v*v)): the operation order of the hand-written kernel
    # (kernels/gray_scott), so the two agree bit for bit
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

ALLEN_CAHN = AllenCahn()

#: every model by its command-line name
MODELS: dict[str, Any] = {
    m.name: m
    for m in (GRAY_SCOTT, ALLEN_CAHN, BRUSSELATOR, FITZHUGH_NAGUMO, SCHNAKENBERG, BARKLEY,
              TURING)
}
