/* rdgpu OpenCL helpers shared by every kernel family.
 *
 * The host builds one program per (context, dtype, layout) from this file followed by the
 * family sources, with these build options:
 *
 *   -D REAL_IS_DOUBLE=0|1   `real` is float or double
 *   -D COL_STRIDE=n         column stride of the grid kernels (see "Layouts" below)
 *   -D ROW_LAYOUT=0|1       1: one work-item per row (CPU devices)
 *   -D RDGPU_NO_RESTRICT    no `restrict` qualifiers (for Oclgrind)
 *   -D RDGPU_CLANG_BUILTINS sqrt/fabs as clang builtins (PoCL; see SQRT below)
 *
 * Layouts.  A grid kernel is launched on the NDRange (COL_STRIDE, ny): work-item (j0, i)
 * handles the columns j0, j0 + COL_STRIDE, ... of row i.
 *   - ROW_LAYOUT = 1 (CPU): COL_STRIDE = 1, so one work-item walks a whole row; the two edge
 *     columns are peeled and the interior loop has no branch, so LLVM vectorises it.
 *   - ROW_LAYOUT = 0 (GPU): COL_STRIDE = 64..256, consecutive work-items read consecutive
 *     columns (coalesced); each cell resolves its ghosts with selects.
 * Both layouts call the same inline cell functions, so their arithmetic cannot drift.
 *
 * Boundary conditions (see rdgpu/boundary.py): per axis a kind (BC_PERIODIC, BC_NEUMANN,
 * BC_DIRICHLET) and a value g.  Ghost cells: periodic wraps, Neumann repeats the edge cell,
 * Dirichlet is g.  Corner ghosts (9-point stencil) resolve y first: a Dirichlet-y ghost row
 * is g_y everywhere, otherwise the row is wrapped/clamped and the column is resolved with
 * the x rule.
 *
 * Arithmetic follows the NumPy references operation by operation (same order, no
 * contraction into FMAs), so float64 results agree bit for bit and float32 results too
 * wherever the device rounds sqrt/division correctly.
 *
 * Subnormals (docs/equations.md): every value a kernel writes goes through FLUSH, which
 * turns a value whose magnitude is below the smallest normal number of `real` into 0.  The host also
 * builds with -cl-denorms-are-zero: devices that honour it (PoCL sets the x86 FTZ/DAZ
 * bits while a kernel runs) then flush intermediate results too, so that no kernel slows
 * down on subnormal arithmetic; FLUSH makes the outputs follow the rule on every device.
 */

#pragma OPENCL FP_CONTRACT OFF

#ifndef REAL_IS_DOUBLE
#define REAL_IS_DOUBLE 0
#endif

#if REAL_IS_DOUBLE
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
typedef double real;
#else
typedef float real;
#endif

/* Helper functions are `static inline`: a plain C99 `inline` definition may be left
 * without an out-of-line body when a compiler does not inline it (-cl-opt-disable).
 * OpenCL C 1.1 has no `static` functions. */
#if defined(__OPENCL_C_VERSION__) && __OPENCL_C_VERSION__ >= 120
#define INLINE static inline
#else
#define INLINE inline
#endif

/* restrict-qualified pointers (no aliasing between a kernel's arrays) help LLVM vectorise;
 * -D RDGPU_NO_RESTRICT drops them (Oclgrind cannot interpret the noalias intrinsics) */
#ifdef RDGPU_NO_RESTRICT
#define RESTRICT
#else
#define RESTRICT restrict
#endif

#ifndef COL_STRIDE
#define COL_STRIDE 1
#endif

#ifndef ROW_LAYOUT
#define ROW_LAYOUT 1
#endif

/* sqrt and fabs.  PoCL links its builtin library functions as out-of-line calls, which
 * stops LLVM from vectorising a loop; with -D RDGPU_CLANG_BUILTINS (the host passes it for
 * PoCL) the clang builtins become the llvm.sqrt / llvm.fabs intrinsics instead (IEEE
 * correctly rounded, vectorisable).  Other compilers get the standard functions. */
#if defined(RDGPU_CLANG_BUILTINS) && REAL_IS_DOUBLE
#define SQRT(x) __builtin_sqrt(x)
#define FABS(x) __builtin_fabs(x)
#elif defined(RDGPU_CLANG_BUILTINS)
#define SQRT(x) __builtin_sqrtf(x)
#define FABS(x) __builtin_fabsf(x)
#else
#define SQRT(x) sqrt(x)
#define FABS(x) fabs(x)
#endif

#define BC_PERIODIC 0
#define BC_NEUMANN 1
#define BC_DIRICHLET 2
/* the kernels' own kind (rdgpu.domains.boundary.WRAPPED): loads wrap as periodic ones, the
 * end cells carry ghost flags as Dirichlet ones (per-species conditions on such an axis) */
#define BC_WRAPPED 3

#define R0 ((real)0)
#define R1 ((real)1)
#define R2 ((real)2)

/* Flush a subnormal to 0 (NaN and infinities pass): a select, so loops still vectorise. */
#if REAL_IS_DOUBLE
#define REAL_MIN_NORMAL DBL_MIN
#else
#define REAL_MIN_NORMAL FLT_MIN
#endif
INLINE real FLUSH(real x) { return (FABS(x) < REAL_MIN_NORMAL) ? R0 : x; }

/* max/min with 0 that propagate NaN like np.maximum / np.minimum */
INLINE real max0(real a) { return (a < R0) ? R0 : a; }
INLINE real min0(real a) { return (a > R0) ? R0 : a; }

/* NaN-propagating max (np.max semantics) */
INLINE real nanmax(real a, real b) { return (a != a || a > b) ? a : b; }

/* ------------------------------------------------------------------ ghost resolution
 * The neighbour of a cell along one axis is described by an in-range index plus a flag
 * "this is a Dirichlet ghost": the value is then (flag ? g : a[index]).  The index is
 * always valid (clamped when the ghost is Dirichlet) so the load is always safe.       */

/* index of the neighbour below (idx - 1) of position idx on an axis of length n */
INLINE bool kind_wraps(int kind) { return kind == BC_PERIODIC || kind == BC_WRAPPED; }

INLINE int lo_index(int idx, int n, int kind)
{
    if (idx > 0) return idx - 1;
    return kind_wraps(kind) ? n - 1 : 0;
}

/* index of the neighbour above (idx + 1) */
INLINE int hi_index(int idx, int n, int kind)
{
    if (idx < n - 1) return idx + 1;
    return kind_wraps(kind) ? 0 : n - 1;
}

INLINE bool lo_is_ghost(int idx, int kind) { return idx == 0 && kind >= BC_DIRICHLET; }
INLINE bool hi_is_ghost(int idx, int n, int kind) { return idx == n - 1 && kind >= BC_DIRICHLET; }

/* Everything a row needs to find its neighbours (computed once per row). */
typedef struct {
    long c, s, n;        /* offsets (in elements) of this row, the row below (i-1), above (i+1);
                          * 64-bit so that LLVM sees consecutive addresses and vectorises */
    bool s_dir, n_dir;   /* the row below / above is a Dirichlet ghost row */
} RowInfo;

INLINE RowInfo row_info(int i, int nx, int ny, int y_kind)
{
    RowInfo r;
    r.c = (long)i * nx;
    r.s = (long)lo_index(i, ny, y_kind) * nx;
    r.n = (long)hi_index(i, ny, y_kind) * nx;
    r.s_dir = lo_is_ghost(i, y_kind);
    r.n_dir = hi_is_ghost(i, ny, y_kind);
    return r;
}

/* Column neighbours of column j. */
typedef struct {
    long w, e;           /* in-range column indices of the west (j-1) / east (j+1) neighbours */
    bool w_dir, e_dir;   /* the neighbour is a Dirichlet ghost */
} ColInfo;

INLINE ColInfo col_info(int j, int nx, int x_kind)
{
    ColInfo c;
    c.w = lo_index(j, nx, x_kind);
    c.e = hi_index(j, nx, x_kind);
    c.w_dir = lo_is_ghost(j, x_kind);
    c.e_dir = hi_is_ghost(j, nx, x_kind);
    return c;
}

/* Column neighbours of an interior column (0 < j < nx-1), or of a cell k in a flat loop
 * over whole rows (model.cl's rd_span: k - 1, k + 1): no ghost at all. */
INLINE ColInfo col_interior(long j)
{
    ColInfo c;
    c.w = j - 1;
    c.e = j + 1;
    c.w_dir = false;
    c.e_dir = false;
    return c;
}

/* The column neighbours of a row's first (col_first) and last (col_last) cell in a flat
 * loop, the row starting at cell k0: col_info(0 / nx - 1) moved to the flat indices. */
INLINE ColInfo col_first(long k0, int nx, int x_kind)
{
    ColInfo c = col_info(0, nx, x_kind);
    c.w += k0;
    c.e += k0;
    return c;
}

INLINE ColInfo col_last(long k0, int nx, int x_kind)
{
    ColInfo c = col_info(nx - 1, nx, x_kind);
    c.w += k0;
    c.e += k0;
    return c;
}

/* The five-point neighbourhood of one cell with ghosts resolved. */
typedef struct {
    real c, w, e, s, n;
} Nbr5;

INLINE Nbr5 load5(__global const real *a, RowInfo r, ColInfo cc, int j, real gy, real gx)
{
    /* every load is unconditional (the indices are always in range), then a select picks
     * the ghost value: no conditional load in the loop, so it vectorises */
    const real w = a[r.c + cc.w], e = a[r.c + cc.e], s = a[r.s + j], n = a[r.n + j];
    Nbr5 q;
    q.c = a[r.c + j];
    q.w = cc.w_dir ? gx : w;
    q.e = cc.e_dir ? gx : e;
    q.s = r.s_dir ? gy : s;
    q.n = r.n_dir ? gy : n;
    return q;
}

/* The four diagonal neighbours (corner rule: y first, then x). */
typedef struct {
    real sw, se, nw, ne;
} Nbr4d;

INLINE Nbr4d load_diag(__global const real *a, RowInfo r, ColInfo cc, real gy, real gx)
{
    const real sw = a[r.s + cc.w], se = a[r.s + cc.e], nw = a[r.n + cc.w], ne = a[r.n + cc.e];
    Nbr4d q;
    q.sw = r.s_dir ? gy : (cc.w_dir ? gx : sw);
    q.se = r.s_dir ? gy : (cc.e_dir ? gx : se);
    q.nw = r.n_dir ? gy : (cc.w_dir ? gx : nw);
    q.ne = r.n_dir ? gy : (cc.e_dir ? gx : ne);
    return q;
}

/* ------------------------------------------------------------------ row iteration
 * FOR_EACH_CELL(CELL) runs CELL(j, cc) over the columns this work-item owns, where cc is
 * the ColInfo of column j.  Needs nx, x_kind in scope.  In the row layout the edge
 * columns are peeled and the interior loop sees compile-time "no ghost" flags.         */

#if ROW_LAYOUT
#define FOR_EACH_CELL(CELL)                                          \
    do {                                                             \
        if (nx <= 2) {                                               \
            for (int j_ = 0; j_ < nx; ++j_) {                        \
                CELL(j_, col_info(j_, nx, x_kind));                  \
            }                                                        \
        } else {                                                     \
            CELL(0, col_info(0, nx, x_kind));                        \
            for (int j_ = 1; j_ < nx - 1; ++j_) {                    \
                CELL(j_, col_interior(j_));                          \
            }                                                        \
            CELL(nx - 1, col_info(nx - 1, nx, x_kind));              \
        }                                                            \
    } while (0)
#else
#define FOR_EACH_CELL(CELL)                                          \
    do {                                                             \
        for (int j_ = (int)get_global_id(0); j_ < nx; j_ += COL_STRIDE) { \
            CELL(j_, col_info(j_, nx, x_kind));                      \
        }                                                            \
    } while (0)
#endif

/* The row of this work-item, or return when it is past the grid. */
#define GRID_ROW_OR_RETURN(i)                                        \
    const int i = (int)get_global_id(1);                             \
    if (i >= ny) return
