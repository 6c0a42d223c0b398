"""The exact Laplace-Beltrami operator of a graph surface ``z = h(x, y)``, for checks of the
discrete one (tests, ``perf/metric.py``); independent of ``reference.py``'s stencil.

Two ways, each a check of the other:

* :func:`exact_laplace_beltrami` -- for trigonometric ``h`` and ``u`` (:class:`Waves`, exact
  derivatives), the non-divergence form of the operator on a graph
  ``Δ_Γ u = g^{ij} u_ij − (g^{ij} h_ij)(h_k u_k)/g`` with ``g^{ij} = δ_ij − h_i h_j / g``,
  ``g = 1 + h_x² + h_y²`` (the Christoffel symbols of a graph are ``Γ^k_ij = h_k h_ij / g``);
* :func:`spectral_laplace_beltrami` -- the divergence form ``(1/√g) ∂_i(√g g^{ij} ∂_j u)``
  with FFT derivatives of periodic samples (spectrally accurate for smooth fields).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Waves:
    """``f(x, y) = Σ a cos(kx x + ky y + φ)`` over the ``terms`` ``(a, kx, ky, φ)``."""

    terms: tuple[tuple[float, float, float, float], ...]

    def __call__(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        out = np.zeros(np.broadcast_shapes(np.shape(x), np.shape(y)))
        for a, kx, ky, phase in self.terms:
            out += a * np.cos(kx * x + ky * y + phase)
        return out

    def d(self, px: int = 0, py: int = 0) -> Waves:
        """The derivative ``∂x^px ∂y^py`` (each derivative shifts the phase by π/2)."""
        return Waves(tuple((a * kx**px * ky**py, kx, ky, phase + (px + py) * np.pi / 2)
                           for a, kx, ky, phase in self.terms))

    def scaled(self, factor: float) -> Waves:
        return Waves(tuple((factor * a, kx, ky, phase) for a, kx, ky, phase in self.terms))


def exact_laplace_beltrami(h: Waves, u: Waves, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``Δ_Γ u`` at the points ``(x, y)`` on the graph of ``h`` (module doc), float64."""
    hx, hy = h.d(1, 0)(x, y), h.d(0, 1)(x, y)
    g = 1.0 + hx**2 + hy**2

    def trace(f: Waves) -> np.ndarray:  # g^{ij} f_ij
        fxx, fxy, fyy = f.d(2, 0)(x, y), f.d(1, 1)(x, y), f.d(0, 2)(x, y)
        return fxx + fyy - (hx * hx * fxx + 2.0 * hx * hy * fxy + hy * hy * fyy) / g

    return trace(u) - trace(h) * (hx * u.d(1, 0)(x, y) + hy * u.d(0, 1)(x, y)) / g


def spectral_laplace_beltrami(h: np.ndarray, u: np.ndarray, dx: float,
                              dy: float) -> np.ndarray:
    """``Δ_Γ u`` of periodic samples ``h, u [ny, nx]`` with FFT derivatives (float64)."""
    ny, nx = u.shape
    kx = 2j * np.pi * np.fft.fftfreq(nx, dx)
    ky = 2j * np.pi * np.fft.fftfreq(ny, dy)[:, None]
    if nx % 2 == 0:
        kx[nx // 2] = 0  # the Nyquist mode has no odd derivative
    if ny % 2 == 0:
        ky[ny // 2] = 0

    def ddx(f: np.ndarray) -> np.ndarray:
        return np.fft.ifft(kx * np.fft.fft(f, axis=1), axis=1).real

    def ddy(f: np.ndarray) -> np.ndarray:
        return np.fft.ifft(ky * np.fft.fft(f, axis=0), axis=0).real

    hx, hy, ux, uy = ddx(h), ddy(h), ddx(u), ddy(u)
    root = np.sqrt(1.0 + hx**2 + hy**2)
    fx = ((1.0 + hy**2) * ux - hx * hy * uy) / root
    fy = ((1.0 + hx**2) * uy - hx * hy * ux) / root
    return (ddx(fx) + ddy(fy)) / root


#: the surface and the exact solution's spatial parts of :func:`manufactured_rds`
RDS_HEIGHT = Waves(((0.4, 1.0, 2.0, 0.3), (0.3, -2.0, 1.0, 1.1)))
RDS_U = Waves(((1.0, 1.0, 1.0, 0.0), (0.5, 0.0, 2.0, 0.7)))
RDS_V = Waves(((0.8, 2.0, -1.0, 0.2), (0.4, 1.0, 0.0, 0.0)))


def manufactured_rds(n: int, Du: float = 1.0, Dv: float = 0.5) -> dict:
    """Seed 002 §4's convergence check: a reaction-diffusion system on the rough periodic
    surface ``z = RDS_HEIGHT`` over ``[0, 2π]²`` (``n × n`` cells) whose exact solution is
    ``u = e^{−t} φ``, ``v = e^{−t} ψ`` (``φ = RDS_U``, ``ψ = RDS_V``):

        ``u_t = Du Δ_Γ u − uv + e^{−t} Au + e^{−2t} P``,
        ``v_t = Dv Δ_Γ v + uv + e^{−t} Av − e^{−2t} P``,

    with the parameter fields ``Au = −(φ + Du Δ_Γ φ)``, ``Av = −(ψ + Dv Δ_Γ ψ)``, ``P = φψ``
    (``Δ_Γ`` exact).  Returns the model's ``equations``, the ``domain`` dict, the
    ``params``, the initial ``fields`` and ``exact(t)`` giving ``(u, v)``."""
    d = 2.0 * np.pi / n
    c = (np.arange(n) + 0.5) * d
    y, x = np.meshgrid(c, c, indexing="ij")
    phi, psi = RDS_U(x, y), RDS_V(x, y)
    return {
        "equations": {"u": "Du*laplace(u) - u*v + exp(-t)*Au + exp(-2*t)*P",
                      "v": "Dv*laplace(v) + u*v + exp(-t)*Av - exp(-2*t)*P"},
        "domain": {"grid": (n, n), "dx": d, "height": RDS_HEIGHT(x, y)},
        "params": {"Du": Du, "Dv": Dv, "P": phi * psi,
                   "Au": -(phi + Du * exact_laplace_beltrami(RDS_HEIGHT, RDS_U, x, y)),
                   "Av": -(psi + Dv * exact_laplace_beltrami(RDS_HEIGHT, RDS_V, x, y))},
        "fields": {"u": phi, "v": psi},
        "exact": lambda t: (np.exp(-t) * phi, np.exp(-t) * psi),
    }
