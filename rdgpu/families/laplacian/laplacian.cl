/* Grid Laplacian (equations §1).  Needs common.cl.
 *
 * laplacian5: out = (E + W - 2u) cx + (N + S - 2u) cy      with cx = 1/dx², cy = 1/dy²
 * laplacian9: out = (4 (W + E + S + N) + SW + SE + NW + NE - 20u) c9   with c9 = 1/(6h²)
 * (outputs flushed of subnormals, see common.cl)
 */

INLINE real lap5_cell(Nbr5 q, real cx, real cy)
{
    return FLUSH((q.e + q.w - R2 * q.c) * cx + (q.n + q.s - R2 * q.c) * cy);
}

INLINE real lap9_cell(Nbr5 q, Nbr4d d, real c9)
{
    const real edge = q.w + q.e + q.s + q.n;
    const real corner = d.sw + d.se + d.nw + d.ne;
    return FLUSH(((real)4 * edge + corner - (real)20 * q.c) * c9);
}

__kernel void laplacian5(__global const real *RESTRICT u, __global real *RESTRICT out,
                         const int nx, const int ny, const int y_kind, const real gy,
                         const int x_kind, const real gx, const real cx, const real cy)
{
    GRID_ROW_OR_RETURN(i);
    const RowInfo r = row_info(i, nx, ny, y_kind);
#define LAP5_CELL(j, cc) out[r.c + (j)] = lap5_cell(load5(u, r, (cc), (j), gy, gx), cx, cy)
    FOR_EACH_CELL(LAP5_CELL);
#undef LAP5_CELL
}

__kernel void laplacian9(__global const real *RESTRICT u, __global real *RESTRICT out,
                         const int nx, const int ny, const int y_kind, const real gy,
                         const int x_kind, const real gx, const real c9)
{
    GRID_ROW_OR_RETURN(i);
    const RowInfo r = row_info(i, nx, ny, y_kind);
#define LAP9_CELL(j, cc)                                                         \
    do {                                                                         \
        const ColInfo cc_ = (cc);                                                \
        out[r.c + (j)] = lap9_cell(load5(u, r, cc_, (j), gy, gx),                \
                                   load_diag(u, r, cc_, gy, gx), c9);            \
    } while (0)
    FOR_EACH_CELL(LAP9_CELL);
#undef LAP9_CELL
}
