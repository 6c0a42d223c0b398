/* Analytic Bernoulli substep (equations §2).  Needs common.cl.
 *
 * out = u / SQRT(d + u² (1 - d)),  d = exp(-2τ/ε²),  omd = 1 - d (rounded in `real`);
 * subnormal results flushed to 0 (see common.cl).
 * Any shape: the array is flat, n elements.  Work-item g handles the contiguous chunk
 * [g*chunk, min(n, (g+1)*chunk)): chunk = 1 on GPUs (coalesced), a few thousand on CPUs
 * (a vectorised inner loop).
 */

INLINE real bernoulli_cell(real u, real d, real omd)
{
    return FLUSH(u / SQRT(d + u * u * omd));
}

__kernel void bernoulli(__global const real *RESTRICT u, __global real *RESTRICT out,
                        const long n, const long chunk, const real d, const real omd)
{
    const long start = (long)get_global_id(0) * chunk;
    const long stop = (n - start < chunk) ? n : start + chunk;
    for (long k = start; k < stop; ++k) {
        out[k] = bernoulli_cell(u[k], d, omd);
    }
}
