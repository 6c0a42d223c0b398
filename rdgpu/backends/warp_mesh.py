"""The Warp CSR (mesh) kernels: ``spmv``, ``mesh_gray_scott``, ``mesh_diffusion``,
``csr_sor_colour`` (a part of :class:`~rdgpu.backends.warp_backend.WarpBackend`)."""

from __future__ import annotations

from rdgpu.backends.base import DeviceArray, DeviceCSR, FieldOrScalar
from rdgpu.backends.warp_runtime import ROW_BLOCK


class WarpMeshKernels:
    """The CSR kernels of :class:`~rdgpu.backends.warp_backend.WarpBackend` (a mixin):
    ``families/mesh/warp_kernels.py``, rows in blocks on the CPU, one row per thread on
    CUDA."""

    # ------------------------------------------------------------------ CSR / mesh kernels
    def _run_rows(self, kernels, n_rows: int, nnz: int, args: list) -> None:
        """Launch a ``(blocks, rows)`` CSR kernel pair over ``n_rows`` rows: one thread per
        row on CUDA; on the CPU one thread per ``ROW_BLOCK`` rows, in row chunks side by
        side (``run_split``) once the matrix is large."""
        if n_rows == 0:
            return
        blocks, rows = kernels
        if self.per_cell:
            self.launch(rows, n_rows, args, 0)
            return
        self.run_split(blocks, -(-n_rows // ROW_BLOCK), nnz + n_rows,
                        [*args, n_rows, ROW_BLOCK])

    def csr_handles(self, A: DeviceCSR) -> list:
        return [A.indptr.handle, A.indices.handle, A.data.handle]

    def _vparam(self, p: FieldOrScalar, like: DeviceArray, what: str):
        """``(value, is_field)`` of a per-vertex parameter: a flat array or a scalar."""
        if isinstance(p, DeviceArray):
            if p.size != like.size or p.dtype != like.dtype:
                raise ValueError(f"{what} field must have {like.size} elements of "
                                 f"{like.dtype}, got {p.shape} {p.dtype}")
            return self.flat(p), True
        return like.dtype.type(p), False

    def spmv(self, A: DeviceCSR, x: DeviceArray, y: DeviceArray) -> None:
        self._check_csr(A, x, y, "spmv")
        kernels = self.module("mesh").SPMV[A.dtype]
        args = [*self.csr_handles(A), self.flat(x), self.flat(y)]
        self._run_rows(kernels, A.shape[0], A.nnz, args)

    def mesh_gray_scott(
        self,
        L: DeviceCSR,
        u: DeviceArray,
        v: DeviceArray,
        u_out: DeviceArray,
        v_out: DeviceArray,
        *,
        Du: float,
        Dv: float,
        F: FieldOrScalar,
        k: FieldOrScalar,
        dt: float,
    ) -> None:
        for a in (u, v, u_out, v_out):
            self._check_csr(L, u, a, "mesh_gray_scott")
        t = u.dtype.type
        f_val, f_field = self._vparam(F, u, "mesh_gray_scott F")
        k_val, k_field = self._vparam(k, u, "mesh_gray_scott k")
        kernels = self.module("mesh").GRAY_SCOTT[(u.dtype, f_field, k_field)]
        args = [
            *self.csr_handles(L), self.flat(u), self.flat(v), self.flat(u_out),
            self.flat(v_out), f_val, k_val, t(Du), t(Dv), t(dt),
        ]
        self._run_rows(kernels, L.shape[0], L.nnz, args)

    def mesh_diffusion(
        self,
        L: DeviceCSR,
        u: DeviceArray,
        out: DeviceArray,
        *,
        D: float,
        dt: float,
        source: FieldOrScalar = 0.0,
    ) -> None:
        self._check_csr(L, u, out, "mesh_diffusion")
        t = u.dtype.type
        s_val, s_field = self._vparam(source, u, "mesh_diffusion source")
        kernels = self.module("mesh").DIFFUSION[(u.dtype, s_field)]
        args = [*self.csr_handles(L), self.flat(u), self.flat(out), t(D), s_val, t(dt)]
        self._run_rows(kernels, L.shape[0], L.nnz, args)

    def csr_sor_colour(
        self,
        A: DeviceCSR,
        x: DeviceArray,
        rhs: DeviceArray,
        rows: DeviceArray,
        change: DeviceArray,
        *,
        omega: float,
    ) -> None:
        self._check_sor(A, x, rhs, rows, change)
        t = x.dtype.type
        om = t(omega)
        kernels = self.module("mesh").SOR[x.dtype]
        args = [
            *self.csr_handles(A), A.diagonal.handle, self.flat(x), self.flat(rhs),
            rows.handle, self.flat(change), om, t(1) - om,
        ]
        n = rows.size
        # work: about nnz · n / n_rows matrix entries
        self._run_rows(kernels, n, A.nnz * n // max(A.shape[0], 1), args)
