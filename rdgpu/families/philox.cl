/* Philox-4x32-10, the counter-based generator of the families that draw random numbers
 * (walkers/, noise/): bit for bit rdgpu/families/philox.py (the definition) and
 * warp_philox.py.  Integer only; the host prepends this header to those families' own
 * programs (OpenCLBackend.own_program(..., headers=("philox.cl",))).
 */

typedef struct { uint c[4]; } Philox4;

/* one round of the counter x under the round key (k0, k1).  The 64-bit products are
 * written out rather than mul_hi: PoCL calls its mul_hi out of line, which keeps the
 * work-item loop scalar (measured: Philox alone 26 -> 87 M/s on 2 cores) */
inline Philox4 philox_round(Philox4 x, uint k0, uint k1)
{
    const ulong p0 = (ulong)0xD2511F53u * x.c[0], p1 = (ulong)0xCD9E8D57u * x.c[2];
    Philox4 y;
    y.c[0] = (uint)(p1 >> 32) ^ x.c[1] ^ k0;
    y.c[1] = (uint)p1;
    y.c[2] = (uint)(p0 >> 32) ^ x.c[3] ^ k1;
    y.c[3] = (uint)p0;
    return y;
}

/* Philox-4x32-10 of the counter (c0, c1, c2, c3) under the key (k0, k1). */
inline Philox4 philox(uint c0, uint c1, uint c2, uint c3, uint k0, uint k1)
{
    Philox4 x;
    x.c[0] = c0; x.c[1] = c1; x.c[2] = c2; x.c[3] = c3;
    x = philox_round(x, k0, k1);
    for (int r = 0; r < 9; ++r) {
        k0 += 0x9E3779B9u;
        k1 += 0xBB67AE85u;
        x = philox_round(x, k0, k1);
    }
    return x;
}
