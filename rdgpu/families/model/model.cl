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

/*@GRID@*/
/* Grids (1-D, 2-D, 3-D as nz × ny rows of nx cells; an ensemble as nm such grids one
 * after the other, member-major): one work-item per row (CPU) or COL_STRIDE work-items per
 * row (GPU), see common.cl.  A row's neighbour rows are always in its own member.  Neighbour rows are resolved once per
 * row by the boundary rule; every load is unconditional (indices always in range) and a
 * select picks the Dirichlet ghost, so the interior loop has no branch and vectorises. */
__kernel void rd_program(@ARGS@,
        const int nx, const int ny, const int nz, const int nm,
        const int x_kind, const real gx, const int y_kind, const real gy,
        const int z_kind, const real gz,
        const real cx, const real cy, const real cz,
        const real dx, const real dy, const real dz)
{
    const int row = (int)get_global_id(1);
    if (row >= ny * nz * nm) return;
    const int i = row % ny;
    const int kz = (row / ny) % nz;
    const int m_ = row / (ny * nz);  /* the ensemble member */
    const long m0 = (long)m_ * nz;   /* its first z layer */
    const long rc = (long)row * nx;
    const long rs = ((m0 + kz) * ny + lo_index(i, ny, y_kind)) * nx;
    const long rn = ((m0 + kz) * ny + hi_index(i, ny, y_kind)) * nx;
    const bool ds = lo_is_ghost(i, y_kind), dn = hi_is_ghost(i, ny, y_kind);
    const long rb = ((m0 + lo_index(kz, nz, z_kind)) * ny + i) * nx;
    const long rt = ((m0 + hi_index(kz, nz, z_kind)) * ny + i) * nx;
    const bool db = lo_is_ghost(kz, z_kind), dt_ = hi_is_ghost(kz, nz, z_kind);
    /* the four rows diagonal in (z, y), for the isotropic 3-D stencil */
    const long rbs = ((m0 + lo_index(kz, nz, z_kind)) * ny + lo_index(i, ny, y_kind)) * nx;
    const long rbn = ((m0 + lo_index(kz, nz, z_kind)) * ny + hi_index(i, ny, y_kind)) * nx;
    const long rts = ((m0 + hi_index(kz, nz, z_kind)) * ny + lo_index(i, ny, y_kind)) * nx;
    const long rtn = ((m0 + hi_index(kz, nz, z_kind)) * ny + hi_index(i, ny, y_kind)) * nx;
    const real yc = ((real)i + (real)0.5) * dy;
    const real zc = ((real)kz + (real)0.5) * dz;
    (void)rs; (void)rn; (void)ds; (void)dn; (void)rb; (void)rt; (void)db; (void)dt_;
    (void)yc; (void)zc; (void)dx; (void)rbs; (void)rbn; (void)rts; (void)rtn; (void)m_;
@ROW@
#define RD_CELL(j, cc)                                                                    \
    do {                                                                                  \
        const ColInfo cc_ = (cc);                                                         \
        const long k_ = rc + (j);                                                          \
        (void)cc_;                                                                        \
@CELL@ \
    } while (0)
    FOR_EACH_CELL(RD_CELL);
#undef RD_CELL
}
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
