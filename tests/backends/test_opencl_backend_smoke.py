"""Smoke test of the OpenCL backend against the NumPy references (a few seconds on PoCL).

Every kernel, float32 and float64, every boundary kind including mixed pairs, awkward
shapes, and both launch layouts: "row" (the CPU default) and "strided" (the GPU layout,
forced here on the CPU device with a small column stride so its loops run several times).
"""

from __future__ import annotations

import sys

import numpy as np
import pytest

pytest.importorskip("pyopencl")

from rdgpu.core.errors import BackendUnavailableError  # noqa: E402
from rdgpu.domains.boundary import parse_bc  # noqa: E402
from rdgpu.families import load_module  # noqa: E402

opencl_backend = pytest.importorskip("rdgpu.backends.opencl_backend")
opencl_devices = pytest.importorskip("rdgpu.backends.opencl_devices")
OpenCLBackend = opencl_backend.OpenCLBackend

try:
    opencl_backend.list_devices()
except BackendUnavailableError as exc:  # pragma: no cover - machine without a driver
    pytest.skip(f"no OpenCL device: {exc}", allow_module_level=True)

lap_ref = load_module("laplacian", "reference.py")
bern_ref = load_module("bernoulli", "reference.py")
gs_ref = load_module("gray_scott", "reference.py")
sor_ref = load_module("sor", "reference.py")
ls_ref = load_module("levelset", "reference.py")

SHAPES = [(1, 7), (3, 5), (7, 1), (2, 2), (37, 64), (64, 37)]
BCS = [
    "periodic",
    "neumann",
    ("dirichlet", 0.3),
    ("periodic", ("dirichlet", 0.3)),
    (("dirichlet", -0.7), "neumann"),
    ("neumann", "periodic"),
    (("dirichlet", 0.25), ("dirichlet", -1.5)),
]
DTYPES = [np.float32, np.float64]
LAYOUTS = [("row", None), ("strided", 16)]


@pytest.fixture(scope="module", params=LAYOUTS, ids=[name for name, _ in LAYOUTS])
def backend(request):
    layout, stride = request.param
    return OpenCLBackend(layout=layout, col_stride=stride)


def close(got, ref, dtype, what, ulps=4):
    """Equal to round-off: a few ulps of the result's scale."""
    eps = np.finfo(dtype).eps
    scale = max(1.0, float(np.nanmax(np.abs(ref))) if ref.size else 1.0)
    assert got.dtype == np.dtype(dtype), what
    np.testing.assert_allclose(got, ref, rtol=ulps * eps, atol=ulps * eps * scale, err_msg=what)


def field(rng, shape, dtype, lo=-1.0, hi=1.0):
    return rng.uniform(lo, hi, shape).astype(dtype)


def cases():
    for shape in SHAPES:
        for bc in BCS:
            yield shape, parse_bc(bc)


@pytest.mark.parametrize("dtype", DTYPES)
def test_laplacian(backend, dtype):
    rng = np.random.default_rng(1)
    for shape, bc in cases():
        u = field(rng, shape, dtype)
        du, out = backend.upload(u), backend.empty(shape, dtype)
        for dx, dy in ((0.5, 0.5), (0.3, 0.7)):
            backend.laplacian(du, out, dx=dx, dy=dy, bc=bc, stencil=5)
            ref = lap_ref.laplacian(u, dx, dy, bc, 5)
            close(out.numpy(), ref, dtype, f"lap5 {shape} {bc} dx={dx} dy={dy}")
        backend.laplacian(du, out, dx=0.4, dy=0.4, bc=bc, stencil=9)
        ref = lap_ref.laplacian(u, 0.4, 0.4, bc, 9)
        close(out.numpy(), ref, dtype, f"lap9 {shape} {bc}")
    with pytest.raises(ValueError):
        backend.laplacian(du, out, dx=0.4, dy=0.5, bc=bc, stencil=9)


@pytest.mark.parametrize("dtype", DTYPES)
def test_bernoulli(backend, dtype):
    rng = np.random.default_rng(2)
    for shape in [(1,), (7,), (40_000,), *SHAPES]:
        u = field(rng, shape, dtype, -1.5, 1.5)
        du, out = backend.upload(u), backend.empty(shape, dtype)
        for decay in (0.0, 0.37, 1.0):
            backend.bernoulli(du, out, decay=decay)
            close(out.numpy(), bern_ref.bernoulli(u, decay), dtype, f"bernoulli {shape} {decay}")


@pytest.mark.parametrize("dtype", DTYPES)
def test_gray_scott(backend, dtype):
    rng = np.random.default_rng(3)
    kw = dict(Du=0.16, Dv=0.08, dt=0.9, dx=1.0, dy=1.1)
    for shape, bc in cases():
        u = field(rng, shape, dtype, 0.2, 1.0)
        v = field(rng, shape, dtype, 0.0, 0.5)
        Ff = field(rng, shape, dtype, 0.01, 0.06)
        kf = field(rng, shape, dtype, 0.04, 0.07)
        for F, k in ((0.035, 0.065), (Ff, 0.065), (0.035, kf), (Ff, kf)):
            dF = backend.upload(F) if isinstance(F, np.ndarray) else F
            dk = backend.upload(k) if isinstance(k, np.ndarray) else k
            a, b = backend.upload(u), backend.upload(v)
            a2, b2 = backend.empty_like(a), backend.empty_like(b)
            ru, rv = u, v
            for _ in range(3):  # ping-pong
                backend.gray_scott(a, b, a2, b2, F=dF, k=dk, bc=bc, **kw)
                a, b, a2, b2 = a2, b2, a, b
                ru, rv = gs_ref.gray_scott_step(ru, rv, F=F, k=k, bc=bc, **kw)
            what = f"gray_scott {shape} {bc} F={type(F).__name__} k={type(k).__name__}"
            close(a.numpy(), ru, dtype, what)
            close(b.numpy(), rv, dtype, what)


def sor_ok(shape, bc):
    """Periodic axes must have even length for red-black SOR."""
    return not ((bc.y.kind == 0 and shape[0] % 2) or (bc.x.kind == 0 and shape[1] % 2))


@pytest.mark.parametrize("dtype", DTYPES)
def test_sor_half_sweeps(backend, dtype):
    rng = np.random.default_rng(4)
    tested = 0
    for shape, bc in cases():
        if not sor_ok(shape, bc):
            continue
        tested += 1
        c = field(rng, shape, dtype)
        fixed = (rng.random(shape) < 0.2).astype(np.uint8)
        rhs = field(rng, shape, dtype)
        for f in (None, rhs):
            dc, dfixed = backend.upload(c), backend.upload(fixed)
            drhs = None if f is None else backend.upload(f)
            change = backend.upload(np.full(shape[0], np.nan, dtype))  # colour 0 overwrites
            ref_c = c
            ref_change = None
            for color in (0, 1, 0, 1):
                backend.sor_half_sweep(
                    dc, dfixed, drhs, change, color=color, omega=1.7, dx=0.5, dy=0.8, bc=bc
                )
                ref_c, ch = sor_ref.sor_half_sweep(ref_c, fixed, f, color, 1.7, 0.5, 0.8, bc)
                ref_change = ch if color == 0 else np.maximum(ref_change, ch)
                what = f"sor {shape} {bc} rhs={f is not None} color={color}"
                close(dc.numpy(), ref_c, dtype, what)
                close(change.numpy(), ref_change, dtype, what + " row_change")
    assert tested > 20


@pytest.mark.parametrize("dtype", DTYPES)
def test_levelset(backend, dtype):
    rng = np.random.default_rng(5)
    for shape, bc in cases():
        phi = field(rng, shape, dtype)
        phi0 = field(rng, shape, dtype)
        speed = field(rng, shape, dtype)
        dphi, out = backend.upload(phi), backend.empty(shape, dtype)
        for sp in (0.8, -0.6, speed):
            dsp = backend.upload(sp) if isinstance(sp, np.ndarray) else sp
            backend.levelset_step(dphi, dsp, out, dt=0.1, dx=0.5, dy=0.7, bc=bc)
            ref = ls_ref.levelset_step(phi, sp, 0.1, 0.5, 0.7, bc)
            close(out.numpy(), ref, dtype, f"levelset {shape} {bc} speed={type(sp).__name__}")
        dphi0 = backend.upload(phi0)
        for subcell in (False, True):
            backend.reinit_step(
                dphi, dphi0, out, dtau=0.2, width=0.5, dx=0.5, dy=0.7, bc=bc, subcell=subcell
            )
            ref = ls_ref.reinit_step(phi, phi0, 0.2, 0.5, 0.5, 0.7, bc, subcell)
            close(out.numpy(), ref, dtype, f"reinit {shape} {bc} subcell={subcell}")


def test_default_col_stride_gray_scott():
    """The GPU layout with its default stride (128 > nx: idle work-items)."""
    b = OpenCLBackend(layout="strided")
    assert b.col_stride == 128
    rng = np.random.default_rng(6)
    bc = parse_bc(("periodic", "neumann"))
    u, v = field(rng, (37, 300), np.float32, 0, 1), field(rng, (37, 300), np.float32, 0, 1)
    kw = dict(Du=0.2, Dv=0.1, F=0.04, k=0.06, dt=1.0, dx=1.0, dy=1.0, bc=bc)
    a, bb = b.upload(u), b.upload(v)
    a2, b2 = b.empty_like(a), b.empty_like(bb)
    b.gray_scott(a, bb, a2, b2, **kw)
    ru, rv = gs_ref.gray_scott_step(u, v, **kw)
    close(a2.numpy(), ru, np.float32, "gs u")
    close(b2.numpy(), rv, np.float32, "gs v")


def test_memory_ops():
    b = OpenCLBackend()
    x = np.arange(12, dtype=np.float64).reshape(3, 4)
    d = b.upload(x)
    assert d.shape == (3, 4) and d.dtype == np.float64 and d.backend is b
    np.testing.assert_array_equal(d.numpy(), x)
    e = b.empty((3, 4), np.float64)
    b.copy(d, e)
    np.testing.assert_array_equal(b.download(e), x)
    z = b.upload(np.zeros((0, 5), np.float32))
    assert b.download(z).shape == (0, 5)
    m = b.upload(np.array([1, 0, 1], np.uint8))
    np.testing.assert_array_equal(m.numpy(), [1, 0, 1])
    with pytest.raises(ValueError):
        b.copy(d, b.empty((4, 3), np.float64))
    b.synchronize()


def test_device_selection():
    devices = opencl_backend.list_devices()
    key, platform, device = devices[0]
    b = OpenCLBackend(key)
    assert b.name == "opencl"
    assert device.name.strip() in b.device and platform.name.strip() in b.device
    b2 = OpenCLBackend(device.name.strip()[:6].upper())  # case-insensitive substring
    assert b2.device
    with pytest.raises(BackendUnavailableError, match=r"Devices: 0:0 = "):
        OpenCLBackend("no-such-device-xyz")
    with pytest.raises(BackendUnavailableError, match="no OpenCL device"):
        OpenCLBackend("99:0")


def test_float64_without_fp64():
    b = OpenCLBackend()
    b.fp64 = False
    b._programs.clear()
    with pytest.raises(BackendUnavailableError, match="float64"):
        b.empty((2, 2), np.float64)
    with pytest.raises(BackendUnavailableError, match="float64"):
        b.upload(np.zeros(3))
    b.empty((2, 2), np.float32)


def test_unavailable_messages(monkeypatch):
    import pyopencl as cl

    monkeypatch.setattr(cl, "get_platforms", lambda: [])
    with pytest.raises(BackendUnavailableError, match="pip install pyopencl pocl"):
        OpenCLBackend()
    monkeypatch.setitem(sys.modules, "pyopencl", None)
    with pytest.raises(BackendUnavailableError, match="pyopencl"):
        OpenCLBackend()


def test_default_device_skips_a_driver_that_cannot_compile(monkeypatch):
    """A driver whose compiler cannot target this CPU (PoCL 3.0 on AMD Zen 5) is passed
    over by the default choice, and naming it explicitly says why it cannot be used."""
    from rdgpu.core.errors import BackendUnavailableError

    devices = opencl_backend.list_devices()
    first = devices[0][2]
    probed = {d.int_ptr: None for _k, _p, d in devices}  # pretend the others work
    probed[first.int_ptr] = "error: unknown target CPU"
    monkeypatch.setattr(opencl_devices, "_PROBED", probed)
    if len(devices) > 1:
        _platform, chosen = opencl_backend.select_device(None)
        assert chosen.int_ptr != first.int_ptr
    with pytest.raises(BackendUnavailableError, match="cannot compile kernels.*unknown target"):
        opencl_backend.select_device(devices[0][0])
    monkeypatch.setattr(opencl_devices, "_PROBED",
                        {d.int_ptr: "error: unknown target CPU" for _k, _p, d in devices})
    with pytest.raises(BackendUnavailableError, match="no OpenCL device here can compile"):
        opencl_backend.select_device(None)
