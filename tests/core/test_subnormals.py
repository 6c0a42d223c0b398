"""Subnormal numbers are flushed to zero on every backend and in the references (SPEC).

Each kernel family gets inputs (all normal numbers) whose exact result is subnormal at
some cells; every backend and launch shape must write exactly 0 there, write no subnormal
anywhere and agree with the NumPy reference.  The inputs are built so that every
intermediate result is normal or exactly 0 (or ends up below the result's last bit), so a
device that also flushes intermediate results (FTZ/DAZ on a CPU) computes the same thing as
one that does not (a GPU, the reference).  With ``t`` the smallest normal number:

* Laplacian: a field of ``4t``/``4.25t`` stripes (differences ``0.5t``), ``dx = dy = 1``;
* Gray-Scott: ``v = 64t``, ``F + k = 1 − 2⁻⁸``, ``dt = 1``: ``v' = 64t − 63.75t = 0.25t``;
* Bernoulli: ``u = 2t`` with ``decay = 16``: ``2t/4``;
* level sets: a front cell ``1.5t`` (step, speed ``t``) or ``3t`` relaxed by ``2.25t``
  (reinitialisation, Russo-Smereka fix);
* SOR (grid and CSR), SpMV, mesh Gray-Scott / diffusion, generated reaction kernels:
  sums of a few ``±0.25t``-sized pieces that cancel to ``0.5t`` or less.

Then: the Warp CPU kernels switch FTZ/DAZ on only inside their bodies, so the calling
thread's floating-point state is untouched; and :mod:`rdgpu.core.fpenv`.
"""

import os
import platform
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import scipy.sparse as sp
from conftest import backend_or_skip, tolerance

import rdgpu
from rdgpu.core.fpenv import flush_subnormals, smallest_normal
from rdgpu.domains.boundary import parse_bc
from rdgpu.domains.grid import Grid
from rdgpu.families import load_module
from rdgpu.models import define_model


@pytest.fixture
def be(variant_backend):
    """Every backend, and the GPU launch shapes run on the CPU: Warp's one-thread-per-cell
    kernels (which do not set FTZ/DAZ) and OpenCL's strided layout."""
    return variant_backend


def ref(family):
    return load_module(family, "reference.py")


def no_subnormal(a: np.ndarray) -> None:
    """No value of ``a`` is subnormal (0, normal numbers, inf and NaN only)."""
    a = np.asarray(a)
    bad = (a != 0) & (np.abs(a) < np.finfo(a.dtype).tiny)
    assert not bad.any(), f"{int(bad.sum())} subnormal values, e.g. {a[bad][:4]}"


def check(got: np.ndarray, want: np.ndarray, zero: np.ndarray | None, scale: float = 1.0):
    """``got`` is exactly 0 where ``zero``, has no subnormal, and matches the reference."""
    assert got.dtype == want.dtype and got.shape == want.shape
    no_subnormal(got)
    no_subnormal(want)
    if zero is not None:
        assert zero.any()
        np.testing.assert_array_equal(got[zero], 0)
        np.testing.assert_array_equal(want[zero], 0)
    np.testing.assert_allclose(got, want, **tolerance(got.dtype, scale))


# ---------------------------------------------------------------------------- grids
@pytest.mark.parametrize("stencil", [5, 9])
def test_laplacian(be, dtype, stencil):
    t = smallest_normal(dtype)
    u = np.tile(np.array([4.0, 4.25] * 4) * t, (5, 1)).astype(dtype)  # exact multiples of t
    bc = parse_bc("periodic")
    d_u, out = be.upload(u), be.empty(u.shape, dtype)
    be.laplacian(d_u, out, dx=1.0, dy=1.0, bc=bc, stencil=stencil)
    want = ref("laplacian").laplacian(u, 1.0, 1.0, bc, stencil)
    check(out.numpy(), want, np.ones(u.shape, bool))


def gray_scott_inputs(dtype):
    """v = 0.25 in columns 0-3 (normal results), 64t elsewhere (0.25t results where all
    four neighbours are 64t too, i.e. columns 5-14)."""
    t = smallest_normal(dtype)
    u = np.ones((6, 16), dtype)
    v = np.full((6, 16), 64 * t, dtype)
    v[:, :4] = 0.25
    zero = np.zeros(v.shape, bool)
    zero[:, 5:15] = True
    return u, v, zero


GS = dict(Du=0.1, Dv=0.05, F=0.5, k=0.5 - 2.0**-8, dt=1.0)


def test_gray_scott(be, dtype):
    u, v, zero = gray_scott_inputs(dtype)
    bc = parse_bc("periodic")
    du, dv = be.upload(u), be.upload(v)
    uo, vo = be.empty(u.shape, dtype), be.empty(u.shape, dtype)
    be.gray_scott(du, dv, uo, vo, dx=1.0, dy=1.0, bc=bc, **GS)
    want_u, want_v = ref("gray_scott").gray_scott_step(
        u, v, GS["Du"], GS["Dv"], GS["F"], GS["k"], GS["dt"], 1.0, 1.0, bc
    )
    check(uo.numpy(), want_u, None)
    check(vo.numpy(), want_v, zero)


def test_gray_scott_api(be, dtype):
    """The functional API over several steps (ping-pong buffers)."""
    u, v, _ = gray_scott_inputs(dtype)
    got_u, got_v = rdgpu.gray_scott(u, v, steps=3, backend=be, **GS)
    want_u, want_v = u, v
    for _ in range(3):
        want_u, want_v = ref("gray_scott").gray_scott_step(
            want_u, want_v, GS["Du"], GS["Dv"], GS["F"], GS["k"], GS["dt"], 1.0, 1.0,
            parse_bc("periodic"),
        )
    no_subnormal(got_u)
    no_subnormal(got_v)
    np.testing.assert_array_equal(got_v[:, 7:13], 0)
    np.testing.assert_allclose(got_v, want_v, **tolerance(dtype))


def test_bernoulli(be, dtype):
    t = smallest_normal(dtype)
    u = np.array([2 * t, -2 * t, 0.5, -0.5, 4 * t, 1.0], dtype)  # 4t/4 = t stays
    zero = np.array([True, True, False, False, False, False])
    d_u, out = be.upload(u), be.empty(u.shape, dtype)
    be.bernoulli(d_u, out, decay=16.0)
    got = out.numpy()
    check(got, ref("bernoulli").bernoulli(u, 16.0), zero)
    assert got[4] == dtype.type(t)


def front_row(dtype, centre: float) -> np.ndarray:
    """3 equal rows ``[−3, −2, −1, centre, 1, 2, 3, 4]``."""
    return np.tile(np.array([-3.0, -2.0, -1.0, centre, 1.0, 2.0, 3.0, 4.0]), (3, 1)).astype(dtype)


def test_levelset_step(be, dtype):
    t = smallest_normal(dtype)
    phi = front_row(dtype, 1.5 * t)  # 1.5t − 1·(t·1) = 0.5t
    bc = parse_bc(("periodic", "neumann"))
    d_phi, out = be.upload(phi), be.empty(phi.shape, dtype)
    be.levelset_step(d_phi, t, out, dt=1.0, dx=1.0, dy=1.0, bc=bc)
    zero = np.zeros(phi.shape, bool)
    zero[:, 3] = True
    check(out.numpy(), ref("levelset").levelset_step(phi, t, 1.0, 1.0, 1.0, bc), zero, 4.0)


def test_reinit_step(be, dtype):
    t = smallest_normal(dtype)
    phi0 = front_row(dtype, 1.5 * t)
    phi = front_row(dtype, 3 * t)  # front cell: 3t − 1.5 (3t − 1.5t/1) = 0.75t
    bc = parse_bc(("periodic", "neumann"))
    d_phi, d_phi0, out = be.upload(phi), be.upload(phi0), be.empty(phi.shape, dtype)
    be.reinit_step(d_phi, d_phi0, out, dtau=1.5, width=1.0, dx=1.0, dy=1.0, bc=bc)
    want = ref("levelset").reinit_step(phi, phi0, 1.5, 1.0, 1.0, 1.0, bc, True)
    zero = np.zeros(phi.shape, bool)
    zero[:, 3] = True
    check(out.numpy(), want, zero, 8.0)


def test_sor_half_sweep(be, dtype):
    """All cells 2t, dx = dy = 1, ω = 1: the red cells become ``2t − f/4``: 0.5t (→ 0,
    change 2t) in even rows where f = 6t, 1.5t (change 0.5t → 0) in odd rows where f = 2t."""
    t = smallest_normal(dtype)
    shape = (4, 6)
    c = np.full(shape, 2 * t, dtype)
    rhs = np.full(shape, 2 * t, dtype)
    rhs[::2] = 6 * t
    fixed = np.zeros(shape, np.uint8)
    bc = parse_bc("neumann")
    dc, dfixed, drhs = be.upload(c), be.upload(fixed), be.upload(rhs)
    change = be.upload(np.full(shape[0], np.nan, dtype))
    be.sor_half_sweep(dc, dfixed, drhs, change, color=0, omega=1.0, dx=1.0, dy=1.0, bc=bc)
    want, want_change = ref("sor").sor_half_sweep(c, fixed, rhs, 0, 1.0, 1.0, 1.0, bc)
    red = ref("sor").colour_mask(shape, 0)
    zero = red.copy()
    zero[1::2] = False
    check(dc.numpy(), want, zero)
    got_change = change.numpy()
    check(got_change, want_change, np.array([False, True, False, True]))
    np.testing.assert_array_equal(got_change[::2], dtype.type(2 * t))


# ---------------------------------------------------------------------------- CSR
def ring(n: int, off: float, diag: float) -> sp.csr_matrix:
    """The periodic 1-D stencil ``[off, diag, off]`` on ``n >= 3`` points."""
    i = np.arange(n)
    rows = np.concatenate([i, i, i])
    cols = np.concatenate([(i - 1) % n, i, (i + 1) % n])
    data = np.concatenate([np.full(n, off), np.full(n, diag), np.full(n, off)])
    m = sp.csr_matrix((data, (rows, cols)), shape=(n, n))
    m.sort_indices()
    return m


def csr_arrays(m, dtype):
    m = sp.csr_matrix(m)
    m.sort_indices()
    return m.indptr.astype(np.int32), m.indices.astype(np.int32), m.data.astype(dtype)


def test_spmv(be, dtype):
    t = smallest_normal(dtype)
    q = 0.25
    dense = np.array([
        [q, 0, 0, 0, 0, 0],     # 0.25t
        [q, q, 0, 0, 0, 0],     # 0.5t
        [q, q, q, 0, 0, 0],     # 0.75t
        [q, 0, 0, 1, 0, 0],     # 1 + 0.25t = 1
        [0, 0, 0, 0.5, 0.5, 0],  # 1.5
        [0, 0, 0, 0, 0, 4],     # 4t
    ])
    x = np.array([t, t, t, 1.0, 2.0, t], dtype)
    A = sp.csr_matrix(dense)
    dx, y = be.upload(x), be.empty((6,), dtype)
    be.spmv(be.upload_csr(A, dtype), dx, y)
    want = ref("mesh").spmv(*csr_arrays(A, dtype), x, A.shape)
    check(y.numpy(), want, np.array([True, True, True, False, False, False]), 4.0)


def test_mesh_gray_scott(be, dtype):
    t = smallest_normal(dtype)
    L = ring(8, 1.0, -2.0)  # a uniform field has L v = 0 exactly
    u = np.ones(8, dtype)
    v = np.full(8, 64 * t, dtype)
    dL = be.upload_csr(L, dtype)
    du, dv, uo, vo = be.upload(u), be.upload(v), be.empty((8,), dtype), be.empty((8,), dtype)
    be.mesh_gray_scott(dL, du, dv, uo, vo, Du=GS["Du"], Dv=GS["Dv"], F=GS["F"], k=GS["k"],
                       dt=GS["dt"])
    want_u, want_v = ref("mesh").mesh_gray_scott(
        *csr_arrays(L, dtype), u, v, GS["Du"], GS["Dv"], GS["F"], GS["k"], GS["dt"]
    )
    check(uo.numpy(), want_u, None)
    check(vo.numpy(), want_v, np.ones(8, bool))


def test_mesh_diffusion(be, dtype):
    t = smallest_normal(dtype)
    L = ring(8, 1.0, -2.0)
    u = np.full(8, 2 * t, dtype)
    u[0] = 1.0
    zero = np.ones(8, bool)
    zero[[7, 0, 1]] = False
    du, out = be.upload(u), be.empty((8,), dtype)
    be.mesh_diffusion(be.upload_csr(L, dtype), du, out, D=0.3, dt=1.0, source=-1.5 * t)
    want = ref("mesh").mesh_diffusion(*csr_arrays(L, dtype), u, 0.3, 1.0, -1.5 * t)
    check(out.numpy(), want, zero, 4.0)


def test_csr_sor_colour(be, dtype):
    """x = 2t, off-diagonals −0.75: σ = −3t; rhs −2.5t gives x = 0.5t (→ 0, change 2t),
    rhs −1.5t gives x = 1.5t (change 0.5t → 0)."""
    t = smallest_normal(dtype)
    A = ring(8, -0.75, 1.0)
    x = np.full(8, 2 * t, dtype)
    rhs = np.where(np.arange(8) % 4 == 0, -2.5 * t, -1.5 * t).astype(dtype)
    rows = np.arange(0, 8, 2, dtype=np.int32)
    dA = be.upload_csr(A, dtype)
    dx, drhs, drows = be.upload(x), be.upload(rhs), be.upload(rows)
    change = be.upload(np.full(8, -1.0, dtype))
    be.csr_sor_colour(dA, dx, drhs, drows, change, omega=1.0)
    want, want_change = ref("mesh").csr_sor_colour(
        *csr_arrays(A, dtype), A.diagonal().astype(dtype), x, rhs, rows, 1.0
    )
    want_change = np.where(np.isnan(want_change), dtype.type(-1), want_change)
    check(dx.numpy(), want, np.arange(8) % 4 == 0)
    check(change.numpy(), want_change, np.arange(8) % 4 == 2)


def test_generated_model_kernel(be, dtype):
    """Generated step ``u' = u + dt (−a u + 1e-310·1e10)`` with a = 0.75: 2t − 1.5t = 0.5t.
    A literal that is subnormal in the dtype is 0 in every backend (1e-310 is subnormal in
    float64, 0 in float32), so the last term is 0, not 1e-300."""
    t = smallest_normal(dtype)
    model = define_model("flush", {"u": "-a*u + 1e-310*1e10"}, {"a": 0.75})
    u = np.array([[2 * t, 1.0, 2 * t], [0.5, 2 * t, 3.0]], dtype)
    grid = Grid(u.shape, bc="neumann")
    got, want = (_one_step(model, grid, u, b, dtype) for b in (be, "numpy"))
    check(got, want, u == dtype.type(2 * t))


def _one_step(model, domain, u, backend, dtype):
    st = model.stepper(domain, {}, dt=1.0, backend=backend, dtype=dtype)
    st.set_state({"u": u})
    st.advance(1)
    return st.get_state()["u"]


# ---------------------------------------------------------------------------- thread state
_X86 = platform.machine().lower() in ("x86_64", "amd64", "i386", "i686")


def _mxcsr_reader():
    """A Warp CPU kernel that stores the executing thread's MXCSR (the calling thread).
    (This file has no ``from __future__ import annotations``: Warp evaluates the kernel's
    annotations, and ``wp`` is local here.)"""
    wp = pytest.importorskip("warp")
    if getattr(_mxcsr_reader, "kernel", None) is None:

        @wp.func_native(
            "#if !defined(__CUDA_ARCH__) && (defined(__x86_64__) || defined(__i386__))\n"
            "    return (int)__builtin_ia32_stmxcsr();\n"
            "#else\n"
            "    return -1;\n"
            "#endif\n"
        )
        def read_mxcsr() -> int: ...

        @wp.kernel
        def store_mxcsr(out: wp.array(dtype=wp.int32)):
            out[0] = read_mxcsr()

        _mxcsr_reader.kernel = store_mxcsr
    kernel = _mxcsr_reader.kernel

    def read() -> int:
        out = wp.zeros(1, dtype=wp.int32, device="cpu")
        wp.launch(kernel, dim=1, inputs=[out], device="cpu")
        return int(out.numpy()[0])

    return read


FTZ_DAZ = 0x8040
CONTROL_BITS = ~0x3F  # MXCSR without its sticky exception flags


def _run_every_family(be, dtype) -> None:
    """One call of each Warp kernel kind on a grid small enough to run in this thread, and
    one large enough to be cut into chunks that run on the pool threads too."""
    for shape in ((5, 8), (300, 260)):
        rng = np.random.default_rng(0)
        u = rng.uniform(0.1, 0.9, shape).astype(dtype)
        bc = parse_bc("neumann")
        du, out, out2 = be.upload(u), be.empty(shape, dtype), be.empty(shape, dtype)
        be.laplacian(du, out, dx=1.0, dy=1.0, bc=bc, stencil=5)
        be.bernoulli(du, out, decay=0.5)
        be.gray_scott(du, du, out, out2, Du=0.1, Dv=0.05, F=0.04, k=0.06, dt=1.0, dx=1.0,
                      dy=1.0, bc=bc)
        be.levelset_step(du, 0.5, out, dt=0.1, dx=1.0, dy=1.0, bc=bc)
        be.reinit_step(du, du, out, dtau=0.3, width=1.0, dx=1.0, dy=1.0, bc=bc)
        be.sor_half_sweep(be.upload(u), be.upload(np.zeros(shape, np.uint8)), None,
                          be.empty((shape[0],), dtype), color=0, omega=1.5, dx=1.0, dy=1.0,
                          bc=bc)
        n = u.size
        L = be.upload_csr(ring(n, 1.0, -2.0), dtype)
        flat = be.upload(u.ravel())
        be.spmv(L, flat, be.empty((n,), dtype))
        be.mesh_diffusion(L, flat, be.empty((n,), dtype), D=0.1, dt=0.1)
        _one_step(define_model("decay", {"u": "-u"}), Grid(shape), u, be, dtype)
    be.synchronize()


@pytest.mark.skipif(not _X86, reason="MXCSR is x86 only")
@pytest.mark.parametrize("launch", ["auto", "cells"])
def test_warp_leaves_thread_fp_state(launch):
    """The row/block kernels switch FTZ/DAZ on inside their bodies and restore the thread's
    MXCSR at their end: the calling thread's control bits are the same after the calls."""
    from rdgpu.backends.warp_backend import WarpBackend

    read = _mxcsr_reader()
    be = WarpBackend("cpu", launch=launch)
    before = read()
    if before & FTZ_DAZ:
        pytest.skip(f"FTZ/DAZ already set in this thread by something else: {before:#x}")
    for dtype in (np.float32, np.float64):
        _run_every_family(be, np.dtype(dtype))
        after = read()
        assert after & CONTROL_BITS == before & CONTROL_BITS, f"{before:#x} -> {after:#x}"


@pytest.mark.parametrize("name", ["numpy", "warp", "opencl"])
def test_user_thread_keeps_subnormals(name):
    """After rdgpu calls, plain NumPy in the same thread still computes subnormals (no FTZ
    leaked into the caller) and still reads them (no DAZ)."""
    be = backend_or_skip(name)
    for dtype in (np.float32, np.float64):
        _run_every_family(be, np.dtype(dtype))
        rdgpu.gray_scott(*gray_scott_inputs(dtype)[:2], backend=name, **GS)
    assert np.float32(1e-38) / np.float32(10) != 0  # FTZ would give 0
    assert np.float64(1e-308) / np.float64(10) != 0
    assert np.float32(1e-40) * np.float32(2) != 0  # DAZ would read 1e-40 as 0
    assert np.float64(1e-310) * np.float64(2) != 0


# ---------------------------------------------------------------------------- rdgpu.core.fpenv
def test_fpenv():
    assert smallest_normal(np.float32) == float(np.finfo(np.float32).tiny)
    assert smallest_normal("float64") == float(np.finfo(np.float64).tiny)
    a = np.array([1.0, 0.0, -0.0, np.finfo(np.float32).tiny, np.inf, np.nan], np.float32)
    assert flush_subnormals(a) is a  # no subnormal: the array itself, no copy
    ints = np.arange(4)
    assert flush_subnormals(ints) is ints
    b = np.array([1e-40, -1e-40, 1.0, np.nan, 1e-30], np.float32)
    before = b.copy()
    f = flush_subnormals(b)
    assert f is not b and f.dtype == b.dtype
    np.testing.assert_array_equal(b, before)  # the input is not modified
    np.testing.assert_array_equal(f, np.array([0, 0, 1.0, np.nan, 1e-30], np.float32))
    assert not np.signbit(f[1])
    d = np.array([[5e-324, 1.0], [2.3e-308, -3e-310]])  # tiny = 2.2250738585e-308
    np.testing.assert_array_equal(flush_subnormals(d), [[0, 1.0], [2.3e-308, 0]])
    c = np.array([1e-310 + 1j, 1 + 1e-310j])
    np.testing.assert_array_equal(flush_subnormals(c), [1j, 1])


# ---------------------------------------------------------------------------- Warp verify_fp
_VERIFY_FP_SCRIPT = textwrap.dedent(
    """
    import numpy as np
    import warp as wp

    wp.config.verify_fp = True
    import rdgpu

    be = "warp"
    rng = np.random.default_rng(0)
    u = rng.uniform(0.1, 0.9, (24, 20))
    v = rng.uniform(0.0, 0.4, (24, 20))
    mesh = rdgpu.SurfaceMesh.icosphere(2)
    mu = rng.uniform(0.1, 0.9, mesh.n_vertices)
    mv = rng.uniform(0.0, 0.4, mesh.n_vertices)


    def poison():
        # freed NaN-filled blocks: a later uninitialised allocation may reuse them
        for n in (u.size, u.shape[0], mesh.n_vertices, mesh.laplacian.nnz):
            for dtype in (wp.float32, wp.float64):
                wp.full(n, float("nan"), dtype=dtype, device="cpu")


    calls = {
        "laplacian": lambda: rdgpu.laplacian(u, backend=be),
        "bernoulli": lambda: rdgpu.bernoulli_substep(u, tau=0.01, eps=0.3, backend=be),
        "gray_scott": lambda: rdgpu.gray_scott(
            u, v, Du=0.1, Dv=0.05, F=0.04, k=0.06, dt=1.0, steps=3, backend=be),
        "sor_sweep": lambda: rdgpu.sor_sweep(u, u > 0.8, omega=1.5, backend=be),
        "levelset_advance": lambda: rdgpu.levelset_advance(
            u - 0.5, 1.0, dt=0.1, steps=3, backend=be),
        "reinitialize": lambda: rdgpu.reinitialize(u - 0.5, iterations=3, backend=be),
        "spmv": lambda: rdgpu.spmv(mesh.laplacian, mu, backend=be),
        "mesh gray_scott": lambda: rdgpu.gray_scott(
            mu, mv, Du=0.01, Dv=0.005, F=0.04, k=0.06, dt=0.1, steps=3, mesh=mesh,
            backend=be),
        "diffusion_step": lambda: rdgpu.diffusion_step(u, D=0.1, dt=0.5, steps=3, backend=be),
        "mesh diffusion_step": lambda: rdgpu.diffusion_step(
            mu, D=0.01, dt=0.1, steps=3, mesh=mesh, backend=be),
    }
    for dtype in (np.float32, np.float64):
        u, v, mu, mv = (a.astype(dtype) for a in (u, v, mu, mv))
        for name, call in calls.items():
            poison()
            out = call()
            out = out[0] if isinstance(out, tuple) else out
            assert np.isfinite(out).all(), name
            print("OK", name, np.dtype(dtype).name, flush=True)
    """
)


def test_warp_verify_fp():
    """Every family runs clean under ``wp.config.verify_fp`` (which checks every value a
    kernel loads and the old value of every element it stores to): no kernel touches
    uninitialised memory.  In a subprocess: verify_fp changes the module hashes (a full
    recompile), and a failed check aborts the process on CUDA (prints, on the CPU)."""
    pytest.importorskip("warp")
    backend_or_skip("warp")
    env = dict(os.environ)
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    env["PYTHONPATH"] = os.pathsep.join(p for p in (root, env.get("PYTHONPATH")) if p)
    proc = subprocess.run(
        [sys.executable, "-c", _VERIFY_FP_SCRIPT], env=env, capture_output=True, text=True,
        timeout=1200,
    )
    output = proc.stdout + proc.stderr
    assert proc.returncode == 0, output[-3000:]
    assert output.count("OK ") == 20, output[-3000:]
    # a failed check prints "<file>:<line> - index(arr, i, j) nan)" (and asserts on CUDA)
    assert "(arr" not in output, output[-3000:]


# ---------------------------------------------------------------------------- CUDA code
def test_warp_cuda_code_compiles():
    """The CUDA build of every Warp family (and of generated model kernels on a grid and a
    mesh) compiles --
    the FTZ/DAZ snippets compile to nothing under nvrtc -- and flushes explicitly: its PTX
    compares with the smallest normal float32 (0f00800000) and float64
    (0d0010000000000000).  Needs only NVRTC (shipped with Warp), no GPU.  The PTX goes to
    the rdgpu cache folder, where Warp finds it again while the sources are unchanged."""
    wp = pytest.importorskip("warp")
    backend_or_skip("warp")
    archs = list(getattr(wp, "get_cuda_supported_archs", lambda: [])() or [])
    if not hasattr(wp, "compile_aot_module") or not archs:
        pytest.skip("this Warp cannot compile CUDA code here (no NVRTC)")
    from rdgpu.backends.warp_backend import WarpBackend
    from rdgpu.backends.warp_codegen import cache_dir, warp_module, warp_source
    from rdgpu.models import MODELS

    arch = 90 if 90 in archs else archs[0]
    cpu = WarpBackend("cpu")
    modules = {f: load_module(f, "warp_kernels.py")
               for f in ("laplacian", "bernoulli", "gray_scott", "sor", "levelset", "mesh")}
    program = MODELS["gray-scott"].stepper(Grid((4, 4)), {}, dt=1.0, backend="numpy")._euler
    for dtype in (np.float32, np.float64):
        for kind in ("grid3", "grid2iso", "mesh"):
            src = warp_source(program, kind, frozenset({"F"}), dtype)
            modules[f"model-{kind}-{np.dtype(dtype).name}"] = warp_module(src, cpu)
    for name, module in modules.items():
        paths = wp.compile_aot_module(
            module, arch=arch, module_dir=cache_dir() / "cuda-check" / name, use_ptx=True
        )
        ptx = b"".join(p.read_bytes() for p in paths if p.suffix == ".ptx")
        assert ptx, f"{name}: no PTX in {paths}"
        if not name.endswith("float64"):
            assert b"0f00800000" in ptx, f"{name}: no float32 flush"
        if not name.endswith("float32"):
            assert b"0d0010000000000000" in ptx, f"{name}: no float64 flush"
