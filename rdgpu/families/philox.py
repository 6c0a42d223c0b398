"""Philox-4x32-10 in NumPy, the counter-based generator of every family that draws random
numbers (``walkers/``, ``noise/``): one definition, bit for bit that of the Warp
functions in ``warp_philox.py`` and the OpenCL ones in ``philox.cl``.

``philox4x32(counter, key)`` maps a counter of four 32-bit words and a key of two to four
32-bit words: ten rounds of ``(c0, c1, c2, c3) -> (hi(M1·c2) ^ c1 ^ k0, lo(M1·c2),
hi(M0·c0) ^ c3 ^ k1, lo(M0·c0))``, the key bumped by the Weyl constants ``(W0, W1)``
between rounds (Salmon et al., "Parallel random numbers: as easy as 1, 2, 3", SC 2011;
Random123's published answers are checked in ``tests/growth/test_walkers.py``).
"""

from __future__ import annotations

import numpy as np

#: the round multipliers and the key's Weyl increments
M0, M1 = np.uint64(0xD2511F53), np.uint64(0xCD9E8D57)
W0, W1 = 0x9E3779B9, 0xBB67AE85
MASK32 = np.uint64(0xFFFFFFFF)


def philox4x32(ctr, key) -> tuple[np.ndarray, ...]:
    """Philox-4x32-10 of the counters ``ctr`` (4 uint32 arrays or scalars) under ``key``
    (2 uint32): returns 4 uint32 arrays."""
    c0, c1, c2, c3 = (np.asarray(c, np.uint64) & MASK32 for c in ctr)
    c0, c1, c2, c3 = np.broadcast_arrays(c0, c1, c2, c3)
    k0, k1 = int(key[0]) & 0xFFFFFFFF, int(key[1]) & 0xFFFFFFFF
    for rnd in range(10):
        if rnd:
            k0, k1 = (k0 + W0) & 0xFFFFFFFF, (k1 + W1) & 0xFFFFFFFF
        p0, p1 = M0 * c0, M1 * c2
        c0, c1, c2, c3 = (
            (p1 >> np.uint64(32)) ^ c1 ^ np.uint64(k0),
            p1 & MASK32,
            (p0 >> np.uint64(32)) ^ c3 ^ np.uint64(k1),
            p0 & MASK32,
        )
    return tuple(c.astype(np.uint32) for c in (c0, c1, c2, c3))


def key_of(seed: int) -> tuple[int, int]:
    """The Philox key ``(low, high)`` 32-bit words of a non-negative 64-bit seed."""
    return seed & 0xFFFFFFFF, (seed >> 32) & 0xFFFFFFFF
