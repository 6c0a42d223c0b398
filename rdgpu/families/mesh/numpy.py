"""The mesh family on the NumPy backend: the references on host arrays, the vectors as
flat views of the handles."""

from __future__ import annotations

from rdgpu.families.mesh import check_csr, check_gray_scott, check_sor, vertex_field
from rdgpu.families.mesh import reference as _reference


def _csr(A) -> tuple:
    return A.indptr.handle, A.indices.handle, A.data.handle


def _flat(d):
    return d.handle.reshape(-1)


def _param(p, like, what: str):
    """A number, or the flat NumPy view of a field of like's size and dtype."""
    return _flat(p) if vertex_field(p, like, what) else float(p)


def spmv(rt, A, x, y) -> None:
    """``y = A x`` (see :mod:`rdgpu.families.mesh`)."""
    check_csr(A, x, y, "spmv")
    _flat(y)[...] = _reference.spmv(*_csr(A), _flat(x), A.shape)


def mesh_gray_scott(rt, L, u, v, u_out, v_out, *, Du, Dv, F, k, dt) -> None:
    """One mesh Gray-Scott step (see :mod:`rdgpu.families.mesh`)."""
    check_gray_scott(L, u, v, u_out, v_out)
    un, vn = _reference.mesh_gray_scott(
        *_csr(L), _flat(u), _flat(v), Du, Dv, _param(F, u, "mesh_gray_scott F"),
        _param(k, u, "mesh_gray_scott k"), dt
    )
    _flat(u_out)[...] = un
    _flat(v_out)[...] = vn


def mesh_diffusion(rt, L, u, out, *, D, dt, source=0.0) -> None:
    """``out = u + dt (D (L u) + source)`` (see :mod:`rdgpu.families.mesh`)."""
    check_csr(L, u, out, "mesh_diffusion")
    _flat(out)[...] = _reference.mesh_diffusion(
        *_csr(L), _flat(u), D, dt, _param(source, u, "mesh_diffusion source")
    )


def csr_sor_colour(rt, A, x, rhs, rows, change, *, omega) -> None:
    """One colour of multicolour SOR, in place on ``x`` (see :mod:`rdgpu.families.mesh`)."""
    check_sor(A, x, rhs, rows, change)
    r = rows.handle
    new, delta = _reference.csr_sor_colour(
        *_csr(A), A.diagonal.handle, _flat(x), _flat(rhs), r, omega
    )
    _flat(x)[r] = new[r]
    _flat(change)[r] = delta[r]
