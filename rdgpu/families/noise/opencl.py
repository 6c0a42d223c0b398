"""The noise family's OpenCL launcher: ``noise.cl`` is a program of its own, built after
``common.cl`` and the header ``philox.cl`` with the array's real type (the backend's
``own_program``); one work-item per pair of elements, in work-groups of ``GROUP`` (the
last one padded: the kernel skips pairs past the end)."""

from __future__ import annotations

from rdgpu.families.noise import check

#: argument types of the program's kernel (B buffer, l int64, u uint32): out; n; step low,
#: step high, stream, seed low, seed high
PROGRAM_ARGS = {"normal_fill": "Bl" "uuuuu"}
#: the shared sources the program is built after (rdgpu/families/philox.cl)
HEADERS = ("philox.cl",)
#: work-items per work-group (one fixed size: PoCL compiles one function per local size)
GROUP = 256


def normal_fill(rt, out, *, seed: int, step: int, stream: int) -> None:
    """Fill ``out`` with standard normal numbers on the OpenCL backend ``rt`` (see
    :mod:`rdgpu.families.noise`)."""
    words = check(rt, out, seed, step, stream)
    rt.check_real(out.dtype)
    n = out.size
    if n == 0:
        return
    pairs = (n + 1) // 2
    kernel = rt.own_program("noise", PROGRAM_ARGS, out.dtype, headers=HEADERS)["normal_fill"]
    group = min(GROUP, rt.max_group)
    rt.enqueue(kernel, (out.handle, n, *words), (-(-pairs // group) * group,), (group,))
