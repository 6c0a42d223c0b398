/* One pass of a model's generated program (rdgpu/integrators/passes.py, printed by rdgpu/backends/opencl_codegen.py).  Needs common.cl.
 *
 * The compiler fills in this template per program, domain kind and dtype: @ARGS@ becomes
 * the buffers (inputs _in_*, outputs _out_*, parameter fields _pf_*) and scalars (_p_*
 * scalar parameters, _b_* builtins such as the step _h, b_t the time, len_* the domain
 * extents; every identifier made of a name starts with _, rdgpu/models/names.py), and
 * the cell body the loads, the Laplacians and the fully parenthesised expressions with
 * exact hex-float literals.  FP_CONTRACT is OFF (common.cl): the arithmetic is the NumPy
 * reference's, operation by operation.  This program writes:
@OUTPUTS@
 */

/* NaN-propagating min/max (numpy.minimum / numpy.maximum) */
INLINE real nanmin2(real a, real b) { return (a != a || a < b) ? a : b; }
INLINE real nanmax2(real a, real b) { return (a != a || a > b) ? a : b; }
/* comparisons (rdgpu.ir.equations.COMPARISONS): 1 where true, else 0 */
INLINE real cmp_lt(real a, real b) { return (a < b) ? (real)1 : (real)0; }
INLINE real cmp_le(real a, real b) { return (a <= b) ? (real)1 : (real)0; }
INLINE real cmp_gt(real a, real b) { return (a > b) ? (real)1 : (real)0; }
INLINE real cmp_ge(real a, real b) { return (a >= b) ? (real)1 : (real)0; }
INLINE real cmp_eq(real a, real b) { return (a == b) ? (real)1 : (real)0; }
INLINE real cmp_ne(real a, real b) { return (a != b) ? (real)1 : (real)0; }

/*@GRID@*/
/* Grids (1-D, 2-D, 3-D as nz × ny rows of nx cells; an ensemble as nm such grids one
 * after the other, member-major; a plane is one member's z layer).  A row's neighbour rows
 * are always in its own member.  Neighbour rows are resolved once per row by the boundary
 * rule; every load is unconditional (indices always in range) and a select picks the
 * Dirichlet ghost, so the interior loop has no branch and vectorises.
 *
 * RD_ROW(row_) declares the offsets of row row_ (counted over every plane): its own rc,
 * its neighbour rows' rs, rn (y), rb, rt (z), the diagonal ones, the ghost flags and the
 * row's member m_. */
#define RD_ROW(row_)                                                                      \
    const int i = (row_) % ny;                                                            \
    const int kz = ((row_) / ny) % nz;                                                    \
    const int m_ = (row_) / (ny * nz);  /* the ensemble member */                         \
    const long m0 = (long)m_ * nz;      /* its first z layer */                           \
    const long rc = (long)(row_) * nx;                                                    \
    const long rs = ((m0 + kz) * ny + lo_index(i, ny, y_kind)) * nx;                      \
    const long rn = ((m0 + kz) * ny + hi_index(i, ny, y_kind)) * nx;                      \
    const bool ds = lo_is_ghost(i, y_kind), dn = hi_is_ghost(i, ny, y_kind);              \
    const long rb = ((m0 + lo_index(kz, nz, z_kind)) * ny + i) * nx;                      \
    const long rt = ((m0 + hi_index(kz, nz, z_kind)) * ny + i) * nx;                      \
    const bool db = lo_is_ghost(kz, z_kind), dt_ = hi_is_ghost(kz, nz, z_kind);           \
    const long rbs = ((m0 + lo_index(kz, nz, z_kind)) * ny + lo_index(i, ny, y_kind)) * nx; \
    const long rbn = ((m0 + lo_index(kz, nz, z_kind)) * ny + hi_index(i, ny, y_kind)) * nx; \
    const long rts = ((m0 + hi_index(kz, nz, z_kind)) * ny + lo_index(i, ny, y_kind)) * nx; \
    const long rtn = ((m0 + hi_index(kz, nz, z_kind)) * ny + hi_index(i, ny, y_kind)) * nx; \
    const real yc = ((real)i + (real)0.5) * dy;                                           \
    const real zc = ((real)kz + (real)0.5) * dz;                                          \
    (void)rs; (void)rn; (void)ds; (void)dn; (void)rb; (void)rt; (void)db; (void)dt_;      \
    (void)yc; (void)zc; (void)dx; (void)rbs; (void)rbn; (void)rts; (void)rtn; (void)m_

/* One cell: column j (or, in rd_span's flat loop, the cell's own index with rc = 0) of the
 * row whose offsets are in scope; cc its ColInfo. */
#define RD_CELL(j, cc)                                                                    \
    do {                                                                                  \
        const ColInfo cc_ = (cc);                                                         \
        const long k_ = rc + (j);                                                          \
        (void)cc_;                                                                        \
@CELL@ \
    } while (0)

/* One work-item per row (CPU) or COL_STRIDE work-items per row (GPU), see common.cl. */
__kernel void rd_program(@ARGS@,
        const int nx, const int ny, const int nz, const int nm,
        const int x_kind, const real gx, const int y_kind, const real gy,
        const int z_kind, const real gz,
        const real cx, const real cy, const real cz,
        const real dx, const real dy, const real dz)
{
    const int row = (int)get_global_id(1);
    if (row >= ny * nz * nm) return;
    RD_ROW(row);
@MEMBER@
@ROW@
    FOR_EACH_CELL(RD_CELL);
}
/*@SPAN@*/
#if ROW_LAYOUT
/* Short rows (CPU): one work-item per span of `span` interior rows (1 <= i < ny - 1) of one
 * plane, `spans` spans per plane.  Inside a plane the neighbours of an interior row are at
 * fixed offsets (rs = rc - nx, rn = rc + nx, rb/rt one plane away or wrapped, no y ghost),
 * so the whole span is ONE loop over its cells k with the neighbours at k - 1, k + 1,
 * k -+ nx, k + (rb - rc)...: a long vector loop however short the rows.  The loop runs from
 * the span's second cell to its last but one, so every load is in range; the cells at a
 * row's x edges come out wrong there (their x neighbours are the next or previous row's)
 * and are then recomputed with the x boundary rule, which overwrites them (the outputs
 * are not the inputs).  The first span of a plane also takes row 0, the last row ny - 1,
 * whole, as rd_program does.  Every cell's arithmetic is rd_program's, bit for bit.
 * Needs nx >= 3 and ny >= 3; programs that read the x or y coordinate or a metric take
 * rd_program. */
__kernel void rd_span(@ARGS@,
        const int nx, const int ny, const int nz, const int nm,
        const int x_kind, const real gx, const int y_kind, const real gy,
        const int z_kind, const real gz,
        const real cx, const real cy, const real cz,
        const real dx, const real dy, const real dz, const int span, const int spans)
{
    const int item = (int)get_global_id(1);
    const int plane = item / spans;  /* m_ * nz + kz */
    if (plane >= nz * nm) return;
    const int part = item - plane * spans;
    const int first = 1 + part * span;
    const int last = min(first + span, ny - 1);  /* the span: interior rows [first, last) */
    const int m_ = plane / nz;
@MEMBER@
    {
        const int kz = plane - m_ * nz;
        const long pz = (long)ny * nx;  /* one plane */
        const long rc = 0, rs = -(long)nx, rn = (long)nx;
        const bool ds = false, dn = false;
        const long rb = (long)(lo_index(kz, nz, z_kind) - kz) * pz;
        const long rt = (long)(hi_index(kz, nz, z_kind) - kz) * pz;
        const bool db = lo_is_ghost(kz, z_kind), dt_ = hi_is_ghost(kz, nz, z_kind);
        const long rbs = rb - nx, rbn = rb + nx, rts = rt - nx, rtn = rt + nx;
        const real zc = ((real)kz + (real)0.5) * dz;
        (void)rs; (void)rn; (void)ds; (void)dn; (void)rb; (void)rt; (void)db; (void)dt_;
        (void)zc; (void)dx; (void)dy; (void)rbs; (void)rbn; (void)rts; (void)rtn;
        const long k0 = (long)plane * pz + (long)first * nx + 1;
        const long k1 = (long)plane * pz + (long)last * nx - 1;
        for (long j_ = k0; j_ < k1; ++j_) {
            RD_CELL(j_, col_interior(j_));
        }
        /* the rows' x-edge cells again, with the x boundary rule */
        for (long r0_ = k0 - 1; r0_ < k1; r0_ += nx) {
            RD_CELL(r0_, col_first(r0_, nx, x_kind));
            RD_CELL(r0_ + nx - 1, col_last(r0_, nx, x_kind));
        }
    }
    for (int r_ = 0; r_ < ny; r_ += ny - 1) {  /* the y-edge rows, whole */
        if ((r_ == 0) ? part != 0 : part != spans - 1) continue;
        RD_ROW(plane * ny + r_);
        FOR_EACH_CELL(RD_CELL);
    }
}
#endif
/*@END SPAN@*/
#undef RD_CELL
#undef RD_ROW
/*@END GRID@*/

/*@MESH@*/
/* Meshes: CSR rows of L = A⁻¹W, a block of rows per work-item (CPU) or one (GPU); each
 * Laplacian is Σ_q data[q] x[indices[q]] in index order, as kernels/mesh.  An ensemble
 * is nm copies of the n_vert vertices, member-major (n_rows = nm·n_vert): row k_ is vertex
 * v_ of member m_, whose values start at moff_. */
__kernel void rd_program(__global const int *RESTRICT indptr,
        __global const int *RESTRICT indices, __global const real *RESTRICT data,
        @ARGS@,
        const int n_rows, const int block, const int n_vert@COORDS@)
{
    const long first_ = (long)get_global_id(0) * (long)block;
    const long stop_ = ((long)n_rows - first_ < (long)block) ? (long)n_rows : first_ + block;
    long m_ = first_ / n_vert;
    long v_ = first_ - m_ * n_vert;
    for (long k_ = first_; k_ < stop_; ++k_) {
        const long moff_ = m_ * n_vert;
        const int p0_ = indptr[v_], p1_ = indptr[v_ + 1];
        (void)p0_; (void)p1_; (void)moff_;
@BODY@
        if (++v_ == n_vert) { v_ = 0; ++m_; }
    }
}
/*@END MESH@*/
