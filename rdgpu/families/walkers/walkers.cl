/* Random-walker DLA (seed 001 §2): one walker step and the in-order sticking resolution.
 * The rules and the state layout (state = COUNT, EXT, DONE, STEPS) are those of
 * walkers/reference.py.  Integer only: built after the header philox.cl (Philox4,
 * philox: Philox-4x32-10, shared with the noise family), without common.cl.
 *
 * walk_step: one work-item per walker.  resolve: one work-item for all walkers, in id
 * order.  philox_fill: out[n] = philox((w0 + n, t_lo, t_hi, purpose), (k0, k1)).
 */

/* (r · n) >> 32: a uniform index below n */
inline int pick(uint r, int n) { return (int)(((ulong)r * (ulong)n) >> 32); }

inline int occupied(__global const uchar *grid, int ny, int nx, int i, int j, int geometry)
{
    if (geometry == 1) j = (j + nx) % nx;
    if (i < 0 || i >= ny || j < 0 || j >= nx) return 0;
    return grid[(long)i * nx + j] != 0;
}

inline void release(__global int *pos, int w, uint r, int launch, int geometry, int ny,
                    int nx, __global const int *ring_start, __global const int *ring_ij)
{
    if (geometry == 0) {
        const int lo = ring_start[launch];
        const int idx = lo + pick(r, ring_start[launch + 1] - lo);
        pos[2 * w] = ny / 2 + ring_ij[2 * idx];
        pos[2 * w + 1] = nx / 2 + ring_ij[2 * idx + 1];
    } else {
        pos[2 * w] = launch;
        pos[2 * w + 1] = pick(r, nx);
    }
}

__kernel void walk_step(__global const uchar *grid, __global int *pos, __global int *want,
                        __global const int *state, __global const int *ring_start,
                        __global const int *ring_ij, const int ny, const int nx,
                        const int n_walkers, const uint t_lo, const uint t_hi, const uint k0,
                        const uint k1, const int geometry, const long thresh, const int margin)
{
    const int w = (int)get_global_id(0);
    if (w >= n_walkers || state[2] != 0) return;
    const Philox4 r = philox((uint)w, t_lo, t_hi, 0u, k0, k1);
    const int i = pos[2 * w], j = pos[2 * w + 1];
    const int launch = state[1] + margin;
    const uint d = r.c[0] >> 30;
    int ni = i + (d == 2u) - (d == 3u);
    int nj = j + (d == 0u) - (d == 1u);
    bool kill = grid[(long)i * nx + j] != 0;
    if (geometry == 0) {
        const long di = ni - ny / 2, dj = nj - nx / 2, lim = launch;
        if (ni < 0 || ni >= ny || nj < 0 || nj >= nx || di * di + dj * dj > 4 * lim * lim)
            kill = true;
    } else {
        nj = (nj + nx) % nx;
        if (ni > min(ny - 1, 2 * launch)) kill = true;
    }
    want[w] = 0;
    if (kill) {
        release(pos, w, r.c[2], launch, geometry, ny, nx, ring_start, ring_ij);
        return;
    }
    if (occupied(grid, ny, nx, ni, nj, geometry)) {
        ni = i;
        nj = j;
    }
    pos[2 * w] = ni;
    pos[2 * w + 1] = nj;
    const int adj = occupied(grid, ny, nx, ni, nj + 1, geometry)
                    + occupied(grid, ny, nx, ni, nj - 1, geometry)
                    + occupied(grid, ny, nx, ni + 1, nj, geometry)
                    + occupied(grid, ny, nx, ni - 1, nj, geometry);
    if (adj > 0 && (long)r.c[1] < thresh) want[w] = 1;
}

__kernel void resolve(__global uchar *grid, __global int *arrival, __global int *pos,
                      __global const int *want, __global int *state,
                      __global const int *ring_start, __global const int *ring_ij,
                      const int ny, const int nx, const int n_walkers, const uint t_lo,
                      const uint t_hi, const uint k0, const uint k1, const int geometry,
                      const int margin, const int particles, const int limit)
{
    if (get_global_id(0) != 0 || state[2] != 0) return;
    state[3] += 1;
    for (int w = 0; w < n_walkers; ++w) {
        if (want[w] == 0) continue;
        const int i = pos[2 * w], j = pos[2 * w + 1];
        const long at = (long)i * nx + j;
        if (grid[at] == 0) {
            grid[at] = 1;
            const int count = state[0] + 1;
            state[0] = count;
            arrival[at] = count;
            int ext = state[1];
            if (geometry == 1) {
                ext = max(ext, i);
            } else {
                const long di = i - ny / 2, dj = j - nx / 2;
                while ((long)ext * ext < di * di + dj * dj) ++ext;
            }
            state[1] = ext;
            if (count >= particles) { state[2] = 1; return; }
            if (ext + margin > limit) { state[2] = 2; return; }
        }
        const Philox4 r = philox((uint)w, t_lo, t_hi, 1u, k0, k1);
        release(pos, w, r.c[2], state[1] + margin, geometry, ny, nx, ring_start, ring_ij);
    }
}

__kernel void philox_fill(__global uint *out, const int n, const uint w0, const uint t_lo,
                          const uint t_hi, const uint purpose, const uint k0, const uint k1)
{
    const int k = (int)get_global_id(0);
    if (k >= n) return;
    const Philox4 r = philox(w0 + (uint)k, t_lo, t_hi, purpose, k0, k1);
    for (int q = 0; q < 4; ++q) out[4 * k + q] = r.c[q];
}
