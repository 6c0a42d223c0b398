"""Grid kernels on a grid without a y axis: one row, ``dy = inf``, a Neumann y condition.

This is how a 1-D problem reaches the backends: ``1/dy² = 0`` (Laplacian, Gray-Scott),
``1/dy = 0`` (level sets), ``wy = 0`` in SOR (whose weights are ``wx = 1/(2(1 + r))``,
``wy = r/(2(1 + r))``, ``wf = dx²/(2(1 + r))`` with ``r = dx²/dy² = 0``).  Every kernel, at
the backend level, must equal its 1-D formula, written out here independently (float64)."""

import math

import numpy as np
import pytest
from conftest import tolerance

from rdgpu.domains.boundary import parse_bc

DX = 0.5
N = 10  # even: periodic red-black SOR needs it
X_BCS = ["periodic", "neumann", ("dirichlet", 0.3)]
X_IDS = ["per", "neu", "dir"]


@pytest.fixture
def be(variant_backend):
    return variant_backend


def grid_bc(x_bc):
    return parse_bc(("neumann", x_bc))


def west_east(u: np.ndarray, x_bc) -> tuple[np.ndarray, np.ndarray]:
    """``(u[j−1], u[j+1])`` of a 1-D float64 array with the x condition's ghosts."""
    u = np.asarray(u, dtype=np.float64)
    if x_bc == "periodic":
        return np.roll(u, 1), np.roll(u, -1)
    if x_bc == "neumann":
        lo, hi = u[0], u[-1]
    else:
        lo = hi = x_bc[1]
    return np.concatenate([[lo], u[:-1]]), np.concatenate([u[1:], [hi]])


def lap1(u, x_bc):
    w, e = west_east(u, x_bc)
    return (e + w - 2.0 * u) / DX**2


def grads1(phi, x_bc):
    """Godunov ``(∇⁺, ∇⁻)`` in 1-D."""
    w, e = west_east(phi, x_bc)
    dm, dp = (phi - w) / DX, (e - phi) / DX
    plus = np.sqrt(np.maximum(dm, 0) ** 2 + np.minimum(dp, 0) ** 2)
    minus = np.sqrt(np.maximum(dp, 0) ** 2 + np.minimum(dm, 0) ** 2)
    return plus, minus


def row(dtype, seed, low=-1.0, high=1.0):
    return np.random.default_rng(seed).uniform(low, high, (1, N)).astype(dtype)


def close(got, want, dtype, scale):
    got = np.asarray(got)
    assert got.shape == (1, N) and got.dtype == dtype
    np.testing.assert_allclose(got[0], want, **tolerance(dtype, scale))


@pytest.mark.parametrize("x_bc", X_BCS, ids=X_IDS)
def test_laplacian(be, dtype, x_bc):
    u = row(dtype, 1)
    out = be.empty(u.shape, dtype)
    be.laplacian(be.upload(u), out, dx=DX, dy=math.inf, bc=grid_bc(x_bc), stencil=5)
    close(out.numpy(), lap1(u[0], x_bc), dtype, 4 / DX**2)


@pytest.mark.parametrize("x_bc", X_BCS, ids=X_IDS)
def test_gray_scott(be, dtype, x_bc):
    u, v = row(dtype, 2, 0.0, 1.0), row(dtype, 3, 0.0, 0.5)
    p = dict(Du=0.2, Dv=0.1, F=0.04, k=0.06, dt=0.3)
    uo, vo = be.empty(u.shape, dtype), be.empty(u.shape, dtype)
    be.gray_scott(be.upload(u), be.upload(v), uo, vo, dx=DX, dy=math.inf, bc=grid_bc(x_bc), **p)
    u1, v1 = u[0].astype(np.float64), v[0].astype(np.float64)
    uvv = u1 * v1 * v1
    want_u = u1 + p["dt"] * (p["Du"] * lap1(u1, x_bc) - uvv + p["F"] * (1 - u1))
    want_v = v1 + p["dt"] * (p["Dv"] * lap1(v1, x_bc) + uvv - (p["F"] + p["k"]) * v1)
    close(uo.numpy(), want_u, dtype, 4.0)
    close(vo.numpy(), want_v, dtype, 4.0)


@pytest.mark.parametrize("with_rhs", [False, True], ids=["f0", "rhs"])
@pytest.mark.parametrize("x_bc", X_BCS, ids=X_IDS)
def test_sor_half_sweeps(be, dtype, x_bc, with_rhs):
    """Both colours: ``c ← (1 − ω) c + ω ((E + W)/2 − dx² f/2)`` on the cells ``j`` of the
    colour (``j % 2 == color`` in row 0) that are not fixed; row change = max ``|Δc|``."""
    omega = 1.6
    c = row(dtype, 4)
    f = row(dtype, 5) if with_rhs else None
    fixed = np.zeros((1, N), np.uint8)
    fixed[0, 3] = 1
    dc, dfixed = be.upload(c), be.upload(fixed)
    drhs = None if f is None else be.upload(f)
    change = be.upload(np.full(1, np.nan, dtype))
    want = c[0].astype(np.float64)
    rhs = np.zeros(N) if f is None else f[0].astype(np.float64)
    want_change = 0.0
    for color in (0, 1):
        be.sor_half_sweep(dc, dfixed, drhs, change, color=color, omega=omega, dx=DX,
                          dy=math.inf, bc=grid_bc(x_bc))
        w, e = west_east(want, x_bc)
        new = (1 - omega) * want + omega * ((e + w) / 2 - DX**2 * rhs / 2)
        upd = (np.arange(N) % 2 == color) & (fixed[0] == 0)
        step = np.abs(new - want)[upd].max()
        want_change = step if color == 0 else max(want_change, step)
        want = np.where(upd, new, want)
        want = want.astype(dtype).astype(np.float64)  # the kernels store in the dtype
        close(dc.numpy(), want, dtype, 4.0)
        got_change = change.numpy()
        assert got_change.shape == (1,) and np.isfinite(got_change[0])
        np.testing.assert_allclose(got_change[0], want_change, **tolerance(dtype, 4.0))


@pytest.mark.parametrize("speed", [0.8, -0.6], ids=["out", "in"])
@pytest.mark.parametrize("x_bc", X_BCS, ids=X_IDS)
def test_levelset_step(be, dtype, x_bc, speed):
    phi = row(dtype, 6)
    out = be.empty(phi.shape, dtype)
    be.levelset_step(be.upload(phi), speed, out, dt=0.1, dx=DX, dy=math.inf, bc=grid_bc(x_bc))
    p = phi[0].astype(np.float64)
    plus, minus = grads1(p, x_bc)
    want = p - 0.1 * (max(speed, 0) * plus + min(speed, 0) * minus)
    close(out.numpy(), want, dtype, 4.0)


@pytest.mark.parametrize("subcell", [False, True], ids=["godunov", "subcell"])
@pytest.mark.parametrize("x_bc", X_BCS, ids=X_IDS)
def test_reinit_step(be, dtype, x_bc, subcell):
    phi0 = row(dtype, 7)
    phi = row(dtype, 8)
    dtau, width = 0.2, DX
    out = be.empty(phi.shape, dtype)
    be.reinit_step(be.upload(phi), be.upload(phi0), out, dtau=dtau, width=width, dx=DX,
                   dy=math.inf, bc=grid_bc(x_bc), subcell=subcell)
    p, z = phi[0].astype(np.float64), phi0[0].astype(np.float64)
    s = z / np.sqrt(z * z + width * width)
    plus, minus = grads1(p, x_bc)
    want = p - dtau * (np.maximum(s, 0) * plus + np.minimum(s, 0) * minus - s)
    if subcell:
        w, e = west_east(z, x_bc)
        front = (z * w < 0) | (z * e < 0) | (z == 0)
        grad = np.maximum.reduce([
            np.abs(e - w) / (2 * DX), np.abs(e - z) / DX, np.abs(z - w) / DX,
            np.full(N, 1e-30),
        ])
        relaxed = p - (dtau / DX) * (np.sign(z) * np.abs(p) - z / grad)
        assert front.any() and not front.all()
        want = np.where(front, relaxed, want)
    close(out.numpy(), want, dtype, 16.0)
