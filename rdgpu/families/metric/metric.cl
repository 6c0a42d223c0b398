/* Laplace-Beltrami operator of a graph surface z = h(x, y) over a periodic grid
 * (rdgpu.metric; the maths and evaluation order of kernels/metric/reference.py).
 * Needs common.cl.
 *
 * metric_laplacian: out = w_c (axial + cross) with
 *   axial = (ex_c (E - c) - ex_w (c - W)) + (ny_c (N - c) - ny_s (c - S))
 *   cross = (bx_c (NE - c) + bx_sw (SW - c)) - (bx_s (SE - c) + bx_w (NW - c))
 * (_w/_s/_sw: the coefficient of the cell to the west/south/south-west; every operation in
 * the reference's order, FP_CONTRACT off), flushed of subnormals.
 *
 * u (and out) may hold nm members [nm, ny, nx] one after the other; the four coefficient
 * arrays [ny, nx] are shared by every member.  Launched on nm * ny rows (see common.cl for
 * the row and strided layouts); both axes are periodic, so the row neighbours wrap within
 * the member and only the edge columns wrap (x_kind = periodic in FOR_EACH_CELL).
 */

INLINE real metric_cell(__global const real *RESTRICT u, __global const real *RESTRICT ex,
                        __global const real *RESTRICT ny_, __global const real *RESTRICT bx,
                        __global const real *RESTRICT w, long rc, long rs, long rn, long kc,
                        long ks, long jw, long j, long je)
{
    const real c = u[rc + j];
    const real e = u[rc + je], wst = u[rc + jw], n = u[rn + j], s = u[rs + j];
    const real ne = u[rn + je], sw = u[rs + jw], se = u[rs + je], nw = u[rn + jw];
    const real axial = ((ex[kc + j] * (e - c)) - (ex[kc + jw] * (c - wst)))
                       + ((ny_[kc + j] * (n - c)) - (ny_[ks + j] * (c - s)));
    const real cross = ((bx[kc + j] * (ne - c)) + (bx[ks + jw] * (sw - c)))
                       - ((bx[ks + j] * (se - c)) + (bx[kc + jw] * (nw - c)));
    return FLUSH(w[kc + j] * (axial + cross));
}

__kernel void metric_laplacian(__global const real *RESTRICT u,
                               __global const real *RESTRICT ex,
                               __global const real *RESTRICT ny_,
                               __global const real *RESTRICT bx,
                               __global const real *RESTRICT w,
                               __global real *RESTRICT out,
                               const int nx, const int ny, const int nm)
{
    const int row = (int)get_global_id(1);
    if (row >= ny * nm) return;
    const int x_kind = BC_PERIODIC; /* for FOR_EACH_CELL */
    const int i = row % ny;
    const long m0 = (long)(row - i) * nx;                          /* the member's first cell */
    const long kc = (long)i * nx;                                  /* coefficient rows */
    const long ks = (long)lo_index(i, ny, BC_PERIODIC) * nx;
    const long rc = m0 + kc;                                       /* u rows */
    const long rs = m0 + ks;
    const long rn = m0 + (long)hi_index(i, ny, BC_PERIODIC) * nx;
#define METRIC_CELL(j, cc)                                                              \
    do {                                                                                \
        const ColInfo cc_ = (cc);                                                       \
        out[rc + (j)] = metric_cell(u, ex, ny_, bx, w, rc, rs, rn, kc, ks, cc_.w, (j),  \
                                    cc_.e);                                             \
    } while (0)
    FOR_EACH_CELL(METRIC_CELL);
#undef METRIC_CELL
}
