"""The mesh family's Warp launchers (``warp_kernels.py``): ``(blocks, rows)`` kernel pairs
over the matrix rows through the backend's CSR row launch (``run_rows``: blocks of
``ROW_BLOCK`` rows per thread on the CPU, one row per thread on CUDA); vectors as flat
views (``flat``)."""

from __future__ import annotations

from rdgpu.families.mesh import check_csr, check_gray_scott, check_sor, vertex_field


def _csr(A) -> list:
    return [A.indptr.handle, A.indices.handle, A.data.handle]


def _param(rt, p, like, what: str):
    """``(value, is_field)`` of a per-vertex parameter: a flat array, or a number in
    like's dtype."""
    if vertex_field(p, like, what):
        return rt.flat(p), True
    return like.dtype.type(p), False


def spmv(rt, A, x, y) -> None:
    """``y = A x`` on the Warp backend ``rt``."""
    check_csr(A, x, y, "spmv")
    kernels = rt.module("mesh").SPMV[A.dtype]
    args = [*_csr(A), rt.flat(x), rt.flat(y)]
    rt.run_rows(kernels, A.shape[0], A.nnz, args)


def mesh_gray_scott(rt, L, u, v, u_out, v_out, *, Du, Dv, F, k, dt) -> None:
    """One mesh Gray-Scott step on the Warp backend ``rt``."""
    check_gray_scott(L, u, v, u_out, v_out)
    t = u.dtype.type
    f_val, f_field = _param(rt, F, u, "mesh_gray_scott F")
    k_val, k_field = _param(rt, k, u, "mesh_gray_scott k")
    kernels = rt.module("mesh").GRAY_SCOTT[(u.dtype, f_field, k_field)]
    args = [
        *_csr(L), rt.flat(u), rt.flat(v), rt.flat(u_out), rt.flat(v_out), f_val, k_val,
        t(Du), t(Dv), t(dt),
    ]
    rt.run_rows(kernels, L.shape[0], L.nnz, args)


def mesh_diffusion(rt, L, u, out, *, D, dt, source=0.0) -> None:
    """``out = u + dt (D (L u) + source)`` on the Warp backend ``rt``."""
    check_csr(L, u, out, "mesh_diffusion")
    t = u.dtype.type
    s_val, s_field = _param(rt, source, u, "mesh_diffusion source")
    kernels = rt.module("mesh").DIFFUSION[(u.dtype, s_field)]
    args = [*_csr(L), rt.flat(u), rt.flat(out), t(D), s_val, t(dt)]
    rt.run_rows(kernels, L.shape[0], L.nnz, args)


def csr_sor_colour(rt, A, x, rhs, rows, change, *, omega) -> None:
    """One colour of multicolour SOR on the Warp backend ``rt``."""
    check_sor(A, x, rhs, rows, change)
    t = x.dtype.type
    om = t(omega)
    kernels = rt.module("mesh").SOR[x.dtype]
    args = [
        *_csr(A), A.diagonal.handle, rt.flat(x), rt.flat(rhs), rows.handle, rt.flat(change),
        om, t(1) - om,
    ]
    n = rows.size
    # work: about nnz · n / n_rows matrix entries
    rt.run_rows(kernels, n, A.nnz * n // max(A.shape[0], 1), args)
