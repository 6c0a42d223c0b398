/* First-order upwind level-set step and reinitialisation (equations §5).  Needs common.cl.
 *
 * One-sided differences D-x = (φ - W)/dx, D+x = (E - φ)/dx (likewise y), and
 *   ∇+ = SQRT(max(D-x,0)² + min(D+x,0)² + max(D-y,0)² + min(D+y,0)²)
 *   ∇- = SQRT(max(D+x,0)² + min(D-x,0)² + max(D+y,0)² + min(D-y,0)²)
 * levelset_step_{s,f}: out = φ - h (max(F,0) ∇+ + min(F,0) ∇-)   (F scalar / field)
 * reinit_step:        out = φ - h (max(S,0) ∇+ + min(S,0) ∇- - S),  S = φ0/SQRT(φ0² + w2)
 * reinit_step_subcell: the same with the Russo-Smereka fix at the front of φ0 (below)
 * Host constants: ix = 1/dx, iy = 1/dy, w2 = width² (rounded in `real`).
 * The *3 kernels are the same on a 3-D grid [nz, ny, nx] (seed 003, eq. 3.11): the z terms
 * D±z = ±(T|B - φ)/dz join the sums after the x and y ones (iz = 1/dz).
 * Every output is flushed of subnormals (FLUSH, see common.cl).
 */

typedef struct {
    real plus, minus;
} Grad2;

INLINE real sq(real a) { return a * a; }

/* the sums of squares under the roots of ∇+ and ∇- (x terms, then y terms) */
INLINE Grad2 upwind_sq(Nbr5 q, real ix, real iy)
{
    const real dmx = (q.c - q.w) * ix, dpx = (q.e - q.c) * ix;
    const real dmy = (q.c - q.s) * iy, dpy = (q.n - q.c) * iy;
    Grad2 g;
    g.plus = sq(max0(dmx)) + sq(min0(dpx)) + sq(max0(dmy)) + sq(min0(dpy));
    g.minus = sq(max0(dpx)) + sq(min0(dmx)) + sq(max0(dpy)) + sq(min0(dmy));
    return g;
}

INLINE Grad2 upwind_grad(Nbr5 q, real ix, real iy)
{
    Grad2 g = upwind_sq(q, ix, iy);
    g.plus = SQRT(g.plus);
    g.minus = SQRT(g.minus);
    return g;
}

/* 3-D (seed 003, eq. 3.11): the z terms (below b, above t) join the 2-D sums */
INLINE Grad2 upwind_grad3(Nbr5 q, real b, real t, real ix, real iy, real iz)
{
    Grad2 g = upwind_sq(q, ix, iy);
    const real dmz = (q.c - b) * iz, dpz = (t - q.c) * iz;
    g.plus = SQRT(g.plus + sq(max0(dmz)) + sq(min0(dpz)));
    g.minus = SQRT(g.minus + sq(max0(dpz)) + sq(min0(dmz)));
    return g;
}

INLINE real levelset_apply(real c, Grad2 g, real f, real h)
{
    return c - h * (max0(f) * g.plus + min0(f) * g.minus);
}

INLINE real levelset_cell(Nbr5 q, real f, real ix, real iy, real h)
{
    return levelset_apply(q.c, upwind_grad(q, ix, iy), f, h);
}

INLINE real reinit_apply(real c, Grad2 g, real p0, real w2, real h)
{
    const real s = p0 / SQRT(p0 * p0 + w2);
    return c - h * (max0(s) * g.plus + min0(s) * g.minus - s);
}

INLINE real reinit_cell(Nbr5 q, real p0, real w2, real ix, real iy, real h)
{
    return reinit_apply(q.c, upwind_grad(q, ix, iy), p0, w2, h);
}

/* np.sign: -1, 0 (keeping the zero's sign) or +1; NaN stays NaN */
INLINE real sign_of(real a) { return (a > R0) ? R1 : ((a < R0) ? -R1 : a); }

/* Russo-Smereka subcell fix: at a front cell of φ0 (a sign change to a face neighbour, or
 * φ0 == 0) relax φ towards the distance estimate D = φ0 / |∇φ0|:
 *   φ - rel (sgn(φ0) |φ| - D),   rel = Δτ / min(dx, dy(, dz)),
 *   |∇φ0| = max(SQRT(cx² + cy² (+ cz²)), |one-sided differences|, tiny),
 *   cx = (E - W) hx, cy = (N - S) hy, cz = (T - B) hz,  hx = 0.5/dx, ...
 * Elsewhere the Godunov value `away` is kept. */
INLINE bool front_xy(Nbr5 z)
{
    return (z.c * z.w < R0) | (z.c * z.e < R0) | (z.c * z.s < R0) | (z.c * z.n < R0) |
           (z.c == R0);
}

INLINE real one_sided_xy(real grad, Nbr5 z, real ix, real iy)
{
    grad = nanmax(grad, FABS((z.e - z.c) * ix));
    grad = nanmax(grad, FABS((z.c - z.w) * ix));
    grad = nanmax(grad, FABS((z.n - z.c) * iy));
    return nanmax(grad, FABS((z.c - z.s) * iy));
}

INLINE real subcell_relax(real away, real phi, real p0, bool front, real grad, real rel,
                          real tiny)
{
    const real dist = p0 / nanmax(grad, tiny);
    const real relaxed = phi - rel * (sign_of(p0) * FABS(phi) - dist);
    return front ? relaxed : away;
}

INLINE real reinit_subcell(real away, real phi, Nbr5 z, real ix, real iy, real hx, real hy,
                           real rel, real tiny)
{
    const real cx = (z.e - z.w) * hx, cy = (z.n - z.s) * hy;
    const real grad = one_sided_xy(SQRT(cx * cx + cy * cy), z, ix, iy);
    return subcell_relax(away, phi, z.c, front_xy(z), grad, rel, tiny);
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

/* ------------------------------------------------------------------ 3-D grids
 * nz × ny rows of nx cells, one work-item per row (CPU) or COL_STRIDE per row (GPU).  A
 * row's in-plane neighbours are those of the 2-D kernels (offset to its plane); its plane
 * neighbours below (B, k - 1) and above (T, k + 1) are resolved once per row by the z rule. */
typedef struct {
    RowInfo r;           /* offsets in the whole array (plane included) */
    long b, t;           /* offsets of the same row in the plane below / above */
    bool b_dir, t_dir;   /* that plane is a Dirichlet ghost */
} RowInfo3;

INLINE RowInfo3 row_info3(int row, int nx, int ny, int nz, int y_kind, int z_kind)
{
    const int i = row % ny, k = row / ny;
    const long plane = (long)k * ny * nx;
    RowInfo3 q;
    q.r = row_info(i, nx, ny, y_kind);
    q.r.c += plane;
    q.r.s += plane;
    q.r.n += plane;
    q.b = ((long)lo_index(k, nz, z_kind) * ny + i) * nx;
    q.t = ((long)hi_index(k, nz, z_kind) * ny + i) * nx;
    q.b_dir = lo_is_ghost(k, z_kind);
    q.t_dir = hi_is_ghost(k, nz, z_kind);
    return q;
}

INLINE real below(__global const real *a, RowInfo3 q, int j, real gz)
{
    const real v = a[q.b + j];
    return q.b_dir ? gz : v;
}

INLINE real above(__global const real *a, RowInfo3 q, int j, real gz)
{
    const real v = a[q.t + j];
    return q.t_dir ? gz : v;
}

#define GRID3_ROW_OR_RETURN(q3)                                                           \
    const int row3_ = (int)get_global_id(1);                                              \
    if (row3_ >= ny * nz) return;                                                         \
    const RowInfo3 q3 = row_info3(row3_, nx, ny, nz, y_kind, z_kind);                     \
    const RowInfo r = q3.r

#define LEVELSET3_KERNEL(NAME, FV)                                                        \
__kernel void NAME(__global const real *RESTRICT phi, __global const real *RESTRICT fp,   \
                   __global real *RESTRICT out, const int nx, const int ny, const int nz, \
                   const int y_kind, const real gy, const int x_kind, const real gx,      \
                   const int z_kind, const real gz,                                       \
                   const real fs, const real ix, const real iy, const real iz, const real h) \
{                                                                                         \
    GRID3_ROW_OR_RETURN(q3);                                                              \
    FOR_EACH_CELL(LS3_CELL_##FV);                                                         \
}
#define LS3_CELL_GEN(j, cc, FV)                                                           \
    do {                                                                                  \
        const long idx_ = r.c + (j);                                                      \
        const Nbr5 q_ = load5(phi, r, (cc), (j), gy, gx);                                 \
        const Grad2 g_ = upwind_grad3(q_, below(phi, q3, (j), gz), above(phi, q3, (j), gz), \
                                      ix, iy, iz);                                        \
        out[idx_] = FLUSH(levelset_apply(q_.c, g_, (FV), h));                            \
    } while (0)
#define LS3_CELL_S(j, cc) LS3_CELL_GEN(j, cc, fs)
#define LS3_CELL_F(j, cc) LS3_CELL_GEN(j, cc, fp[idx_])

LEVELSET3_KERNEL(levelset_step3_s, S)
LEVELSET3_KERNEL(levelset_step3_f, F)

#define REINIT3_KERNEL(NAME, SUBCELL)                                                     \
__kernel void NAME(__global const real *RESTRICT phi, __global const real *RESTRICT phi0, \
                   __global real *RESTRICT out, const int nx, const int ny, const int nz, \
                   const int y_kind, const real gy, const int x_kind, const real gx,      \
                   const int z_kind, const real gz,                                       \
                   const real w2, const real ix, const real iy, const real iz, const real h, \
                   const real hx, const real hy, const real hz, const real rel,           \
                   const real tiny)                                                       \
{                                                                                         \
    GRID3_ROW_OR_RETURN(q3);                                                              \
    FOR_EACH_CELL(RI3_CELL_##SUBCELL);                                                    \
}
#define RI3_AWAY(j, cc)                                                                   \
        const ColInfo cc_ = (cc);                                                         \
        const long idx_ = r.c + (j);                                                      \
        const Nbr5 q_ = load5(phi, r, cc_, (j), gy, gx);                                  \
        const Grad2 g_ = upwind_grad3(q_, below(phi, q3, (j), gz), above(phi, q3, (j), gz), \
                                      ix, iy, iz);                                        \
        const real away_ = reinit_apply(q_.c, g_, phi0[idx_], w2, h)
#define RI3_CELL_0(j, cc)                                                                 \
    do {                                                                                  \
        RI3_AWAY(j, cc);                                                                  \
        (void)cc_;                                                                        \
        out[idx_] = FLUSH(away_);                                                         \
    } while (0)
#define RI3_CELL_1(j, cc)                                                                 \
    do {                                                                                  \
        RI3_AWAY(j, cc);                                                                  \
        const Nbr5 z_ = load5(phi0, r, cc_, (j), gy, gx);                                 \
        const real zb_ = below(phi0, q3, (j), gz), zt_ = above(phi0, q3, (j), gz);        \
        const real cx_ = (z_.e - z_.w) * hx, cy_ = (z_.n - z_.s) * hy;                    \
        const real cz_ = (zt_ - zb_) * hz;                                                \
        real gr_ = one_sided_xy(SQRT(cx_ * cx_ + cy_ * cy_ + cz_ * cz_), z_, ix, iy);      \
        gr_ = nanmax(gr_, FABS((zt_ - z_.c) * iz));                                        \
        gr_ = nanmax(gr_, FABS((z_.c - zb_) * iz));                                        \
        const bool fr_ = front_xy(z_) | (z_.c * zb_ < R0) | (z_.c * zt_ < R0);            \
        out[idx_] = FLUSH(subcell_relax(away_, q_.c, z_.c, fr_, gr_, rel, tiny));         \
    } while (0)

REINIT3_KERNEL(reinit_step3, 0)
REINIT3_KERNEL(reinit_step3_subcell, 1)
