/* DLA growth kernels (seed 001 §1, eq. 2): the maths of dla/reference.py.  Needs common.cl.
 *
 * States (uchar): 0 empty, 1 object, 2 held boundary.  A candidate is an empty cell with
 * a 4-neighbour in the object (x wraps when wrap_x).  Its weight is
 * min(max(c, 0), 1)^eta in double (mode 0: 1, 1: sqrt, 2: x, 3: x*x, 4: pow(x, eta)),
 * quantised to long as trunc(w * 2^40); other cells weigh 0.  Integer sums are exact, so
 * every backend gets the same row sums and picks the same cell.
 *
 * dla_weights: one work-item per row (global (1, ny)), weights and the row's sum.
 * dla_pick: one work-item; the first cell of `row` whose inclusive running sum exceeds
 * `target` becomes object (state 1, c = 0, arrival = step, weight 0); out = {column,
 * weight} or {-1, 0}.  Needs double precision (cl_khr_fp64) for the weights.
 */

#pragma OPENCL EXTENSION cl_khr_fp64 : enable

#define DLA_QUANTUM 1099511627776.0 /* 2^40 */

INLINE double dla_power(double x, int mode, double eta)
{
    if (mode == 1) return sqrt(x);
    if (mode == 2) return x;
    if (mode == 3) return x * x;
    if (mode == 4) return pow(x, eta);
    return 1.0;
}

__kernel void dla_weights(__global const real *RESTRICT c, __global const uchar *RESTRICT state,
                          __global long *RESTRICT w, __global long *RESTRICT row_sums,
                          const int nx, const int ny, const int mode, const double eta,
                          const int wrap_x)
{
    const int i = (int)get_global_id(1);
    if (i >= ny) return;
    const long r = (long)i * nx;
    long total = 0;
    for (int j = 0; j < nx; ++j) {
        long q = 0;
        if (state[r + j] == 0) {
            bool near = (i > 0 && state[r - nx + j] == 1) ||
                        (i < ny - 1 && state[r + nx + j] == 1);
            if (j > 0) near = near || state[r + j - 1] == 1;
            else if (wrap_x) near = near || state[r + nx - 1] == 1;
            if (j < nx - 1) near = near || state[r + j + 1] == 1;
            else if (wrap_x) near = near || state[r] == 1;
            if (near) {
                double x = (double)c[r + j];
                x = fmin(fmax(x, 0.0), 1.0);
                q = (long)(dla_power(x, mode, eta) * DLA_QUANTUM);
            }
        }
        w[r + j] = q;
        total += q;
    }
    row_sums[i] = total;
}

__kernel void dla_pick(__global real *c, __global uchar *state, __global long *w,
                       __global int *arrival, __global long *out, const int nx,
                       const int row, const long target, const int step)
{
    if (get_global_id(0) != 0) return;
    const long r = (long)row * nx;
    long run = 0;
    int found = -1;
    for (int j = 0; j < nx; ++j) {
        run += w[r + j];
        if (run > target) { found = j; break; }
    }
    if (found >= 0) {
        out[0] = found;
        out[1] = w[r + found];
        w[r + found] = 0;
        state[r + found] = 1;
        c[r + found] = R0;
        arrival[r + found] = step;
    } else {
        out[0] = -1;
        out[1] = 0;
    }
}
