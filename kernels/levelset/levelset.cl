/* First-order upwind level-set step and reinitialisation (equations §5).  Needs common.cl.
 *
 * One-sided differences D-x = (φ - W)/dx, D+x = (E - φ)/dx (likewise y), and
 *   ∇+ = SQRT(max(D-x,0)² + min(D+x,0)² + max(D-y,0)² + min(D+y,0)²)
 *   ∇- = SQRT(max(D+x,0)² + min(D-x,0)² + max(D+y,0)² + min(D-y,0)²)
 * levelset_step_{s,f}: out = φ - h (max(F,0) ∇+ + min(F,0) ∇-)   (F scalar / field)
 * reinit_step:        out = φ - h (max(S,0) ∇+ + min(S,0) ∇- - S),  S = φ0/SQRT(φ0² + w2)
 * reinit_step_subcell: the same with the Russo-Smereka fix at the front of φ0 (below)
 * Host constants: ix = 1/dx, iy = 1/dy, w2 = width² (rounded in `real`).
 * Every output is flushed of subnormals (FLUSH, see common.cl).
 */

typedef struct {
    real plus, minus;
} Grad2;

INLINE real sq(real a) { return a * a; }

INLINE Grad2 upwind_grad(Nbr5 q, real ix, real iy)
{
    const real dmx = (q.c - q.w) * ix, dpx = (q.e - q.c) * ix;
    const real dmy = (q.c - q.s) * iy, dpy = (q.n - q.c) * iy;
    Grad2 g;
    g.plus = SQRT(sq(max0(dmx)) + sq(min0(dpx)) + sq(max0(dmy)) + sq(min0(dpy)));
    g.minus = SQRT(sq(max0(dpx)) + sq(min0(dmx)) + sq(max0(dpy)) + sq(min0(dmy)));
    return g;
}

INLINE real levelset_cell(Nbr5 q, real f, real ix, real iy, real h)
{
    const Grad2 g = upwind_grad(q, ix, iy);
    return q.c - h * (max0(f) * g.plus + min0(f) * g.minus);
}

INLINE real reinit_cell(Nbr5 q, real p0, real w2, real ix, real iy, real h)
{
    const real s = p0 / SQRT(p0 * p0 + w2);
    const Grad2 g = upwind_grad(q, ix, iy);
    return q.c - h * (max0(s) * g.plus + min0(s) * g.minus - s);
}

/* np.sign: -1, 0 (keeping the zero's sign) or +1; NaN stays NaN */
INLINE real sign_of(real a) { return (a > R0) ? R1 : ((a < R0) ? -R1 : a); }

/* Russo-Smereka subcell fix: at a front cell of φ0 (a sign change to a 4-neighbour, or
 * φ0 == 0) relax φ towards the distance estimate D = φ0 / |∇φ0|:
 *   φ - rel (sgn(φ0) |φ| - D),   rel = Δτ / min(dx, dy),
 *   |∇φ0| = max(SQRT(cx² + cy²), |one-sided differences|, tiny),
 *   cx = (E - W) hx, cy = (N - S) hy,  hx = 0.5/dx, hy = 0.5/dy.
 * Elsewhere the Godunov value `away` is kept. */
INLINE real reinit_subcell(real away, real phi, Nbr5 z, real ix, real iy, real hx, real hy,
                           real rel, real tiny)
{
    const bool front = (z.c * z.w < R0) | (z.c * z.e < R0) | (z.c * z.s < R0) |
                       (z.c * z.n < R0) | (z.c == R0);
    const real cx = (z.e - z.w) * hx, cy = (z.n - z.s) * hy;
    real grad = SQRT(cx * cx + cy * cy);
    grad = nanmax(grad, FABS((z.e - z.c) * ix));
    grad = nanmax(grad, FABS((z.c - z.w) * ix));
    grad = nanmax(grad, FABS((z.n - z.c) * iy));
    grad = nanmax(grad, FABS((z.c - z.s) * iy));
    grad = nanmax(grad, tiny);
    const real dist = z.c / grad;
    const real relaxed = phi - rel * (sign_of(z.c) * FABS(phi) - dist);
    return front ? relaxed : away;
}

#define LEVELSET_KERNEL(NAME, FV)                                                         \
__kernel void NAME(__global const real *RESTRICT phi, __global const real *RESTRICT fp,   \
                   __global real *RESTRICT out, const int nx, const int ny,               \
                   const int y_kind, const real gy, const int x_kind, const real gx,      \
                   const real fs, const real ix, const real iy, const real h)             \
{                                                                                         \
    GRID_ROW_OR_RETURN(i);                                                                \
    const RowInfo r = row_info(i, nx, ny, y_kind);                                        \
    FOR_EACH_CELL(LS_CELL_##FV);                                                          \
}
#define LS_CELL_GEN(j, cc, FV)                                                            \
    do {                                                                                  \
        const long idx_ = r.c + (j);                                                       \
        out[idx_] = FLUSH(levelset_cell(load5(phi, r, (cc), (j), gy, gx), (FV), ix, iy,  \
                                        h));                                              \
    } while (0)
#define LS_CELL_S(j, cc) LS_CELL_GEN(j, cc, fs)
#define LS_CELL_F(j, cc) LS_CELL_GEN(j, cc, fp[idx_])

LEVELSET_KERNEL(levelset_step_s, S)
LEVELSET_KERNEL(levelset_step_f, F)

/* reinit_step (plain Godunov) and reinit_step_subcell (with the Russo-Smereka fix) */
#define REINIT_KERNEL(NAME, SUBCELL)                                                      \
__kernel void NAME(__global const real *RESTRICT phi, __global const real *RESTRICT phi0, \
                   __global real *RESTRICT out, const int nx, const int ny,               \
                   const int y_kind, const real gy, const int x_kind, const real gx,      \
                   const real w2, const real ix, const real iy, const real h,             \
                   const real hx, const real hy, const real rel, const real tiny)         \
{                                                                                         \
    GRID_ROW_OR_RETURN(i);                                                                \
    const RowInfo r = row_info(i, nx, ny, y_kind);                                        \
    FOR_EACH_CELL(RI_CELL_##SUBCELL);                                                     \
}
#define RI_CELL_0(j, cc)                                                                  \
    do {                                                                                  \
        const long idx_ = r.c + (j);                                                       \
        out[idx_] = FLUSH(reinit_cell(load5(phi, r, (cc), (j), gy, gx), phi0[idx_], w2, ix, iy, \
                                      h));                                                \
    } while (0)
#define RI_CELL_1(j, cc)                                                                  \
    do {                                                                                  \
        const ColInfo cc_ = (cc);                                                         \
        const long idx_ = r.c + (j);                                                       \
        const Nbr5 q_ = load5(phi, r, cc_, (j), gy, gx);                                  \
        const real away_ = reinit_cell(q_, phi0[idx_], w2, ix, iy, h);                    \
        out[idx_] = FLUSH(reinit_subcell(away_, q_.c, load5(phi0, r, cc_, (j), gy, gx), ix, \
                                         iy, hx, hy, rel, tiny));                         \
    } while (0)

REINIT_KERNEL(reinit_step, 0)
REINIT_KERNEL(reinit_step_subcell, 1)
