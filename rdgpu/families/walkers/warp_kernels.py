"""Warp kernels of random-walker DLA: one walker step (one thread per walker) and the
in-order sticking resolution (one thread); the rules and the state layout are those of
``reference.py``, Philox-4x32-10 is ``rdgpu.families.warp_philox`` (shared).

``PHILOX`` (one thread per counter) fills ``out[n, 4]`` with ``philox4x32((w0 + n, t_lo,
t_hi, purpose), (k0, k1))``: the test of the streams against NumPy.
"""

import warp as wp

from rdgpu.families.warp_philox import philox, vec4u

# fuse_fp off: no FMA contraction (CUDA contracts a*b+c by default), the rounding of
# the NumPy reference, as FP_CONTRACT OFF in common.cl gives OpenCL
wp.set_module_options({"enable_backward": False, "fuse_fp": False})

U8 = wp.array2d(dtype=wp.uint8)
I2 = wp.array2d(dtype=wp.int32)
I1 = wp.array(dtype=wp.int32)


@wp.func
def pick(r: wp.uint32, n: int) -> int:
    return int((wp.uint64(r) * wp.uint64(n)) >> wp.uint64(32))


@wp.func
def occupied(grid: U8, i: int, j: int, geometry: int) -> int:
    ny = grid.shape[0]
    nx = grid.shape[1]
    jj = j
    if geometry == 1:
        jj = (j + nx) % nx
    if i < 0 or i >= ny or jj < 0 or jj >= nx:
        return 0
    return int(grid[i, jj] != wp.uint8(0))


@wp.func
def release(pos: I2, w: int, r: wp.uint32, launch: int, geometry: int, grid: U8,
            ring_start: I1, ring_ij: I2):
    if geometry == 0:
        lo = ring_start[launch]
        idx = lo + pick(r, ring_start[launch + 1] - lo)
        pos[w, 0] = grid.shape[0] / 2 + ring_ij[idx, 0]
        pos[w, 1] = grid.shape[1] / 2 + ring_ij[idx, 1]
    else:
        pos[w, 0] = launch
        pos[w, 1] = pick(r, grid.shape[1])


@wp.kernel
def walk_step(grid: U8, pos: I2, want: I1, state: I1, ring_start: I1, ring_ij: I2,
              t_lo: wp.uint32, t_hi: wp.uint32, k0: wp.uint32, k1: wp.uint32, geometry: int,
              thresh: wp.int64, margin: int):
    w = wp.tid()
    if state[2] != 0:
        return
    ny = grid.shape[0]
    nx = grid.shape[1]
    r = philox(vec4u(wp.uint32(w), t_lo, t_hi, wp.uint32(0)), k0, k1)
    i = pos[w, 0]
    j = pos[w, 1]
    launch = state[1] + margin
    d = int(r[0] >> wp.uint32(30))
    ni = i
    nj = j
    if d == 0:
        nj = j + 1
    elif d == 1:
        nj = j - 1
    elif d == 2:
        ni = i + 1
    else:
        ni = i - 1
    kill = int(grid[i, j] != wp.uint8(0))
    if geometry == 0:
        di = wp.int64(ni - ny / 2)
        dj = wp.int64(nj - nx / 2)
        lim = wp.int64(launch)
        if ni < 0 or ni >= ny or nj < 0 or nj >= nx or di * di + dj * dj > wp.int64(4) * lim * lim:
            kill = 1
    else:
        nj = (nj + nx) % nx
        if ni > wp.min(ny - 1, 2 * launch):
            kill = 1
    want[w] = 0
    if kill != 0:
        release(pos, w, r[2], launch, geometry, grid, ring_start, ring_ij)
        return
    if occupied(grid, ni, nj, geometry) != 0:
        ni = i
        nj = j
    pos[w, 0] = ni
    pos[w, 1] = nj
    adj = (occupied(grid, ni, nj + 1, geometry) + occupied(grid, ni, nj - 1, geometry)
           + occupied(grid, ni + 1, nj, geometry) + occupied(grid, ni - 1, nj, geometry))
    if adj > 0 and wp.int64(r[1]) < thresh:
        want[w] = 1


@wp.kernel
def resolve(grid: U8, arrival: I2, pos: I2, want: I1, state: I1, ring_start: I1,
            ring_ij: I2, t_lo: wp.uint32, t_hi: wp.uint32, k0: wp.uint32, k1: wp.uint32,
            geometry: int, margin: int, particles: int, limit: int):
    if state[2] != 0:
        return
    state[3] = state[3] + 1
    ny = grid.shape[0]
    nx = grid.shape[1]
    for w in range(want.shape[0]):
        if want[w] != 0:
            i = pos[w, 0]
            j = pos[w, 1]
            if grid[i, j] == wp.uint8(0):
                grid[i, j] = wp.uint8(1)
                count = state[0] + 1
                state[0] = count
                arrival[i, j] = count
                ext = state[1]
                if geometry == 1:
                    ext = wp.max(ext, i)
                else:
                    di = wp.int64(i - ny / 2)
                    dj = wp.int64(j - nx / 2)
                    d2 = di * di + dj * dj
                    while wp.int64(ext) * wp.int64(ext) < d2:
                        ext = ext + 1
                state[1] = ext
                if count >= particles:
                    state[2] = 1
                    return
                if ext + margin > limit:
                    state[2] = 2
                    return
            r = philox(vec4u(wp.uint32(w), t_lo, t_hi, wp.uint32(1)), k0, k1)
            release(pos, w, r[2], state[1] + margin, geometry, grid, ring_start, ring_ij)


@wp.kernel
def philox_fill(out: wp.array2d(dtype=wp.uint32), w0: wp.uint32, t_lo: wp.uint32,
                t_hi: wp.uint32, purpose: wp.uint32, k0: wp.uint32, k1: wp.uint32):
    n = wp.tid()
    r = philox(vec4u(w0 + wp.uint32(n), t_lo, t_hi, purpose), k0, k1)
    for q in range(4):
        out[n, q] = r[q]


PHILOX = philox_fill
