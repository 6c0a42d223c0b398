/* Pointwise reaction-diffusion update, generated per model.  Needs common.cl.
 *
 *   out_s = x_s + h (D_s lap_s + R_s(x; p))      (no D_s lap_s term where D_s = 0)
 *
 * rdgpu/reaction.py fills in this template: @ARGS@ becomes the buffers and scalars (the
 * species x0.., their Laplacians l0.. where D_s != 0, the outputs o0.., the parameters
 * p_NAME as a buffer when a per-cell field or a `real` when a scalar, the D_s and h) and
 * @BODY@ the loads and the fully parenthesised reaction expressions with exact hex-float
 * literals.  FP_CONTRACT is OFF (common.cl), so the arithmetic matches the NumPy reference.
 * This kernel:
@REACTIONS@
 *
 * Any shape, flat: n elements.  Work-item g handles [g*chunk, min(n, (g+1)*chunk)): chunk
 * is a few thousand on CPU devices (one vectorisable loop), 1 on GPUs (coalesced).
 */

__kernel void reaction_step(@ARGS@,
                            const long n, const long chunk)
{
    const long start = (long)get_global_id(0) * chunk;
    const long stop = (n - start < chunk) ? n : start + chunk;
    for (long k = start; k < stop; ++k) {
@BODY@
    }
}
