"""The functional API: one call per kernel family on arrays of any library
(``rdgpu.laplacian``, ``rdgpu.gray_scott``, ...), and implicit diffusion."""
