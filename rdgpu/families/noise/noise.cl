/* The noise family: normal_fill, standard normal numbers from Philox-4x32-10 by
 * Box–Muller (the definition is the docstring of rdgpu/families/noise/__init__.py).
 * Built as a program of its own after common.cl (`real`, SQRT, FLUSH, INLINE) and
 * philox.cl (Philox4, philox), with the real type of the array.
 *
 * normal_fill: one work-item per pair j < ceil(n / 2) of the flat array out; it writes
 * elements 2j and, below n, 2j + 1.
 */

#if REAL_IS_DOUBLE
#define TWO_PI 0x1.921fb54442d18p+2
#else
#define TWO_PI 0x1.921fb6p+2f
#endif

/* Box–Muller's u1 of the words r: exact (24 or 53 significant bits), in (0, 1) */
INLINE real u1_of(const Philox4 r)
{
#if REAL_IS_DOUBLE
    const double hi = (double)(r.c[0] >> 6) * 0x1p26 + (double)(r.c[2] >> 6);
    return (hi + 0.5) * 0x1p-52;
#else
    return ((float)(r.c[0] >> 9) + 0.5f) * 0x1p-23f;
#endif
}

/* Box–Muller's u2 of the words r: exact, in [0, 1) */
INLINE real u2_of(const Philox4 r)
{
#if REAL_IS_DOUBLE
    return ((double)(r.c[1] >> 5) * 0x1p26 + (double)(r.c[3] >> 6)) * 0x1p-53;
#else
    return (float)(r.c[1] >> 8) * 0x1p-24f;
#endif
}

__kernel void normal_fill(__global real *RESTRICT out, const long n, const uint step_lo,
                          const uint step_hi, const uint stream, const uint seed_lo,
                          const uint seed_hi)
{
    const long j = (long)get_global_id(0);
    const long k = 2 * j;
    if (k >= n) return;
    const Philox4 r = philox((uint)j, step_lo, step_hi, stream, seed_lo, seed_hi);
    const real rho = SQRT((real)-2 * log(u1_of(r)));
    const real theta = TWO_PI * u2_of(r);
    real c;
    const real s = sincos(theta, &c);
    out[k] = FLUSH(rho * c);
    if (k + 1 < n) out[k + 1] = FLUSH(rho * s);
}
