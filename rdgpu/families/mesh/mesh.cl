/* CSR kernels on triangle meshes (equations §6) and multicolour SOR.  Needs common.cl.
 *
 * A CSR matrix is (indptr[n_rows + 1], indices[nnz], data[nnz]), int32 indices sorted per
 * row.  Every row is summed in index order, acc = 0; acc += a_ij x_j, without FMA
 * contraction (FP_CONTRACT OFF in common.cl): the order of kernels/mesh/reference.py.
 *
 * Launch shape: work-item g handles the rows [g*block, min(n, (g+1)*block)).  On CPU
 * devices block is a few hundred to a few thousand rows (a serial loop per work-item, a
 * handful of work-groups per core); on GPUs block = 1 (one work-item per row, work-groups
 * of COL_STRIDE work-items).  The host rounds the global size up; surplus work-items find
 * an empty range.
 *
 *   csr_spmv                   y = A x
 *   mesh_gray_scott_{s,f}{s,f} one fused forward-Euler Gray-Scott step with Δ = L
 *                              (F then k; s = scalar, f = per-vertex field)
 *   mesh_diffusion_{s,f}       out = u + h (D (L u) + source)   (source scalar / field)
 *   csr_sor_colour             one colour of multicolour SOR for A x = rhs, in place:
 *                              for i = rows[t], x_i <- om1 x_i + om (rhs_i - Σ_{j≠i} a_ij x_j)
 *                              / diag_i, change[i] = |Δx_i|
 * Every value written is flushed of subnormals (FLUSH, see common.cl).
 */

/* the rows [*first, *stop) of this work-item */
#define CSR_RANGE(n, block)                                                               \
    const long g_ = (long)get_global_id(0);                                               \
    const long first_ = g_ * (long)(block);                                               \
    const long stop_ = ((long)(n) - first_ < (long)(block)) ? (long)(n) : first_ + (block)

/* Σ data[q] x[indices[q]] over p <= q < end, in order.  A row of 7 entries (a valence-6
 * vertex and its diagonal: most rows of a triangle mesh) runs as straight-line code. */
INLINE real csr_dot(__global const int *RESTRICT indices, __global const real *RESTRICT data,
                    __global const real *RESTRICT x, int p, const int end)
{
    real acc = R0;
    if (end - p == 7) {
        acc += data[p] * x[indices[p]];
        acc += data[p + 1] * x[indices[p + 1]];
        acc += data[p + 2] * x[indices[p + 2]];
        acc += data[p + 3] * x[indices[p + 3]];
        acc += data[p + 4] * x[indices[p + 4]];
        acc += data[p + 5] * x[indices[p + 5]];
        acc += data[p + 6] * x[indices[p + 6]];
    } else {
        for (; p < end; ++p) {
            acc += data[p] * x[indices[p]];
        }
    }
    return acc;
}

__kernel void csr_spmv(__global const int *RESTRICT indptr, __global const int *RESTRICT indices,
                       __global const real *RESTRICT data, __global const real *RESTRICT x,
                       __global real *RESTRICT y, const int n_rows, const int block)
{
    CSR_RANGE(n_rows, block);
    if (first_ >= stop_) return;
    int p = indptr[first_];
    for (long i = first_; i < stop_; ++i) {
        const int end = indptr[i + 1];
        y[i] = FLUSH(csr_dot(indices, data, x, p, end));
        p = end;
    }
}

/* ------------------------------------------------------------------ Gray-Scott */
#define MESH_GS_TERM(q)                                                                   \
    do {                                                                                  \
        const real a_ = data[q];                                                          \
        const int j_ = indices[q];                                                        \
        lu += a_ * u[j_];                                                                 \
        lv += a_ * v[j_];                                                                 \
    } while (0)

#define MESH_GRAY_SCOTT_KERNEL(NAME, FV, KV)                                              \
__kernel void NAME(__global const int *RESTRICT indptr, __global const int *RESTRICT indices, \
                   __global const real *RESTRICT data,                                    \
                   __global const real *RESTRICT u, __global const real *RESTRICT v,      \
                   __global real *RESTRICT uo, __global real *RESTRICT vo,                \
                   __global const real *RESTRICT Fp, __global const real *RESTRICT kp,    \
                   const int n_rows, const int block, const real Du, const real Dv,        \
                   const real Fs, const real ks, const real h)                            \
{                                                                                         \
    CSR_RANGE(n_rows, block);                                                             \
    for (long i = first_; i < stop_; ++i) {                                               \
        real lu = R0, lv = R0;                                                            \
        const int end = indptr[i + 1];                                                    \
        int p = indptr[i];                                                                \
        if (end - p == 7) {                                                               \
            MESH_GS_TERM(p); MESH_GS_TERM(p + 1); MESH_GS_TERM(p + 2); MESH_GS_TERM(p + 3); \
            MESH_GS_TERM(p + 4); MESH_GS_TERM(p + 5); MESH_GS_TERM(p + 6);                \
        } else {                                                                          \
            for (; p < end; ++p) {                                                        \
                MESH_GS_TERM(p);                                                          \
            }                                                                             \
        }                                                                                 \
        const real uc = u[i], vc = v[i];                                                  \
        const real Fc = (FV), kc = (KV);                                                  \
        const real uvv = uc * vc * vc;                                                    \
        uo[i] = FLUSH(uc + h * (Du * lu - uvv + Fc * (R1 - uc)));                         \
        vo[i] = FLUSH(vc + h * (Dv * lv + uvv - (Fc + kc) * vc));                         \
    }                                                                                     \
}

MESH_GRAY_SCOTT_KERNEL(mesh_gray_scott_ss, Fs, ks)
MESH_GRAY_SCOTT_KERNEL(mesh_gray_scott_fs, Fp[i], ks)
MESH_GRAY_SCOTT_KERNEL(mesh_gray_scott_sf, Fs, kp[i])
MESH_GRAY_SCOTT_KERNEL(mesh_gray_scott_ff, Fp[i], kp[i])

/* ------------------------------------------------------------------ diffusion step */
#define MESH_DIFFUSION_KERNEL(NAME, SV)                                                   \
__kernel void NAME(__global const int *RESTRICT indptr, __global const int *RESTRICT indices, \
                   __global const real *RESTRICT data, __global const real *RESTRICT u,   \
                   __global real *RESTRICT out, __global const real *RESTRICT sp,         \
                   const int n_rows, const int block, const real D, const real ss,        \
                   const real h)                                                          \
{                                                                                         \
    CSR_RANGE(n_rows, block);                                                             \
    for (long i = first_; i < stop_; ++i) {                                               \
        const real lap = csr_dot(indices, data, u, indptr[i], indptr[i + 1]);             \
        out[i] = FLUSH(u[i] + h * (D * lap + (SV)));                                      \
    }                                                                                     \
}

MESH_DIFFUSION_KERNEL(mesh_diffusion_s, ss)
MESH_DIFFUSION_KERNEL(mesh_diffusion_f, sp[i])

/* ------------------------------------------------------------------ multicolour SOR
 * The rows of one colour share no stored entry, so updating them in place in any order
 * (or all at once) gives the sequential result.  x is read and written: no restrict. */
__kernel void csr_sor_colour(__global const int *RESTRICT indptr,
                             __global const int *RESTRICT indices,
                             __global const real *RESTRICT data,
                             __global const real *RESTRICT diag, __global real *x,
                             __global const real *RESTRICT rhs,
                             __global const int *RESTRICT rows, __global real *RESTRICT change,
                             const int n, const int block, const real om, const real om1)
{
    CSR_RANGE(n, block);
    for (long t = first_; t < stop_; ++t) {
        const int i = rows[t];
        real sigma = R0;
        const int end = indptr[i + 1];
        for (int p = indptr[i]; p < end; ++p) {
            const int j = indices[p];
            if (j != i) sigma += data[p] * x[j];
        }
        const real old = x[i];
        const real nw = FLUSH(om1 * old + om * ((rhs[i] - sigma) / diag[i]));
        x[i] = nw;
        change[i] = FLUSH(FABS(nw - old));
    }
}
