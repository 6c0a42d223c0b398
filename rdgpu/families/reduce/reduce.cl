/* Max-|u| reduction (Backend.max_abs).  Needs common.cl (REAL_IS_DOUBLE, ROW_LAYOUT, RESTRICT).
 *
 * max_abs_partial writes partial maxima of |u| over the flat array u (n elements); the host
 * takes the max of the partials.  Exact and NaN-aware like numpy.max, on any device:
 *
 *   The kernels compare the IEEE bit patterns of |u|, not floats.  With the sign bit cleared
 *   (bits & ABS_MASK), the bit patterns of non-negative values are ordered as unsigned
 *   integers exactly like the values: 0 < subnormals < normals < +inf < every NaN.  So the
 *   unsigned max of the masked patterns is the pattern of max |u|, or a NaN if any element
 *   is NaN; -0.0 masks to +0.0.  Integer compares ignore the DAZ bit that
 *   -cl-denorms-are-zero sets (a float compare would read subnormals as 0) and need no NaN
 *   branch, and an unsigned max is one vector instruction (vpmaxud / vpmaxuq).
 *
 * The buffers are read as `bits` (uint for float, ulong for double): the same bytes.
 *
 * Shapes (the program is built for one layout, see common.cl):
 *   ROW_LAYOUT = 1 (CPU): work-item g reduces the contiguous chunk [g*chunk, (g+1)*chunk)
 *     (clipped to n) in a branch-free loop that LLVM vectorises; partial[g] per work-item.
 *   ROW_LAYOUT = 0 (GPU): a grid-stride loop (consecutive work-items read consecutive
 *     elements: coalesced), then a tree reduction in local memory `scratch` (one element
 *     per work-item; the work-group size is a power of two); partial[group] per
 *     work-group.  `chunk` is unused.
 *
 * -D RDGPU_REDUCE_SCALAR keeps LLVM from vectorising the row loop (perf/reduce.py measures
 * what vectorisation is worth).
 */

#if REAL_IS_DOUBLE
typedef ulong bits;
#define ABS_MASK 0x7fffffffffffffffUL
#else
typedef uint bits;
#define ABS_MASK 0x7fffffffU
#endif

/* unsigned max as a select (PoCL calls its builtin max() out of line, which would stop
 * the loop from vectorising) */
INLINE bits bits_max(bits a, bits b) { return (b > a) ? b : a; }

INLINE bits abs_bits(bits x) { return x & ABS_MASK; }

/* The strided layout (ROW_LAYOUT = 0) of a reduction kernel with arguments u, partial, n,
 * scratch: work-item t of T folds ITEM(u[t]), ITEM(u[t + T]), ... into an accumulator of
 * type T_ACC (from 0) with COMBINE, in order; then the work-group's tree in local memory,
 * scratch[l] = COMBINE(scratch[l], scratch[l + w]) for w = group/2, ..., 1 (the group
 * size is a power of two); partial[group id] = scratch[0]. */
#define STRIDED_REDUCE(T_ACC, ITEM, COMBINE)                                                 \
    do {                                                                                     \
        const size_t lid = get_local_id(0);                                                  \
        const size_t group = get_local_size(0);                                              \
        const long stride = (long)get_global_size(0);                                        \
        T_ACC acc_ = 0;                                                                      \
        for (long k = (long)get_global_id(0); k < n; k += stride) {                          \
            acc_ = COMBINE(acc_, ITEM(u[k]));                                                \
        }                                                                                    \
        scratch[lid] = acc_;                                                                 \
        barrier(CLK_LOCAL_MEM_FENCE);                                                        \
        for (size_t width = group / 2; width > 0; width /= 2) {                              \
            if (lid < width) {                                                               \
                scratch[lid] = COMBINE(scratch[lid], scratch[lid + width]);                  \
            }                                                                                \
            barrier(CLK_LOCAL_MEM_FENCE);                                                    \
        }                                                                                    \
        if (lid == 0) {                                                                      \
            partial[get_group_id(0)] = scratch[0];                                           \
        }                                                                                    \
    } while (0)

__kernel void max_abs_partial(__global const bits *RESTRICT u, __global bits *RESTRICT partial,
                              const long n, const long chunk, __local bits *scratch)
{
#if ROW_LAYOUT
    const long g = (long)get_global_id(0);
    const long start = g * chunk;
    const long stop = (n - start < chunk) ? n : start + chunk;
    bits m = 0;
#ifdef RDGPU_REDUCE_SCALAR
#pragma clang loop vectorize(disable) interleave(disable)
#endif
    for (long k = start; k < stop; ++k) {
        m = bits_max(m, u[k] & ABS_MASK);
    }
    partial[g] = m;
#else
    STRIDED_REDUCE(bits, abs_bits, bits_max);
#endif
}

/* Sum of squares (Backend.sum_squares): partial sums of u[k]^2, in double for both real
 * types (a float squared in double is exact); the host adds the partials in double.
 *
 *   Order (fixed by this code, not by the compiler; FP_CONTRACT is OFF, see common.cl):
 *   ROW_LAYOUT = 1: work-item g sums its chunk [start, stop) in 16 lanes of a double16:
 *     lane j takes the elements start + j, start + j + 16, ... in increasing order (the
 *     tail's last < 16 elements go to lanes 0, 1, ... likewise); then the lanes are
 *     combined as a tree, lane j += lane j + w for w = 8, 4, 2, 1, and lane 0 is
 *     partial[g].  The lanes are independent chains held in vector registers: two zmm
 *     accumulators on AVX-512, so two adds overlap (one accumulator cannot be vectorised
 *     without reassociating; a private array of 8 accumulators stayed on the stack in
 *     PoCL, measured 2x slower than a double8, which 16 lanes beat in cache).
 *   ROW_LAYOUT = 0: a grid-stride loop (work-item t of T sums t, t + T, ... in order),
 *     then the local-memory tree (scratch[l] += scratch[l + w], w = group/2, ..., 1);
 *     partial[group] per work-group.
 *
 * NaN and inf propagate (inf^2 = inf, inf + NaN = NaN); a float64 square or sum beyond
 * DBL_MAX is inf.  Subnormals: under -cl-denorms-are-zero a subnormal input may be read
 * as 0, and a square below DBL_MIN (|u| < 1.5e-154) may be flushed to 0; either changes
 * the sum by less than n * 1.4e-76 in float32, n * DBL_MIN in float64.
 *
 * Doubles are needed on the device; where it has none (no cl_khr_fp64) the kernel is an
 * empty stub of the same signature, so the rest of the program still builds, and the host
 * refuses the call (reduce/opencl.py).  -D RDGPU_REDUCE_SCALAR makes the row
 * loop one sequential accumulator, not vectorised (perf/reduce.py measures the lanes).
 */

#if defined(cl_khr_fp64) || defined(__opencl_c_fp64)
#pragma OPENCL EXTENSION cl_khr_fp64 : enable

/* x^2 in double: exact for a float x, one rounding for a double x */
INLINE double square_d(const real x)
{
    const double d = (double)x;
    return d * d;
}

INLINE double add_d(double a, double b) { return a + b; }

__kernel void sum_squares_partial(__global const real *RESTRICT u,
                                  __global double *RESTRICT partial, const long n,
                                  const long chunk, __local double *scratch)
{
#if ROW_LAYOUT
    const long g = (long)get_global_id(0);
    const long start = g * chunk;
    const long stop = (n - start < chunk) ? n : start + chunk;
    long k = start;
#ifdef RDGPU_REDUCE_SCALAR
    double s = 0.0;
#pragma clang loop vectorize(disable) interleave(disable)
    for (; k < stop; ++k) {
        s += square_d(u[k]);
    }
    partial[g] = s;
#else
    double16 acc = (double16)(0.0);
    for (; k + 16 <= stop; k += 16) {
        const double16 x = convert_double16(vload16(0, u + k));
        acc += x * x;
    }
    double tail[16] = {0.0}; /* fewer than 16 left */
    for (int j = 0; j < 15; ++j) {
        if (k + j < stop) {
            tail[j] = square_d(u[k + j]);
        }
    }
    acc += vload16(0, tail); /* (+0.0 leaves a lane as it is: lanes are never -0.0) */
    const double8 fold8 = acc.lo + acc.hi;
    const double4 fold4 = fold8.lo + fold8.hi;
    const double2 fold2 = fold4.lo + fold4.hi;
    partial[g] = fold2.lo + fold2.hi;
#endif
#else
    STRIDED_REDUCE(double, square_d, add_d);
#endif
}

#else /* no fp64 on this device: a stub (never launched; the host raises first) */

__kernel void sum_squares_partial(__global const real *RESTRICT u,
                                  __global ulong *RESTRICT partial, const long n,
                                  const long chunk, __local ulong *scratch)
{
}

#endif
