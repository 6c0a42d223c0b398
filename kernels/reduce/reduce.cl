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
    const size_t lid = get_local_id(0);
    const size_t group = get_local_size(0);
    const long stride = (long)get_global_size(0);
    bits m = 0;
    for (long k = (long)get_global_id(0); k < n; k += stride) {
        m = bits_max(m, u[k] & ABS_MASK);
    }
    scratch[lid] = m;
    barrier(CLK_LOCAL_MEM_FENCE);
    for (size_t width = group / 2; width > 0; width /= 2) {
        if (lid < width) {
            scratch[lid] = bits_max(scratch[lid], scratch[lid + width]);
        }
        barrier(CLK_LOCAL_MEM_FENCE);
    }
    if (lid == 0) {
        partial[get_group_id(0)] = scratch[0];
    }
#endif
}
