"""The argument types the OpenCL grid kernels share (``KERNEL_ARGS`` of the grid families'
``opencl.py``): B = buffer, i = int32, l = int64, r = the real type.  A 2-D grid kernel
takes ``nx, ny, y_kind, g_y, x_kind, g_x`` after its buffers, a 3-D one ``nx, ny, nz,
y_kind, g_y, x_kind, g_x, z_kind, g_z`` (the tuples the backend's ``grid``/``grid3`` give).
"""

from __future__ import annotations

#: nx, ny, y_kind, g_y, x_kind, g_x
GRID = "iiirir"
#: nx, ny, nz, y_kind, g_y, x_kind, g_x, z_kind, g_z
GRID3 = "iiiiririr"
