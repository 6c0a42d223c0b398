/* One red-black SOR half-sweep for Δc = f (equations §4).  Needs common.cl.
 *
 * Cells with (i + j) % 2 == color and fixed == 0 get, in place,
 *   c <- (1 - ω) c + ω (wx (E + W) + wy (N + S) - wf f),
 * with r = dx²/dy² (0 when dy = ∞: a grid without a y axis), wx = 1/(2(1 + r)),
 * wy = r/(2(1 + r)), wf = dx²/(2(1 + r)): (dy² (E + W) + dx² (N + S) - dx² dy² f) /
 * (2 (dx² + dy²)) rearranged.  New values and changes are flushed of subnormals.
 * A half-sweep reads only the other colour (and, for a Neumann edge cell, the cell
 * itself), so updating in place is exact.  Periodic axes must have even length (the
 * caller checks).  row_change[i] receives the row's max |Δc| over updated cells
 * (color 0 overwrites, color 1 takes the NaN-propagating max with what is there).
 *
 * Host-side constants: wx, wy, wf computed in double (sor/reference.py `weights`) and
 * rounded to `real`, om = ω, om1 = 1 - ω (rounded in `real` like the reference).
 * Two kernels: sor_half_sweep (f = 0) and sor_half_sweep_rhs.
 *
 * Layouts: in the row layout a work-item updates the colour's cells of its row
 * (stride 2).  Otherwise work-group (COL_STRIDE, 1) owns one row and reduces the row's
 * change in local memory, so the host must launch it with local size (COL_STRIDE, 1).
 */

INLINE real sor_cell(Nbr5 q, real f, bool has_rhs, real wx, real wy, real wf, real om,
                     real om1)
{
    real gs = wx * (q.e + q.w) + wy * (q.n + q.s);
    if (has_rhs) gs = gs - wf * f;
    return FLUSH(om1 * q.c + om * gs);
}

/* Update cell j of the row described by r; returns |Δc| (0 for a fixed cell). */
#define SOR_CELL(j, cc)                                                                   \
    do {                                                                                  \
        const long idx_ = r.c + (j);                                                       \
        const Nbr5 q_ = load5(c, r, (cc), (j), gy, gx);                                   \
        const real f_ = HAS_RHS_ ? rhs[idx_] : R0;                                         \
        const real new_ = sor_cell(q_, f_, HAS_RHS_, wx, wy, wf, om, om1);                \
        const bool held_ = fixed[idx_] != 0;                                              \
        c[idx_] = held_ ? q_.c : new_;                                                    \
        const real d_ = held_ ? R0 : FLUSH(FABS(new_ - q_.c));                            \
        m = nanmax(m, d_);                                                                \
    } while (0)

#if ROW_LAYOUT
#define SOR_LOCAL_DECL
#define SOR_ROW()                                                                         \
    do {                                                                                  \
        int j = (color + i) & 1;                                                          \
        if (j == 0) {                                                                     \
            SOR_CELL(0, col_info(0, nx, x_kind));                                         \
            j = 2;                                                                        \
        }                                                                                 \
        for (; j < nx - 1; j += 2) {                                                      \
            SOR_CELL(j, col_interior(j));                                                 \
        }                                                                                 \
        if (j == nx - 1) {                                                                \
            SOR_CELL(j, col_info(j, nx, x_kind));                                         \
        }                                                                                 \
        row_change[i] = (color == 0) ? m : nanmax(row_change[i], m);                      \
    } while (0)
#else
/* OpenCL wants __local variables at kernel function scope */
#define SOR_LOCAL_DECL __local real red[COL_STRIDE];
#define SOR_ROW()                                                                         \
    do {                                                                                  \
        const int lid = (int)get_local_id(0);                                             \
        for (int j = ((color + i) & 1) + 2 * lid; j < nx; j += 2 * COL_STRIDE) {          \
            SOR_CELL(j, col_info(j, nx, x_kind));                                         \
        }                                                                                 \
        red[lid] = m;                                                                     \
        barrier(CLK_LOCAL_MEM_FENCE);                                                     \
        for (int s = COL_STRIDE / 2; s > 0; s >>= 1) {                                    \
            if (lid < s) red[lid] = nanmax(red[lid], red[lid + s]);                       \
            barrier(CLK_LOCAL_MEM_FENCE);                                                 \
        }                                                                                 \
        if (lid == 0) {                                                                   \
            row_change[i] = (color == 0) ? red[0] : nanmax(row_change[i], red[0]);        \
        }                                                                                 \
    } while (0)
#endif

#define SOR_KERNEL(NAME, HAS_RHS)                                                         \
__kernel void NAME(__global real *c, __global const uchar *RESTRICT fixed,                \
                   __global const real *RESTRICT rhs, __global real *RESTRICT row_change, \
                   const int color, const int nx, const int ny, const int y_kind,         \
                   const real gy, const int x_kind, const real gx, const real wx,         \
                   const real wy, const real wf, const real om, const real om1)           \
{                                                                                         \
    SOR_LOCAL_DECL                                                                        \
    const bool HAS_RHS_ = (HAS_RHS);                                                      \
    const int i = (int)get_global_id(1);                                                  \
    if (i >= ny) return;                                                                  \
    const RowInfo r = row_info(i, nx, ny, y_kind);                                        \
    real m = R0;                                                                          \
    SOR_ROW();                                                                            \
}

SOR_KERNEL(sor_half_sweep, false)
SOR_KERNEL(sor_half_sweep_rhs, true)
