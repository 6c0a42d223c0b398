/* Temporal blocking of a model's explicit Euler step on a 3-D grid (rdgpu/integrators/blocking.py):
 * `steps` = K steps per pass over the grid, bit for bit the K single steps of rd_program
 * (model.cl).  Needs common.cl, the head of model.cl and the row layout.
 *
 * blocked.cl's scheme one dimension up: a work-item takes a band of `band` z-planes
 * [r0, e0) of one member's volume and advances it K steps; level k at planes
 * [r0 − K + k, e0 + K − k) needs level k − 1 one plane further on each side, so level 0
 * (the input) is read K planes beyond the band (the halo, recomputed by both neighbouring
 * bands).  Periodic z wraps (virtual plane v is plane v mod nz); Neumann / Dirichlet z stop
 * at the domain's edge, where the edge plane uses the step kernel's boundary rule (the
 * neighbour plane clamped, the Dirichlet flags db / dt_).  The levels run as a wavefront
 * down the band (at each t: level 1 plane t, level 2 plane t − 1, ...), so each
 * intermediate level keeps a ring of 3 planes per species in the work-item's scratch
 * (`scratch_`, (K − 1)·NS·3·ny·nx values per work-item, sized to stay in the core's L2).
 * Level 1 reads the input buffers, level K writes the outputs (the band's planes only).
 *
 * A plane goes through rd_plane: the step kernel's cell body (the same compiler function,
 * opencl_cell) over its rows, each with the y rule of the step kernel, and their columns
 * (FOR_EACH_CELL); the time of level k is times_[k − 1]. */

/* One plane of one step: level k − 1's plane at pc with its z neighbours at pb, pt (db,
 * dt_: Dirichlet ghost planes), the parameter fields' plane at pf, the output's at po; kz
 * the grid plane (for the z coordinate), m_ the ensemble member. */
INLINE void rd_plane(@ARGS@,
        const int nx, const int ny, const int x_kind, const real gx, const int y_kind,
        const real gy, const real gz, const real cx, const real cy, const real cz,
        const real dx, const real dy, const real dz,
        const long pc, const long pb, const long pt, const bool db, const bool dt_,
        const long pf, const long po, const int kz, const int m_)
{
    (void)m_;
@ROW@
    const real zc = ((real)kz + (real)0.5) * dz;
    (void)zc; (void)dx; (void)cy; (void)cz; (void)gy; (void)gz; (void)db; (void)dt_;
#define RD_CELL(j, cc)                                                                    \
    do {                                                                                  \
        const ColInfo cc_ = (cc);                                                         \
        const long k_ = rc + (j);                                                         \
        const long kf_ = rf + (j);                                                        \
        const long ko_ = ro + (j);                                                        \
        (void)cc_; (void)kf_;                                                             \
@CELL@ \
    } while (0)
#if @FLAT@
    /* programs without the x or y coordinate: the interior rows (0 < i < ny − 1) as ONE
     * loop over the plane's cells with neighbours at fixed offsets, then their x-edge cells
     * again with the x rule, as model.cl's rd_span */
    const bool flat_ = nx >= 3 && ny >= 3;
    if (flat_) {
        const long rc = pc, rs = pc - nx, rn = pc + nx;
        const bool ds = false, dn = false;
        const long rb = pb, rt = pt, rbs = pb - nx, rbn = pb + nx, rts = pt - nx, rtn = pt + nx;
        const long rf = pf, ro = po;
        (void)rs; (void)rn; (void)ds; (void)dn; (void)rb; (void)rt;
        (void)rbs; (void)rbn; (void)rts; (void)rtn;
        const long end_ = (long)(ny - 1) * nx;
        for (long j_ = (long)nx + 1; j_ < end_ - 1; ++j_) {
            RD_CELL(j_, col_interior(j_));
        }
        for (long r0_ = nx; r0_ < end_; r0_ += nx) {
            RD_CELL(r0_, col_first(r0_, nx, x_kind));
            RD_CELL(r0_ + nx - 1, col_last(r0_, nx, x_kind));
        }
    }
#else
    const bool flat_ = false;
#endif
    /* every row with its y rule (flat: rows 0 and ny − 1 only) */
    for (int i = 0; i < ny; i += flat_ ? ny - 1 : 1) {
        const int is = lo_index(i, ny, y_kind), in_ = hi_index(i, ny, y_kind);
        const long rc = pc + (long)i * nx;
        const long rs = pc + (long)is * nx, rn = pc + (long)in_ * nx;
        const bool ds = lo_is_ghost(i, y_kind), dn = hi_is_ghost(i, ny, y_kind);
        const long rb = pb + (long)i * nx, rt = pt + (long)i * nx;
        const long rbs = pb + (long)is * nx, rbn = pb + (long)in_ * nx;
        const long rts = pt + (long)is * nx, rtn = pt + (long)in_ * nx;
        const long rf = pf + (long)i * nx, ro = po + (long)i * nx;
        const real yc = ((real)i + (real)0.5) * dy;
        (void)rs; (void)rn; (void)ds; (void)dn; (void)rb; (void)rt; (void)yc;
        (void)rbs; (void)rbn; (void)rts; (void)rtn;
        FOR_EACH_CELL(RD_CELL);
    }
#undef RD_CELL
}

/* position of virtual plane v in a ring of 3 planes (v may be negative) */
INLINE long ring_plane(int v) { return (long)(((v % 3) + 3) % 3); }

/* NDRange (items): work-item `item` takes the bands item, item + items, ... of the
 * volumes·⌈nz/band⌉ bands (a volume: one ensemble member). */
__kernel void rd_blocked3(@ARGS@,
        __global const real *RESTRICT times_, __global real *RESTRICT scratch_,
        const int nx, const int ny, const int nz, const int volumes,
        const int x_kind, const real gx, const int y_kind, const real gy,
        const int z_kind, const real gz,
        const real cx, const real cy, const real cz,
        const real dx, const real dy, const real dz,
        const int steps, const int band, const int items)
{
    const int item = (int)get_global_id(0);
    if (item >= items) return;
    (void)b_t;  /* the levels' times come from times_ */
    const long plane_ = (long)ny * nx;
    const long ring_ = 3L * plane_;  /* one species' ring of one level */
    __global real *mine_ = scratch_ + (long)item * (steps - 1) * @NS@ * ring_;
    const int bands = (nz + band - 1) / band;
    const bool wrap = kind_wraps(z_kind);
    for (int w = item; w < bands * volumes; w += items) {
        const int m_ = w / bands;
        const long p0 = (long)m_ * nz * plane_;  /* the member's first value */
        const int r0 = (w % bands) * band;
        const int e0 = min(r0 + band, nz);
        for (int t = r0 - steps + 1; t < e0 + steps - 1; ++t) {
            for (int k = 1; k <= steps; ++k) {
                const int v = t - k + 1;  /* the virtual plane of level k */
                const int lo = wrap ? r0 - steps + k : max(r0 - steps + k, 0);
                const int hi = wrap ? e0 + steps - k : min(e0 + steps - k, nz);
                if (v < lo || v >= hi) continue;
                const int kz = ((v % nz) + nz) % nz;
                const long pf = p0 + (long)kz * plane_;
                /* level k − 1: the input buffers (k = 1) or its ring */
                const long pc = (k == 1) ? pf : ring_plane(v) * plane_;
                const long pb = (k == 1) ? p0 + (long)lo_index(kz, nz, z_kind) * plane_
                    : ring_plane((wrap || kz > 0) ? v - 1 : v) * plane_;
                const long pt = (k == 1) ? p0 + (long)hi_index(kz, nz, z_kind) * plane_
                    : ring_plane((wrap || kz < nz - 1) ? v + 1 : v) * plane_;
                /* level k: the output buffers (k = K) or its ring */
                const long po = (k == steps) ? pf : ring_plane(v) * plane_;
                __global const real *src_ = mine_ + (long)max(k - 2, 0) * @NS@ * ring_;
                __global real *dst_ = mine_ + (long)min(k - 1, steps - 2) * @NS@ * ring_;
                (void)src_; (void)dst_;
@SELECT@
                rd_plane(@CALL@,
                         nx, ny, x_kind, gx, y_kind, gy, gz, cx, cy, cz, dx, dy, dz,
                         pc, pb, pt, lo_is_ghost(kz, z_kind), hi_is_ghost(kz, nz, z_kind),
                         pf, po, kz, m_);
            }
        }
    }
}
