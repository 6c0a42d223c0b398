"""Linear stability of the schemes of `rdgpu.ir.schemes.SCHEMES`: the largest
stable step for the linear spatial part of a model (`rdgpu.models.Model.dt_limit`).

A Fourier mode with ``−Δ`` eigenvalue ``m`` evolves with ``A(m) = −m D + m² B`` (``D``, ``B``
the coefficient matrices of ``laplace`` and ``laplace(laplace(·))``); the limit is the
largest step for which every mode that decays in the equations also decays in the scheme,
``0 < m <= m_max``.  Explicit schemes: forward Euler's bound ``min −2 Re λ/|λ|²`` over the
eigenvalues of ``A(m)``, which every registered Runge-Kutta scheme keeps (the stability
regions of Heun, SSP-RK3 and classic RK4 contain Euler's disk); Adams-Bashforth 2's
region is smaller: the largest ``h`` whose two-level recursion has its roots in the unit
disk for every eigenvalue (half of Euler's for a real spectrum).  IMEX schemes: the spectral
radius of the scheme's amplification matrix (`_amplification`), found by bisection;
SBDF2's is the companion matrix of its two-level recursion.  Exponential schemes
(``etdrk4``) integrate the linear part exactly: no limit (``inf``).

First derivatives (advection) add the advective CFL (`advective_rate`, `with_advection`):
a term ``c·∂s/∂x`` with a constant ``c`` (an ``advect()`` velocity, a coefficient of
``d_dx``...) moves information ``|c|/h`` cells per unit time; explicit schemes take ``1/dt
≥ 1/dt_diffusion + Σ|c|/h`` (for upwind differences with forward Euler exactly the bound
that keeps the update a convex combination), IMEX and exponential schemes, whose
derivatives are explicit, ``dt ≤ h/Σ|c|``.  A coefficient that depends on the fields
(Burgers' ``u·d_dx(u)``) sets no limit here.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from rdgpu.ir import equations as eq
from rdgpu.ir.schemes import ExponentialScheme, ImexScheme, MultistepScheme, get_scheme

__all__ = ["advective_rate", "frozen_coefficients", "implicit_factors", "stability_limit",
           "with_advection"]


def stability_limit(D: np.ndarray, B: np.ndarray, m_max: float, method: str,
                    C: np.ndarray | None = None) -> float:
    """The largest stable step of ``method`` for the linear part ``A(m) = −m D + m² B``
    (+ ``C``, for an explicit method: the reactions' constant damping ``diag(γ)``, ``γ <=
    0``), ``0 < m <= m_max`` (module doc; ``method`` a name or alias of `SCHEMES`).
    Remembered per ``(D, B, m_max, method, C)``: an ensemble or a sweep asks for it once
    per member."""
    D, B = np.asarray(D, dtype=np.float64), np.asarray(B, dtype=np.float64)
    C = np.zeros_like(D) if C is None else np.asarray(C, dtype=np.float64)
    return _stability_limit(D.shape, D.tobytes(), B.tobytes(), float(m_max), method,
                            C.tobytes())


@functools.lru_cache(maxsize=4096)
def _stability_limit(shape: tuple[int, ...], d: bytes, b: bytes, m_max: float,
                     method: str, c: bytes) -> float:
    D = np.frombuffer(d, dtype=np.float64).reshape(shape)
    B = np.frombuffer(b, dtype=np.float64).reshape(shape)
    C = np.frombuffer(c, dtype=np.float64).reshape(shape)
    ms = np.unique(np.concatenate([np.linspace(0.0, m_max, 513)[1:], [m_max]]))
    scheme = get_scheme(method)
    if isinstance(scheme, ExponentialScheme):  # the linear part is exact: no limit
        return math.inf
    if not scheme.implicit:
        lam = np.linalg.eigvals(-ms[:, None, None] * D + (ms * ms)[:, None, None] * B
                                + C).ravel()
        neg = lam[lam.real < -1e-300]
        euler = float(np.min(-2.0 * neg.real / np.abs(neg) ** 2)) if neg.size else math.inf
        if isinstance(scheme, MultistepScheme) and neg.size:
            return _multistep_limit(neg, scheme.beta, euler)
        return euler
    def stable(h: float) -> bool:
        for m in ms:
            A = -m * D + m * m * B
            exact = np.max(np.linalg.eigvals(A).real)
            G = _amplification(D, B, m, h, scheme, m_max)
            rho = np.max(np.abs(np.linalg.eigvals(G)))
            if exact <= 0 and rho > 1.0 + 1e-9:
                return False
        return True

    hi = 1.0 / max(m_max * (np.max(np.abs(D)) + m_max * np.max(np.abs(B))), 1e-300)
    if not stable(hi):
        lo = 0.0
    else:
        lo = hi
        while stable(hi * 4.0):
            hi *= 4.0
            lo = hi
            if hi > 1e12:
                return math.inf
        hi *= 4.0
    return _bisect(stable, lo, hi)


def _bisect(stable, lo: float, hi: float) -> float:
    """The largest ``h`` in ``[lo, hi]`` with ``stable(h)`` (``stable(lo)`` holds), to 60
    halvings."""
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if stable(mid):
            lo = mid
        else:
            hi = mid
    return lo


def _multistep_limit(lam: np.ndarray, beta: tuple[float, ...], euler: float) -> float:
    """The largest ``h`` for which the two-level scheme ``x' = x + h(β₀λx + β₁λx₋)`` is
    stable for every eigenvalue ``λ`` of ``lam`` (the roots of ``z² − (1 + hλβ₀)z −
    hλβ₁`` in the closed unit disk), by bisection below Euler's limit ``euler``
    (Adams-Bashforth's region lies inside Euler's disk)."""
    b0, b1 = beta

    def stable(h: float) -> bool:
        p = 1.0 + h * lam * b0
        q = h * lam * b1
        disc = np.sqrt(p * p + 4.0 * q + 0j)
        roots = np.concatenate([(p + disc) / 2.0, (p - disc) / 2.0])
        return bool(np.all(np.abs(roots) <= 1.0 + 1e-12))

    return _bisect(stable, 0.0, euler) if math.isfinite(euler) else math.inf


#: a species' own diffusion ``α Δs`` stays explicit in a one-step IMEX step while
#: ``h α m_max <=`` this (forward Euler's limit is 2: half of it, a margin for the reaction
#: terms stepped with it)
EXPLICIT_DIFFUSION = 1.0


def implicit_factors(alpha: float, beta: float, h: float, theta: float,
                     m_max: float | None = None) -> tuple[float, float]:
    """``(a₁, a₂)`` of ``P = (I − a₁Δ)(I − a₂Δ)`` (module doc of
    `rdgpu.integrators.stepper`).

    Parameters
    ----------
    alpha, beta : float
        The species' own coefficients of ``Δs`` and ``Δ²s`` (``beta <= 0``).
    h : float
        The step the implicit operator is for.
    theta : float
        The θ of the scheme (1 backward Euler, ½ Crank-Nicolson).
    m_max : float or None
        The largest eigenvalue of ``−Δ`` on the domain, given for one-step schemes: a
        diffusion without a bilaplacian that forward Euler steps with a margin (``h α
        m_max <=`` `EXPLICIT_DIFFUSION`) stays explicit, ``(0, 0)``, and costs no solve.
        ``None`` (SBDF2): every species' own linear part is implicit.
    """
    if beta == 0.0:
        if m_max is not None and h * alpha * m_max <= EXPLICIT_DIFFUSION:
            return 0.0, 0.0
        return max(theta * h * alpha, 0.0), 0.0
    prod = -h * beta
    total = max(2.0 * math.sqrt(prod), theta * h * alpha)
    disc = math.sqrt(max(total * total - 4.0 * prod, 0.0))
    return 0.5 * (total + disc), 0.5 * (total - disc)


def _amplification(D: np.ndarray, B: np.ndarray, m: float, h: float,
                   scheme: ImexScheme, m_max: float) -> np.ndarray:
    """The matrix that advances a Fourier mode (``−Δ`` eigenvalue ``m``) by one step of
    an implicit ``scheme``: ``n × n`` for a one-step IMEX scheme, the ``2n × 2n``
    companion matrix of BDF2's recursion ``P x' = (4/3 + 2h'E) x − (1/3 + h'E) x₋``
    (``h' = 2h/3``, ``P`` the implicit factors' symbol per species, ``E = A(m) + (P −
    I)/h'`` the explicit linear part)."""
    if scheme.steps == 1:
        return _imex_amplification(D, B, m, h, scheme.theta, m_max)
    n = D.shape[0]
    hb = 2.0 * h / 3.0
    p = np.empty(n)
    for i in range(n):
        a1, a2 = implicit_factors(D[i, i], B[i, i], hb, 1.0)
        p[i] = (1.0 + a1 * m) * (1.0 + a2 * m)
    E = -m * D + m * m * B + np.diag((p - 1.0) / hb)
    G = np.zeros((2 * n, 2 * n))
    G[:n, :n] = (4.0 / 3.0 * np.eye(n) + 2.0 * hb * E) / p[:, None]
    G[:n, n:] = -(1.0 / 3.0 * np.eye(n) + hb * E) / p[:, None]
    G[n:, :n] = np.eye(n)
    return G


def _imex_amplification(D, B, m, h, theta, m_max):
    """IMEX's ``G = I + h P⁻¹ A(m)``: the scheme is ``P (x' − x) = h f(x)`` (module doc)."""
    n = D.shape[0]
    p = np.empty(n)
    for i in range(n):
        a1, a2 = implicit_factors(D[i, i], B[i, i], h, theta, m_max)
        p[i] = (1.0 + a1 * m) * (1.0 + a2 * m)
    return np.eye(n) + h * (-m * D + m * m * B) / p[:, None]


def advective_rate(trees: Mapping[str, eq.Node], env: Mapping[str, Any],
                   spacings: tuple[float, ...]) -> float:
    """The largest over the equations of ``Σ |c|/h`` (``Σ 2|c|/h²`` for a second
    derivative along an axis): each derivative's constant coefficient ``c`` (products and
    quotients of numbers and the parameters ``env``, the ``max(v, 0)``/``min(v, 0)`` of an
    ``advect()`` velocity) over its axis's spacing
    (``spacings``, x first; derivatives along absent axes and field-dependent
    coefficients count nothing)."""
    worst = 0.0
    for tree in trees.values():
        total = 0.0
        stack: list[tuple[eq.Node, float]] = [(tree, 1.0)]
        while stack:
            node, factor = stack.pop()
            if isinstance(node, eq.Diff):
                k = "xyz".index(node.axis)
                if k < len(spacings):  # a second derivative: Euler's 2/|λ|, λ = −4c/h²
                    total += factor / spacings[k] if node.side != 2 \
                        else 2.0 * factor / spacings[k] ** 2
            elif isinstance(node, eq.Neg):
                stack.append((node.a, factor))
            elif isinstance(node, eq.Bin) and node.op in "+-":
                stack += [(node.a, factor), (node.b, factor)]
            elif isinstance(node, eq.Bin):
                for const, other in ((node.a, node.b), (node.b, node.a)):
                    if node.op == "/" and const is node.a:
                        continue  # c / d_dx(u) is no advection
                    if eq.is_constant(const):
                        with np.errstate(all="ignore"):
                            c = abs(float(eq.evaluate(const, env)))
                            scaled = (np.float64(factor) / c if node.op == "/"
                                      else np.float64(factor) * c)
                        stack.append((other, float(scaled)))  # c = 0 in a quotient: inf
                        break
        worst = max(worst, total)
    return worst if math.isfinite(worst) else math.inf


def frozen_coefficients(tree: eq.Node, env: Mapping[str, Any]) -> eq.Node:
    """``tree`` with each ``div(D*grad(r))`` whose ``D`` depends on no species and not on
    ``t`` written as ``D_max·laplace(r)``, ``D_max`` the value of ``D`` of largest magnitude
    over ``env`` (the domain's coordinates as arrays, the parameters): the linear split then
    sees it.  By Gershgorin the face-averaged operator's eigenvalues lie within those of
    ``D_max Δ`` (each row's weights sum to at most ``D_max`` times the Laplacian's), so
    ``D_max``'s limit is a safe one.  Other divergences stay as they are (none)."""
    def fn(n: eq.Node) -> eq.Node | None:
        if not isinstance(n, eq.DivGrad) or eq.is_constant(n.coef):
            return None
        kinds = {m.kind for m in eq.walk(n.coef) if isinstance(m, eq.Ref)}
        if kinds - {"param", "coord", "length"} or any(
                isinstance(m, (eq.Lap, eq.Diff, eq.LapOf, eq.DivGrad)) for m in eq.walk(n.coef)):
            return None
        with np.errstate(all="ignore"):
            values = np.abs(np.asarray(eq.evaluate(n.coef, env), dtype=np.float64))
        largest = float(values.max()) if values.size else 0.0
        return eq.Bin("*", eq.Num(largest if math.isfinite(largest) else math.inf),
                      eq.Lap(n.name))
    return eq.substitute(tree, fn)


def with_advection(limit: float, rate: float, method: str) -> float:
    """``limit`` (the diffusive one of `stability_limit`) with the advective CFL of
    `advective_rate`'s ``rate`` (module doc)."""
    if not rate > 0 or not limit > 0:
        return limit
    scheme = get_scheme(method)
    if scheme.implicit or isinstance(scheme, ExponentialScheme):
        return min(limit, 1.0 / rate)
    if isinstance(scheme, MultistepScheme):  # its real interval against Euler's 2
        rate *= 2.0 / scheme.real_stability
    return 1.0 / (1.0 / limit + rate)
