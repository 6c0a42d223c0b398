"""The mesh family's OpenCL launchers (``mesh.cl``), over the backend's CSR row launch
(``launch_rows``: blocks of rows per work-item in the row layout, one row per work-item
otherwise)."""

from __future__ import annotations

from rdgpu.families.mesh import check_csr, check_gray_scott, check_sor, vertex_field

#: argument types of the family's kernels (B buffer, i int32, l int64, r the real type):
#: declared, PyOpenCL packs scalars fast
KERNEL_ARGS = {
    "csr_spmv": "BBBBBii",
    "mesh_gray_scott_ss": "BBBBBBBBBiirrrrr",
    "mesh_gray_scott_fs": "BBBBBBBBBiirrrrr",
    "mesh_gray_scott_sf": "BBBBBBBBBiirrrrr",
    "mesh_gray_scott_ff": "BBBBBBBBBiirrrrr",
    "mesh_diffusion_s": "BBBBBBiirrr",
    "mesh_diffusion_f": "BBBBBBiirrr",
    "csr_sor_colour": "BBBBBBBBiirr",
}
#: the mesh Gray-Scott kernel for (F is a field, k is a field)
GRAY_SCOTT = {
    (False, False): "mesh_gray_scott_ss",
    (True, False): "mesh_gray_scott_fs",
    (False, True): "mesh_gray_scott_sf",
    (True, True): "mesh_gray_scott_ff",
}


def _csr(A) -> tuple:
    return A.indptr.handle, A.indices.handle, A.data.handle


def _param(p, u, what: str):
    """``(is_field, buffer, scalar)`` for a number or a field of u's size."""
    if vertex_field(p, u, what):
        return True, p.handle, 0.0
    return False, u.handle, float(p)


def spmv(rt, A, x, y) -> None:
    """``y = A x`` on the OpenCL backend ``rt``."""
    check_csr(A, x, y, "spmv")
    rt.check_on_device(A.data, x, y)
    kernel = rt.kernels(A.dtype)["csr_spmv"]
    rt.launch_rows(kernel, A.shape[0], (*_csr(A), x.handle, y.handle))


def mesh_gray_scott(rt, L, u, v, u_out, v_out, *, Du, Dv, F, k, dt) -> None:
    """One mesh Gray-Scott step on the OpenCL backend ``rt``."""
    check_gray_scott(L, u, v, u_out, v_out)
    rt.check_on_device(L.data, u, v, u_out, v_out)
    f_field, f_buf, f_val = _param(F, u, "mesh_gray_scott F")
    k_field, k_buf, k_val = _param(k, u, "mesh_gray_scott k")
    args = (*_csr(L), u.handle, v.handle, u_out.handle, v_out.handle, f_buf, k_buf)
    kernel = rt.kernels(u.dtype)[GRAY_SCOTT[f_field, k_field]]
    rt.launch_rows(kernel, L.shape[0], args, (Du, Dv, f_val, k_val, dt))


def mesh_diffusion(rt, L, u, out, *, D, dt, source=0.0) -> None:
    """``out = u + dt (D (L u) + source)`` on the OpenCL backend ``rt``."""
    check_csr(L, u, out, "mesh_diffusion")
    rt.check_on_device(L.data, u, out)
    s_field, s_buf, s_val = _param(source, u, "mesh_diffusion source")
    kernel = rt.kernels(u.dtype)["mesh_diffusion_f" if s_field else "mesh_diffusion_s"]
    rt.launch_rows(kernel, L.shape[0], (*_csr(L), u.handle, out.handle, s_buf),
                   (D, s_val, dt))


def csr_sor_colour(rt, A, x, rhs, rows, change, *, omega) -> None:
    """One colour of multicolour SOR on the OpenCL backend ``rt``."""
    check_sor(A, x, rhs, rows, change)
    rt.check_on_device(A.data, x, rhs, change)
    t = x.dtype.type
    om = t(omega)
    kernel = rt.kernels(x.dtype)["csr_sor_colour"]
    rt.launch_rows(
        kernel, rows.size,
        (*_csr(A), A.diagonal.handle, x.handle, rhs.handle, rows.handle, change.handle),
        (om, t(1) - om),
    )
