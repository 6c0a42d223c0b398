"""Smoke test of the Warp backend against the NumPy references (every kernel, both
dtypes, every boundary kind, small and odd shapes, and one grid large enough to take the
multi-threaded row-chunk path)."""

from __future__ import annotations

import sys

import numpy as np
import pytest

pytest.importorskip("warp")

from rdgpu.backends.base import DeviceArray  # noqa: E402
from rdgpu.backends.warp_backend import WarpBackend  # noqa: E402
from rdgpu.core.errors import BackendUnavailableError  # noqa: E402
from rdgpu.domains.boundary import parse_bc  # noqa: E402
from rdgpu.families import load_module  # noqa: E402

BCS = [
    "periodic",
    "neumann",
    ("dirichlet", 0.3),
    ("periodic", ("dirichlet", 0.3)),
    (("dirichlet", -0.7), "periodic"),
    ("neumann", ("dirichlet", 1.5)),
    (("dirichlet", 0.25), "neumann"),
]
# (ny, nx); 300×260 is above the split threshold (row chunks from the thread pool)
SHAPES = [(1, 7), (3, 5), (7, 1), (2, 2), (37, 64), (64, 37), (300, 260)]
DTYPES = [np.float32, np.float64]


@pytest.fixture(scope="module", params=["auto", "cells"])
def be(request):
    """The CPU's row-loop kernels, and the one-thread-per-cell kernels CUDA uses."""
    return WarpBackend("cpu", launch=request.param)


def ref(family):
    return load_module(family, "reference.py")


def close(got, want, scale=1.0):
    """Agreement to round-off: a few ulps of the terms' magnitude."""
    eps = np.finfo(want.dtype).eps
    assert got.dtype == want.dtype and got.shape == want.shape
    np.testing.assert_allclose(got, want, rtol=64 * eps, atol=64 * eps * scale)


def cases(even_periodic=False):
    for bc_spec in BCS:
        bc = parse_bc(bc_spec)
        for shape in SHAPES:
            if even_periodic and (
                (bc.y.kind == 0 and shape[0] % 2) or (bc.x.kind == 0 and shape[1] % 2)
            ):
                continue
            yield bc_spec, bc, shape


def test_device_and_errors(be, monkeypatch):
    assert be.name == "warp" and be.device == "cpu"
    with pytest.raises(BackendUnavailableError, match="'cpu'"):  # names the devices there are
        WarpBackend("no-such-device")
    monkeypatch.setitem(sys.modules, "warp", None)  # as if warp were not installed
    with pytest.raises(BackendUnavailableError, match="pip install warp-lang"):
        WarpBackend("cpu")


def test_memory_roundtrip(be):
    rng = np.random.default_rng(0)
    for a in (
        rng.standard_normal((5, 3)).astype(np.float32),
        rng.standard_normal(11),
        (rng.random((4, 6)) < 0.5).astype(np.uint8),
    ):
        d = be.upload(a)
        assert isinstance(d, DeviceArray) and d.shape == a.shape and d.dtype == a.dtype
        e = be.empty_like(d)
        be.copy(d, e)
        be.synchronize()
        back = e.numpy()
        np.testing.assert_array_equal(back, a)
        back[...] = 0  # a copy, not a view of the device buffer
        np.testing.assert_array_equal(be.download(d), a)
    h = np.arange(6.0)
    d = be.upload(h)
    h[:] = -1  # the upload is a copy too
    np.testing.assert_array_equal(d.numpy(), np.arange(6.0))


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("stencil", [5, 9])
def test_laplacian(be, dtype, stencil):
    rng = np.random.default_rng(1)
    dx = 0.7
    dy = dx if stencil == 9 else 1.3
    for _, bc, shape in cases():
        u = rng.standard_normal(shape).astype(dtype)
        d, out = be.upload(u), be.empty(shape, dtype)
        be.laplacian(d, out, dx=dx, dy=dy, bc=bc, stencil=stencil)
        want = ref("laplacian").laplacian(u, dx, dy, bc, stencil)
        close(out.numpy(), want, scale=10 / dx**2)


@pytest.mark.parametrize("dtype", DTYPES)
def test_bernoulli(be, dtype):
    rng = np.random.default_rng(2)
    for shape in [(1,), (13,), (100_003,), *SHAPES]:
        u = (2 * rng.standard_normal(shape)).astype(dtype)
        d, out = be.upload(u), be.empty(shape, dtype)
        for decay in (0.0, 0.37, 1.0):
            be.bernoulli(d, out, decay=decay)
            close(out.numpy(), ref("bernoulli").bernoulli(u, decay))


@pytest.mark.parametrize("dtype", DTYPES)
def test_gray_scott(be, dtype):
    rng = np.random.default_rng(3)
    gs = ref("gray_scott").gray_scott_step
    for i, (_, bc, shape) in enumerate(cases()):
        u = (1 - 0.5 * rng.random(shape)).astype(dtype)
        v = (0.25 * rng.random(shape)).astype(dtype)
        F_f = (0.03 + 0.02 * rng.random(shape)).astype(dtype)
        k_f = (0.05 + 0.02 * rng.random(shape)).astype(dtype)
        F_s, k_s = 0.037, 0.06
        F, k = [(F_s, k_s), (F_f, k_s), (F_s, k_f), (F_f, k_f)][i % 4]
        Fd = be.upload(F) if isinstance(F, np.ndarray) else F
        kd = be.upload(k) if isinstance(k, np.ndarray) else k
        kw = dict(Du=0.16, Dv=0.08, dt=0.9, dx=1.0, dy=1.1)
        a = [be.upload(u), be.upload(v), be.empty(shape, dtype), be.empty(shape, dtype)]
        wu, wv = u, v
        for step in range(3):  # ping-pong
            src, dst = (a[:2], a[2:]) if step % 2 == 0 else (a[2:], a[:2])
            be.gray_scott(*src, *dst, F=Fd, k=kd, bc=bc, **kw)
            wu, wv = gs(wu, wv, kw["Du"], kw["Dv"], F, k, kw["dt"], kw["dx"], kw["dy"], bc)
        close(a[2].numpy(), wu)
        close(a[3].numpy(), wv)


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("with_rhs", [False, True])
def test_sor_half_sweeps(be, dtype, with_rhs):
    rng = np.random.default_rng(4)
    sweep = ref("sor").sor_half_sweep
    dx, dy, omega = 0.5, 0.8, 1.7
    for _, bc, shape in cases(even_periodic=True):
        c = rng.random(shape).astype(dtype)
        fixed = (rng.random(shape) < 0.2).astype(np.uint8)
        rhs = rng.standard_normal(shape).astype(dtype) if with_rhs else None
        cd, fd = be.upload(c), be.upload(fixed)
        rd = be.upload(rhs) if with_rhs else None
        rc = be.upload(np.full(shape[0], 1e9, dtype))  # colour 0 must overwrite this
        want = c
        for color in (0, 1, 0, 1):
            be.sor_half_sweep(cd, fd, rd, rc, color=color, omega=omega, dx=dx, dy=dy, bc=bc)
            want, change = sweep(want, fixed.astype(bool), rhs, color, omega, dx, dy, bc)
            if color == 0:
                want_rc = change
            else:
                want_rc = np.maximum(want_rc, change)
            close(cd.numpy(), want, scale=4.0)
            close(rc.numpy(), want_rc, scale=4.0)


@pytest.mark.parametrize("dtype", DTYPES)
def test_levelset(be, dtype):
    rng = np.random.default_rng(5)
    ls = ref("levelset")
    dx, dy = 0.9, 0.6
    for i, (_, bc, shape) in enumerate(cases()):
        phi = rng.standard_normal(shape).astype(dtype)
        phi0 = rng.standard_normal(shape).astype(dtype)
        phi0[rng.random(shape) < 0.1] = 0  # exact zeros: the subcell fix's sign(0) = 0
        field = rng.standard_normal(shape).astype(dtype)
        speed = [0.8, -0.6, field][i % 3]
        sd = be.upload(field) if isinstance(speed, np.ndarray) else speed
        pd, p0d, out = be.upload(phi), be.upload(phi0), be.empty(shape, dtype)
        be.levelset_step(pd, sd, out, dt=0.1, dx=dx, dy=dy, bc=bc)
        close(out.numpy(), ls.levelset_step(phi, speed, 0.1, dx, dy, bc), scale=10.0)
        for subcell in (True, False):
            be.reinit_step(
                pd, p0d, out, dtau=0.3, width=dx, dx=dx, dy=dy, bc=bc, subcell=subcell
            )
            want = ls.reinit_step(phi, phi0, 0.3, dx, dx, dy, bc, subcell)
            close(out.numpy(), want, scale=10.0)


def test_recorded_launches(be):
    """Launches are replayed from records: new arrays (even at a recycled address) and
    new scalars must reach the kernel, and a record must not keep an array alive."""
    import gc
    import weakref

    rng = np.random.default_rng(6)
    bc = parse_bc("neumann")
    lap = ref("laplacian").laplacian
    for dx in (1.0, 1.0, 0.5, 0.5, 2.0):
        u = rng.standard_normal((9, 8))
        d, out = be.upload(u), be.empty((9, 8), np.float64)  # fresh buffers every time
        be.laplacian(d, out, dx=dx, dy=dx, bc=bc, stencil=5)
        close(out.numpy(), lap(u, dx, dx, bc, 5), scale=10 / dx**2)
        del d, out
    d, out = be.upload(u), be.empty((9, 8), np.float64)
    be.laplacian(d, out, dx=1.0, dy=1.0, bc=bc, stencil=5)
    handle = weakref.ref(d.handle)
    del d
    gc.collect()
    assert handle() is None
