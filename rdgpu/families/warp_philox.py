"""Philox-4x32-10 as Warp functions, shared by the families that draw random numbers
(``walkers/``, ``noise/``): bit for bit ``rdgpu/families/philox.py`` (the definition) and
``philox.cl``.  A kernel module imports `philox` and `vec4u` from here; Warp builds the
functions into every module whose kernels call them.
"""

import warp as wp

wp.set_module_options({"enable_backward": False, "fuse_fp": False})

#: the four 32-bit words of a counter or of one draw
vec4u = wp.types.vector(length=4, dtype=wp.uint32)
# Philox-4x32 multipliers and Weyl key increments (typed: no int32 literals)
PHILOX_M0 = wp.constant(wp.uint64(0xD2511F53))
PHILOX_M1 = wp.constant(wp.uint64(0xCD9E8D57))
PHILOX_W0 = wp.constant(wp.uint32(0x9E3779B9))
PHILOX_W1 = wp.constant(wp.uint32(0xBB67AE85))
LOW32 = wp.constant(wp.uint64(0xFFFFFFFF))


@wp.func
def philox_round(c: vec4u, k0: wp.uint32, k1: wp.uint32) -> vec4u:
    """One Philox round of the counter ``c`` under the round key ``(k0, k1)``."""
    p0 = wp.uint64(c[0]) * PHILOX_M0
    p1 = wp.uint64(c[2]) * PHILOX_M1
    return vec4u(
        wp.uint32(p1 >> wp.uint64(32)) ^ c[1] ^ k0,
        wp.uint32(p1 & LOW32),
        wp.uint32(p0 >> wp.uint64(32)) ^ c[3] ^ k1,
        wp.uint32(p0 & LOW32),
    )


@wp.func
def philox(c: vec4u, k0: wp.uint32, k1: wp.uint32) -> vec4u:
    """Philox-4x32-10 of the counter ``c`` under the key ``(k0, k1)``."""
    x = philox_round(c, k0, k1)
    a = k0
    b = k1
    for _r in range(9):
        a = a + PHILOX_W0
        b = b + PHILOX_W1
        x = philox_round(x, a, b)
    return x
