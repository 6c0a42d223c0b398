"""The OpenCL CSR (mesh) kernels: ``spmv``, ``mesh_gray_scott``, ``mesh_diffusion``,
``csr_sor_colour`` (a part of :class:`~rdgpu.backends.opencl_backend.OpenCLBackend`)."""

from __future__ import annotations

from rdgpu.backends.base import DeviceArray, FieldOrScalar

#: the Gray-Scott kernel for (F is a field, k is a field)
GS_NAMES = {
    (False, False): "gray_scott_ss",
    (True, False): "gray_scott_fs",
    (False, True): "gray_scott_sf",
    (True, True): "gray_scott_ff",
}


class OpenCLMeshKernels:
    """The CSR kernels of :class:`~rdgpu.backends.opencl_backend.OpenCLBackend` (a mixin):
    ``mesh/mesh.cl`` launched over matrix rows (``launch_rows``)."""

    @staticmethod
    def _csr_buffers(A) -> tuple:
        return A.indptr.handle, A.indices.handle, A.data.handle

    @staticmethod
    def _vertex_param(f: FieldOrScalar, u: DeviceArray, what: str):
        """``(is_field, buffer, scalar)`` for a number or a DeviceArray of u's size."""
        if isinstance(f, DeviceArray):
            if f.size != u.size or f.dtype != u.dtype:
                raise ValueError(
                    f"{what} field must have {u.size} elements of {u.dtype}, got {f.shape} "
                    f"{f.dtype}"
                )
            return True, f.handle, 0.0
        return False, u.handle, float(f)

    def spmv(self, A, x: DeviceArray, y: DeviceArray) -> None:
        self._check_csr(A, x, y, "spmv")
        self.check_on_device(A.data, x, y)
        kernel = self.kernels(A.dtype)["csr_spmv"]
        self.launch_rows(kernel, A.shape[0], (*self._csr_buffers(A), x.handle, y.handle))

    def mesh_gray_scott(
        self,
        L,
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
        self.check_on_device(L.data, u, v, u_out, v_out)
        f_field, f_buf, f_val = self._vertex_param(F, u, "F")
        k_field, k_buf, k_val = self._vertex_param(k, u, "k")
        name = "mesh_" + GS_NAMES[f_field, k_field]
        args = (
            *self._csr_buffers(L), u.handle, v.handle, u_out.handle, v_out.handle, f_buf,
            k_buf,
        )
        kernel = self.kernels(u.dtype)[name]
        self.launch_rows(kernel, L.shape[0], args, (Du, Dv, f_val, k_val, dt))

    def mesh_diffusion(
        self,
        L,
        u: DeviceArray,
        out: DeviceArray,
        *,
        D: float,
        dt: float,
        source: FieldOrScalar = 0.0,
    ) -> None:
        self._check_csr(L, u, out, "mesh_diffusion")
        self.check_on_device(L.data, u, out)
        s_field, s_buf, s_val = self._vertex_param(source, u, "source")
        kernel = self.kernels(u.dtype)["mesh_diffusion_f" if s_field else "mesh_diffusion_s"]
        self.launch_rows(
            kernel, L.shape[0], (*self._csr_buffers(L), u.handle, out.handle, s_buf),
            (D, s_val, dt),
        )

    def csr_sor_colour(
        self,
        A,
        x: DeviceArray,
        rhs: DeviceArray,
        rows: DeviceArray,
        change: DeviceArray,
        *,
        omega: float,
    ) -> None:
        self._check_sor(A, x, rhs, rows, change)
        self.check_on_device(A.data, x, rhs, change)
        t = x.dtype.type
        om = t(omega)
        kernel = self.kernels(x.dtype)["csr_sor_colour"]
        self.launch_rows(
            kernel, rows.size,
            (*self._csr_buffers(A), A.diagonal.handle, x.handle, rhs.handle, rows.handle,
             change.handle),
            (om, t(1) - om),
        )
