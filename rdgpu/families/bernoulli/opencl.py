"""The bernoulli family's OpenCL launcher (kernel ``bernoulli`` of ``bernoulli.cl``)."""

from __future__ import annotations

from rdgpu.families.bernoulli import check

#: argument types of the family's kernels (B buffer, i int32, l int64, r the real type):
#: declared, PyOpenCL packs scalars fast
KERNEL_ARGS = {"bernoulli": "BBllrr"}
#: elements per work-item in the row layout
CHUNK = 16384


def bernoulli(rt, u, out, *, decay: float) -> None:
    """``out = bernoulli(u)`` on the OpenCL backend ``rt``."""
    t = check(u, out)
    rt.check_on_device(u, out)
    n = u.size
    if n == 0:
        return
    d = t(decay)
    # fixed local sizes: PoCL compiles one work-group function per local size
    if rt.layout == "row":
        chunk, group = CHUNK, 1
    else:
        chunk, group = 1, rt.col_stride
    items = -(-n // chunk)
    rt.enqueue(rt.kernels(u.dtype)["bernoulli"], (u.handle, out.handle, n, chunk, d, t(1) - d),
               (-(-items // group) * group,), (group,))
