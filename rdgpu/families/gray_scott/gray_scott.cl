/* One fused forward-Euler Gray-Scott step (equations §3).  Needs common.cl.
 *
 *   u' = u + h (Du Δu - u v² + F (1 - u))
 *   v' = v + h (Dv Δv + u v² - (F + k) v)
 *
 * with the 5-point Laplacian; both outputs are flushed of subnormals (see common.cl).
 * F and k are scalars or per-cell fields: four kernels gray_scott_{s,f}{s,f} (F then k;
 * s = scalar, f = field) share one inline body.  A scalar's pointer argument is unused
 * (the host passes any buffer).
 */

INLINE void gs_cell(Nbr5 a, Nbr5 b, real cx, real cy, real Du, real Dv, real F, real k,
                    real h, __global real *uo, __global real *vo, long idx)
{
    const real lap_u = (a.e + a.w - R2 * a.c) * cx + (a.n + a.s - R2 * a.c) * cy;
    const real lap_v = (b.e + b.w - R2 * b.c) * cx + (b.n + b.s - R2 * b.c) * cy;
    const real uvv = a.c * b.c * b.c;
    uo[idx] = FLUSH(a.c + h * (Du * lap_u - uvv + F * (R1 - a.c)));
    vo[idx] = FLUSH(b.c + h * (Dv * lap_v + uvv - (F + k) * b.c));
}

#define GRAY_SCOTT_KERNEL(NAME, F_FIELD, K_FIELD)                                         \
__kernel void NAME(__global const real *RESTRICT u, __global const real *RESTRICT v,      \
                   __global real *RESTRICT uo, __global real *RESTRICT vo,                \
                   __global const real *RESTRICT Fp, __global const real *RESTRICT kp,    \
                   const int nx, const int ny, const int y_kind, const real gy,            \
                   const int x_kind, const real gx, const real cx, const real cy,         \
                   const real Du, const real Dv, const real Fs, const real ks,            \
                   const real h)                                                          \
{                                                                                         \
    GRID_ROW_OR_RETURN(i);                                                                \
    const RowInfo r = row_info(i, nx, ny, y_kind);                                        \
    FOR_EACH_CELL(GS_CELL_##F_FIELD##K_FIELD);                                            \
}

#define GS_CELL_GEN(j, cc, FV, KV)                                                        \
    do {                                                                                  \
        const ColInfo cc_ = (cc);                                                         \
        const long idx_ = r.c + (j);                                                       \
        gs_cell(load5(u, r, cc_, (j), gy, gx), load5(v, r, cc_, (j), gy, gx), cx, cy,     \
                Du, Dv, (FV), (KV), h, uo, vo, idx_);                                     \
    } while (0)
#define GS_CELL_00(j, cc) GS_CELL_GEN(j, cc, Fs, ks)
#define GS_CELL_10(j, cc) GS_CELL_GEN(j, cc, Fp[idx_], ks)
#define GS_CELL_01(j, cc) GS_CELL_GEN(j, cc, Fs, kp[idx_])
#define GS_CELL_11(j, cc) GS_CELL_GEN(j, cc, Fp[idx_], kp[idx_])

GRAY_SCOTT_KERNEL(gray_scott_ss, 0, 0)
GRAY_SCOTT_KERNEL(gray_scott_fs, 1, 0)
GRAY_SCOTT_KERNEL(gray_scott_sf, 0, 1)
GRAY_SCOTT_KERNEL(gray_scott_ff, 1, 1)
