"""Arrays of any library through the functional API and Simulation (rdgpu.interop): memory
already on the backend is used in place (pointer identity, no upload or download), the
result comes back as the input's kind, ``out=`` receives results, and wrong arrays give
clear errors.  The CUDA paths run only where Warp sees a CUDA device."""

from __future__ import annotations

import numpy as np
import pytest

import rdgpu
from rdgpu.backends import interop
from rdgpu.domains.grid import Grid
from rdgpu.simulation.driver import Simulation
from tests.conftest import backend_or_skip

wp = pytest.importorskip("warp")

GS = {"Du": 0.16, "Dv": 0.08, "F": 0.035, "k": 0.06, "dt": 1.0}


def _fields(shape=(12, 16), dtype=np.float64, seed=0):
    rng = np.random.default_rng(seed)
    u = (1.0 - 0.5 * rng.random(shape)).astype(dtype)
    v = (0.25 * rng.random(shape)).astype(dtype)
    return u, v


def _spy(monkeypatch, be, method):
    """Record the DeviceArrays each call of ``be.<method>`` receives (and still run it)."""
    seen = []
    real = getattr(be, method)

    def spy(*args, **kwargs):
        seen.append(args)
        return real(*args, **kwargs)

    monkeypatch.setattr(be, method, spy)
    return seen


def _forbid(monkeypatch, be, *methods):
    """Make ``be.<method>`` fail: a copy through the host is a test failure."""
    for name in methods:
        def refuse(*args, _name=name, **kwargs):
            raise AssertionError(f"{_name} called: a copy through the host was made")

        monkeypatch.setattr(be, name, refuse)


def _forbid_upload_of(monkeypatch, be, *fields):
    """Fail when ``be.upload`` receives one of ``fields`` (operators and masks may go)."""
    real = be.upload

    def upload(a, *args, **kwargs):
        for f in fields:
            if np.shape(a) == f.shape and np.array_equal(a, f):
                raise AssertionError("a field was uploaded: a copy through the host")
        return real(a, *args, **kwargs)

    monkeypatch.setattr(be, "upload", upload)


# ---------------------------------------------------------------------------- kinds
def test_kind_of_names_each_kind():
    u, _ = _fields()
    assert interop.kind_of(u) == "numpy"
    assert interop.kind_of([[1.0, 2.0]]) == "list"
    assert interop.kind_of(wp.array(u, device="cpu")) == "warp"
    assert interop.kind_of(_DLPackOnly(u)) == "dlpack"
    with pytest.raises(TypeError, match="expected an array"):
        interop.kind_of("abc")


class _DLPackOnly:
    """An array that exposes only the DLPack protocol (as a foreign CPU library would)."""

    def __init__(self, a: np.ndarray):
        self._a = a
        self.shape, self.dtype = a.shape, a.dtype

    def __dlpack__(self, **kwargs):
        return self._a.__dlpack__(**kwargs)

    def __dlpack_device__(self):
        return self._a.__dlpack_device__()


# ---------------------------------------------------------------------------- Warp CPU
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_warp_cpu_array_is_used_in_place(monkeypatch, dtype):
    be = backend_or_skip("warp")
    u, _ = _fields(dtype=dtype)
    w = wp.array(u, dtype=wp.dtype_from_numpy(dtype), device="cpu")
    seen = _spy(monkeypatch, be, "laplacian")
    _forbid(monkeypatch, be, "upload")
    out = rdgpu.laplacian(w, backend=be)
    assert seen[0][0].handle.ptr == w.ptr  # the kernel read the caller's memory
    assert isinstance(out, wp.array) and out.device == w.device
    assert out.ptr != w.ptr  # the result is a new array, the input untouched
    assert np.array_equal(out.numpy(), rdgpu.laplacian(u, backend="numpy"))
    assert np.array_equal(w.numpy(), u)


def test_warp_cpu_steps_never_write_the_input(monkeypatch):
    be = backend_or_skip("warp")
    u, v = _fields()
    wu, wv = wp.array(u, device="cpu"), wp.array(v, device="cpu")
    _forbid(monkeypatch, be, "upload")
    seen = _spy(monkeypatch, be, "gray_scott")
    ru, rv = rdgpu.gray_scott(wu, wv, steps=5, backend=be, **GS)
    assert (seen[0][0].handle.ptr, seen[0][1].handle.ptr) == (wu.ptr, wv.ptr)
    assert all(a.handle.ptr not in (wu.ptr, wv.ptr) for call in seen for a in call[2:4])
    assert np.array_equal(wu.numpy(), u) and np.array_equal(wv.numpy(), v)
    eu, ev = rdgpu.gray_scott(u, v, steps=5, backend="numpy", **GS)
    assert isinstance(ru, wp.array) and isinstance(rv, wp.array)
    np.testing.assert_allclose(ru.numpy(), eu, rtol=0, atol=1e-14)
    np.testing.assert_allclose(rv.numpy(), ev, rtol=0, atol=1e-14)


@pytest.mark.parametrize("fn", ["levelset", "reinit", "diffusion", "sor", "bernoulli"])
def test_every_entry_takes_warp_arrays_in_place(monkeypatch, fn):
    be = backend_or_skip("warp")
    u, _ = _fields()
    phi = u - 0.75
    w = wp.array(phi, device="cpu")
    _forbid_upload_of(monkeypatch, be, phi)
    calls = {
        "levelset": lambda a: rdgpu.levelset_advance(a, 0.5, dt=0.2, steps=3, backend=be),
        "reinit": lambda a: rdgpu.reinitialize(a, iterations=4, backend=be),
        "diffusion": lambda a: rdgpu.diffusion_step(a, D=0.1, dt=0.5, steps=3, backend=be),
        "sor": lambda a: rdgpu.sor_sweep(a, np.zeros(phi.shape, bool), omega=1.5,
                                         backend=be),
        "bernoulli": lambda a: rdgpu.bernoulli_substep(a, tau=0.1, eps=0.5, backend=be),
    }
    got = calls[fn](w)
    want = calls[fn](phi) if fn != "sor" else None
    assert isinstance(got, wp.array) and got.ptr != w.ptr
    assert np.array_equal(w.numpy(), phi)  # never modified
    if want is not None:
        assert np.array_equal(got.numpy(), want)


def test_warp_array_on_another_backend_comes_back_as_warp(monkeypatch):
    be = backend_or_skip("numpy")
    u, _ = _fields()
    w = wp.array(u, device="cpu")
    seen = _spy(monkeypatch, be, "laplacian")
    out = rdgpu.laplacian(w, backend=be)
    # the numpy backend's memory is the host: a Warp CPU array is read in place there too
    assert seen[0][0].handle.__array_interface__["data"][0] == w.ptr
    assert isinstance(out, wp.array) and out.device == w.device
    assert np.array_equal(out.numpy(), rdgpu.laplacian(u, backend="numpy"))


# ---------------------------------------------------------------------------- DLPack
def test_numpy_dlpack_object_is_read_in_place(monkeypatch):
    be = backend_or_skip("numpy")
    u, _ = _fields()
    seen = _spy(monkeypatch, be, "laplacian")
    _forbid(monkeypatch, be, "upload")
    out = rdgpu.laplacian(_DLPackOnly(u), backend=be)
    assert seen[0][0].handle.__array_interface__["data"][0] == u.ctypes.data
    assert isinstance(out, np.ndarray)  # a DLPack object of no known library: NumPy out
    assert np.array_equal(out, rdgpu.laplacian(u, backend="numpy"))


def test_numpy_array_on_numpy_backend_is_read_in_place(monkeypatch):
    be = backend_or_skip("numpy")
    u, _ = _fields()
    seen = _spy(monkeypatch, be, "laplacian")
    _forbid(monkeypatch, be, "upload")
    rdgpu.laplacian(u, backend=be)
    assert seen[0][0].handle.__array_interface__["data"][0] == u.ctypes.data


@pytest.mark.parametrize("name", ["warp", "opencl"])
def test_dlpack_object_on_device_backends(name):
    be = backend_or_skip(name)
    u, v = _fields()
    ru, rv = rdgpu.gray_scott(_DLPackOnly(u), _DLPackOnly(v), steps=3, backend=be, **GS)
    eu, ev = rdgpu.gray_scott(u, v, steps=3, backend=be, **GS)
    assert isinstance(ru, np.ndarray)
    assert np.array_equal(ru, eu) and np.array_equal(rv, ev)


# ---------------------------------------------------------------------------- lists
def test_lists_give_numpy_arrays():
    u, _ = _fields(shape=(6, 8))
    out = rdgpu.laplacian(u.tolist(), backend="numpy")
    assert isinstance(out, np.ndarray) and out.dtype == np.float64
    assert np.array_equal(out, rdgpu.laplacian(u, backend="numpy"))
    row = rdgpu.bernoulli_substep([0.5, -0.25, 0.0], tau=0.1, eps=1.0, backend="numpy")
    assert isinstance(row, np.ndarray) and row.shape == (3,)


# ---------------------------------------------------------------------------- pyopencl
def test_pyopencl_array_on_the_backend_context_stays_on_the_device(monkeypatch):
    be = backend_or_skip("opencl")
    cla = pytest.importorskip("pyopencl.array")
    u, v = _fields(dtype=np.float32)
    du, dv = cla.to_device(be.queue, u), cla.to_device(be.queue, v)
    seen = _spy(monkeypatch, be, "gray_scott")
    _forbid(monkeypatch, be, "upload", "download")  # no host round trip at all
    ru, rv = rdgpu.gray_scott(du, dv, steps=4, backend=be, **GS)
    first = seen[0]
    assert first[0].handle.int_ptr == du.data.int_ptr
    assert first[1].handle.int_ptr == dv.data.int_ptr
    assert isinstance(ru, cla.Array) and ru.context.int_ptr == be.context.int_ptr
    assert ru.data.int_ptr not in (du.data.int_ptr, dv.data.int_ptr)
    monkeypatch.undo()
    eu, ev = rdgpu.gray_scott(u, v, steps=4, backend=be, **GS)
    assert np.array_equal(ru.get(), eu) and np.array_equal(rv.get(), ev)
    assert np.array_equal(du.get(), u)  # the input is not modified


def test_arrays_of_another_device_make_one_copy_and_come_back_as_their_kind():
    be = backend_or_skip("opencl")
    cla = pytest.importorskip("pyopencl.array")
    u, _ = _fields(dtype=np.float32)
    want = rdgpu.laplacian(u, backend="numpy")
    du = cla.to_device(be.queue, u)
    on_host = rdgpu.laplacian(du, backend="numpy")  # a pyopencl array on the numpy backend
    assert isinstance(on_host, cla.Array) and on_host.queue is du.queue
    assert np.array_equal(on_host.get(), want)
    w = wp.array(u, device="cpu")  # a Warp array on the OpenCL backend
    got = rdgpu.laplacian(w, backend=be)
    assert isinstance(got, wp.array) and got.device == w.device
    assert np.array_equal(got.numpy(), rdgpu.laplacian(u, backend=be))


@pytest.mark.parametrize("where", [0, 37, -1])
@pytest.mark.parametrize("bad", [np.nan, -np.inf])
def test_device_resident_inputs_are_checked_on_the_device(monkeypatch, where, bad):
    """A pyopencl input that stays on the device is still refused for NaN/Inf: one
    reduction there, no copy to the host."""
    be = backend_or_skip("opencl")
    cla = pytest.importorskip("pyopencl.array")
    u, v = _fields(dtype=np.float32)
    u.flat[where] = bad
    du, dv = cla.to_device(be.queue, u), cla.to_device(be.queue, v)
    _forbid(monkeypatch, be, "upload", "download")
    with pytest.raises(ValueError, match="u contains NaN or Inf"):
        rdgpu.gray_scott(du, dv, steps=1, backend=be, **GS)
    with pytest.raises(ValueError, match="u contains NaN or Inf"):
        rdgpu.laplacian(du, backend=be)


def test_device_resident_results_are_checked_on_the_device(monkeypatch):
    """A result that stays on the device (a pyopencl array back, or a resident ``out``)
    and overflowed is an error, found by one reduction there."""
    be = backend_or_skip("opencl")
    cla = pytest.importorskip("pyopencl.array")
    big = np.full((9, 13), 3e38, np.float32)
    big[::2] = -3e38  # the Laplacian of this checkerboard of rows overflows float32
    du = cla.to_device(be.queue, big)
    _forbid(monkeypatch, be, "upload", "download")
    with pytest.raises(FloatingPointError, match="overflow float32"):
        rdgpu.laplacian(du, backend=be)
    out = cla.empty(be.queue, big.shape, np.float32)
    with pytest.raises(FloatingPointError, match="overflow float32"):
        rdgpu.laplacian(du, backend=be, out=out)
    monkeypatch.undo()
    with pytest.raises(FloatingPointError, match="overflow float32"):
        rdgpu.laplacian(big, backend=be)  # the same check on the host


def test_pyopencl_buffer_alone_is_refused_with_the_fix():
    be = backend_or_skip("opencl")
    cl = pytest.importorskip("pyopencl")
    buf = cl.Buffer(be.context, cl.mem_flags.READ_WRITE, size=64)
    with pytest.raises(TypeError, match="pyopencl.array.Array"):
        rdgpu.laplacian(buf, backend=be)


# ---------------------------------------------------------------------------- out=
@pytest.mark.parametrize("name", ["numpy", "warp", "opencl"])
def test_out_is_reused_in_a_loop(name):
    be = backend_or_skip(name)
    u, v = _fields()
    uo, vo = np.empty_like(u), np.empty_like(v)
    lap = np.empty_like(u)
    cu, cv = u, v
    for _ in range(3):
        got = rdgpu.gray_scott(cu, cv, steps=2, backend=be, out=(uo, vo), **GS)
        fresh = rdgpu.gray_scott(cu, cv, steps=2, backend=be, **GS)
        assert got[0] is uo and got[1] is vo
        assert np.array_equal(uo, fresh[0]) and np.array_equal(vo, fresh[1])
        assert rdgpu.laplacian(uo, backend=be, out=lap) is lap
        assert np.array_equal(lap, rdgpu.laplacian(fresh[0], backend=be))
        cu, cv = fresh


def test_warp_out_on_warp_backend_receives_on_the_device(monkeypatch):
    be = backend_or_skip("warp")
    u, _ = _fields()
    w = wp.array(u, device="cpu")
    target = wp.empty(u.shape, dtype=wp.float64, device="cpu")
    ptr = target.ptr
    _forbid_upload_of(monkeypatch, be, u)  # the operator's CSR arrays are uploaded
    _forbid(monkeypatch, be, "download")
    for _ in range(3):
        got = rdgpu.diffusion_step(w, D=0.2, dt=0.5, steps=2, backend=be, out=target)
        assert got is target and target.ptr == ptr
    monkeypatch.undo()
    assert np.array_equal(target.numpy(), rdgpu.diffusion_step(u, D=0.2, dt=0.5, steps=2,
                                                               backend=be))


def test_pyopencl_out_on_the_backend_context(monkeypatch):
    be = backend_or_skip("opencl")
    cla = pytest.importorskip("pyopencl.array")
    u, _ = _fields(dtype=np.float32)
    du = cla.to_device(be.queue, u)
    target = cla.empty(be.queue, u.shape, np.float32)
    _forbid(monkeypatch, be, "upload", "download")
    assert rdgpu.laplacian(du, backend=be, out=target) is target
    monkeypatch.undo()
    assert np.array_equal(target.get(), rdgpu.laplacian(u, backend=be))


def test_out_on_the_device_is_written_by_the_kernel(monkeypatch):
    be = backend_or_skip("warp")
    u, v = _fields()
    wu, wv = wp.array(u, device="cpu"), wp.array(v, device="cpu")
    uo, vo = wp.empty_like(wu), wp.empty_like(wv)
    seen = _spy(monkeypatch, be, "gray_scott")
    _forbid(monkeypatch, be, "copy", "upload", "download")  # no copy, not even on the device
    rdgpu.gray_scott(wu, wv, steps=3, backend=be, out=(uo, vo), **GS)
    assert (seen[-1][2].handle.ptr, seen[-1][3].handle.ptr) == (uo.ptr, vo.ptr)
    assert all(a.handle.ptr not in (uo.ptr, vo.ptr) for call in seen[:-1] for a in call)
    monkeypatch.undo()
    eu, ev = rdgpu.gray_scott(u, v, steps=3, backend="numpy", **GS)
    assert np.array_equal(uo.numpy(), eu) and np.array_equal(vo.numpy(), ev)


@pytest.mark.parametrize("name", ["numpy", "warp"])
def test_out_overlapping_the_input(name):
    be = backend_or_skip(name)
    u, _ = _fields()
    want = rdgpu.laplacian(u, backend="numpy")
    big = np.zeros((u.shape[0] + 2, u.shape[1]))
    big[:-2] = u
    got = rdgpu.laplacian(big[:-2], backend=be, out=big[2:])
    assert np.shares_memory(got, big)
    assert np.array_equal(big[2:], want)


@pytest.mark.parametrize("name", ["numpy", "warp"])
def test_out_may_be_a_cpu_dlpack_array(name):
    be = backend_or_skip(name)
    u, _ = _fields()
    target = np.empty_like(u)
    out = _DLPackOnly(target)
    assert rdgpu.bernoulli_substep(u, tau=0.2, eps=0.5, backend=be, out=out) is out
    assert np.array_equal(target, rdgpu.bernoulli_substep(u, tau=0.2, eps=0.5, backend=be))


def test_out_may_be_the_input():
    u, _ = _fields()
    want = rdgpu.laplacian(u, backend="numpy")
    a = u.copy()
    assert rdgpu.laplacian(a, backend="numpy", out=a) is a
    assert np.array_equal(a, want)


def test_out_of_the_wrong_shape_dtype_or_kind_is_an_error():
    u, v = _fields()
    with pytest.raises(ValueError, match=r"out has shape \(3, 3\); the result has shape"):
        rdgpu.laplacian(u, out=np.empty((3, 3)), backend="numpy")
    with pytest.raises(TypeError, match="out has dtype float32; the result has dtype float64"):
        rdgpu.laplacian(u, out=np.empty(u.shape, np.float32), backend="numpy")
    with pytest.raises(TypeError, match="out must be an array that can receive"):
        rdgpu.laplacian(u, out=u.tolist(), backend="numpy")
    frozen = np.empty_like(u)
    frozen.flags.writeable = False
    with pytest.raises(ValueError, match="read-only"):
        rdgpu.laplacian(u, out=frozen, backend="numpy")
    with pytest.raises(TypeError, match=r"out must be a pair \(u_out, v_out\)"):
        rdgpu.gray_scott(u, v, out=np.empty_like(u), backend="numpy", **GS)
    with pytest.raises(ValueError, match="out has shape"):
        rdgpu.spmv(__import__("scipy.sparse").sparse.eye(4), np.ones(4), backend="numpy",
                   out=np.empty(3))


# ---------------------------------------------------------------------------- copies
@pytest.mark.parametrize("name", ["numpy", "warp", "opencl"])
def test_non_contiguous_inputs_are_copied_and_correct(name):
    be = backend_or_skip(name)
    big, _ = _fields(shape=(12, 32))
    view = big[:, ::2]
    want = rdgpu.laplacian(np.ascontiguousarray(view), backend="numpy")
    np.testing.assert_allclose(rdgpu.laplacian(view, backend=be), want, rtol=1e-12, atol=0)
    wview = wp.array(big, device="cpu")[:, ::2]
    assert not wview.is_contiguous
    got = rdgpu.laplacian(wview, backend=be)
    assert isinstance(got, wp.array)
    np.testing.assert_allclose(got.numpy(), want, rtol=1e-12, atol=0)


def test_steps_zero_returns_a_new_array():
    be = backend_or_skip("warp")
    u, _ = _fields()
    w = wp.array(u, device="cpu")
    got = rdgpu.diffusion_step(w, D=0.1, dt=0.5, steps=0, backend=be)
    assert got.ptr != w.ptr and np.array_equal(got.numpy(), u)


def test_wrong_inputs_give_clear_errors():
    with pytest.raises(TypeError, match="u must be a NumPy array, got str"):
        rdgpu.laplacian("abc", backend="numpy")
    ints = wp.array(np.ones((4, 4), np.int32), device="cpu")
    with pytest.raises(TypeError, match="unsupported dtype int32; allowed: float32, float64"):
        rdgpu.laplacian(ints, backend="warp")
    bad = wp.array(np.full((4, 4), np.nan), device="cpu")
    with pytest.raises(ValueError, match="NaN or Inf"):
        rdgpu.laplacian(bad, backend="warp")


# ---------------------------------------------------------------------------- Simulation
def test_simulation_takes_any_array_kind():
    g = Grid((16, 16))
    u, v = _fields(shape=(16, 16))
    F = np.full((16, 16), 0.03)
    ref = Simulation("gray-scott", g, {"F": F}, dt=0.5, backend="numpy",
                     fields={"u": u, "v": v}).run(4)
    sim = Simulation("gray-scott", g, {"F": wp.array(F, device="cpu")}, dt=0.5,
                     backend="numpy", fields={"u": wp.array(u, device="cpu"),
                                              "v": v.tolist()})
    got = sim.run(4)
    for s in ("u", "v"):
        assert isinstance(got.fields[s], np.ndarray)
        assert np.array_equal(got.fields[s], ref.fields[s])


# ---------------------------------------------------------------------------- torch
def test_torch_tensors_come_back_as_tensors():
    torch = pytest.importorskip("torch")
    u, v = _fields()
    tu, tv = torch.from_numpy(u), torch.from_numpy(v)
    ru, rv = rdgpu.gray_scott(tu, tv, steps=2, backend="numpy", **GS)
    eu, _ = rdgpu.gray_scott(u, v, steps=2, backend="numpy", **GS)
    assert isinstance(ru, torch.Tensor) and ru.device == tu.device
    assert np.array_equal(ru.numpy(), eu)
    target = torch.empty_like(tu)
    assert rdgpu.laplacian(tu, backend="warp", out=target) is target


# ---------------------------------------------------------------------------- CUDA
def _cuda_devices() -> int:
    wp.config.quiet = True
    wp.init()
    return wp.get_cuda_device_count()


needs_cuda = pytest.mark.skipif(
    _cuda_devices() == 0, reason="no CUDA device: the Warp CUDA paths run on a machine with a GPU")


@needs_cuda
def test_warp_cuda_array_is_used_in_place(monkeypatch):
    be = rdgpu.get_backend("warp:cuda:0")
    u, v = _fields(dtype=np.float32)
    wu, wv = wp.array(u, device="cuda:0"), wp.array(v, device="cuda:0")
    seen = _spy(monkeypatch, be, "gray_scott")
    _forbid(monkeypatch, be, "upload", "download")
    ru, rv = rdgpu.gray_scott(wu, wv, steps=3, backend=be, **GS)
    assert (seen[0][0].handle.ptr, seen[0][1].handle.ptr) == (wu.ptr, wv.ptr)
    assert isinstance(ru, wp.array) and ru.device == wu.device
    monkeypatch.undo()
    eu, _ = rdgpu.gray_scott(u, v, steps=3, backend="numpy", **GS)
    np.testing.assert_allclose(ru.numpy(), eu, rtol=0, atol=1e-5)


@needs_cuda
def test_warp_cuda_out_and_cpu_input():
    be = rdgpu.get_backend("warp:cuda:0")
    u, _ = _fields()
    target = wp.empty(u.shape, dtype=wp.float64, device="cuda:0")
    got = rdgpu.laplacian(u, backend=be, out=target)
    assert got is target
    np.testing.assert_allclose(target.numpy(), rdgpu.laplacian(u, backend="numpy"),
                               rtol=1e-12, atol=1e-12)
    wc = wp.array(u, device="cuda:0")
    on_cpu = rdgpu.laplacian(wc, backend="numpy")  # one copy to the host, back as CUDA
    assert isinstance(on_cpu, wp.array) and on_cpu.device == wc.device
