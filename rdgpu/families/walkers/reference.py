"""NumPy reference of the random-walker DLA kernels (seed 001 §2): one walker step plus
its in-order sticking resolution; Philox-4x32-10 is `rdgpu.families.philox` (shared with
the noise family; ``philox4x32`` and ``key_of`` are re-exported here).

Conventions shared by every backend (Warp: ``warp_kernels.py``, OpenCL: ``walkers.cl``):

* Random numbers: ``philox4x32(counter, key)`` with the counter ``(walker id, step low
  32 bits, step high 32 bits, purpose)`` and the key ``(seed low, seed high)``; purpose 0
  is the walker's step draw, 1 its release after sticking, 2 its first release.
  Of one draw ``r``: ``r[0] >> 30`` picks the direction (+j, −j, +i, −i), ``r[1] <
  thresh`` (``thresh = round(p_stick · 2³²)``, so ``p_stick = 1`` always sticks) the
  sticking, ``r[2]`` the release position: ``(r[2] · n) >> 32`` of ``n`` choices.
* State ``state`` (int32): ``[COUNT, EXT, DONE, STEPS]``: cells added, the cluster's
  extent (radial: ``ceil`` of its largest distance from the centre; seed001: its highest
  row), 0 / 1 (all particles added) / 2 (the launch line or circle reached the grid
  edge), steps run.
* Grid ``[ny, nx]`` uint8 (1 = object) and ``arrival`` int32 (the order a cell joined:
  seed cells 0, particles 1, 2, …; −1 empty).  Walker positions ``pos[w] = (i, j)``.
* Geometry 0, radial: centre ``(ny // 2, nx // 2)``, released on the lattice ring of
  radius ``R = EXT + margin`` (the cells with ``round(distance) == R``, listed by
  ``ring_table``), re-released beyond distance ``2R`` or off the grid.  Geometry 1,
  seed001: bottom row 0 is the seed, periodic in j, released on row ``EXT + margin`` at a
  uniform column, re-released above row ``min(ny − 1, 2 (EXT + margin))``.

One step (``walk_step``, every walker at once, the grid read-only): a walker standing on
an object cell (one joined there) is re-released; otherwise it steps, a step into the
object is refused (it stays), a step beyond the kill distance re-releases it; a walker
that ends next to the object (4-neighbours) wants to stick when its sticking draw passes.
Then ``resolve`` (serial, walker id order): each wanting walker whose cell is still
empty adds it (``COUNT += 1``, arrival ``COUNT``), and is re-released (also when an
earlier walker took its cell); it stops at ``particles`` cells or when the launch
radius would leave the grid.
"""

from __future__ import annotations

import numpy as np

from rdgpu.families.philox import key_of as key_of
from rdgpu.families.philox import philox4x32 as philox4x32

COUNT, EXT, DONE, STEPS = 0, 1, 2, 3
STEP, RELEASE, FIRST = 0, 1, 2  # purposes (the counter's last word)
RADIAL, SLAB = 0, 1
_DI = np.array([0, 0, 1, -1], np.int64)
_DJ = np.array([1, -1, 0, 0], np.int64)


def draw(walkers, t: int, purpose: int, key) -> tuple[np.ndarray, ...]:
    """The draws of ``walkers`` (uint32 ids) at step ``t`` for ``purpose``."""
    w = np.asarray(walkers, np.uint32)
    return philox4x32((w, t & 0xFFFFFFFF, (t >> 32) & 0xFFFFFFFF, purpose), key)


def pick(r, n) -> np.ndarray:
    """``(r · n) >> 32``: a uniform index below ``n`` from a uint32 ``r``."""
    return ((np.asarray(r, np.uint64) * np.asarray(n, np.uint64)) >> np.uint64(32)).astype(
        np.int64)


def ring_table(r_max: int) -> tuple[np.ndarray, np.ndarray]:
    """``(ring_start, ring_ij)``: the lattice offsets ``(di, dj)`` with ``round(√(di² +
    dj²)) == R`` (i.e. ``(2R − 1)² ≤ 4(di² + dj²) < (2R + 1)²``) are rows
    ``ring_start[R]:ring_start[R + 1]`` of ``ring_ij`` (int32), for ``R ≤ r_max``, in
    angle order."""
    starts = [0]
    rows = []
    for radius in range(r_max + 1):
        d = np.arange(-radius - 1, radius + 2)
        di, dj = np.meshgrid(d, d, indexing="ij")
        q = 4 * (di * di + dj * dj)
        on = ((2 * radius - 1) ** 2 <= q) & (q < (2 * radius + 1) ** 2) if radius else q == 0
        ri, rj = di[on], dj[on]
        order = np.argsort(np.arctan2(ri, rj), kind="stable")
        rows.append(np.stack([ri[order], rj[order]], axis=1))
        starts.append(starts[-1] + len(ri))
    return np.array(starts, np.int32), np.ascontiguousarray(np.concatenate(rows).astype(np.int32))


def release(r, launch, geometry, shape, ring_start, ring_ij) -> tuple[np.ndarray, np.ndarray]:
    """Release positions ``(i, j)`` from the draws ``r`` (uint32) at launch distance
    ``launch``."""
    ny, nx = shape
    if geometry == RADIAL:
        lo = int(ring_start[launch])
        idx = lo + pick(r, int(ring_start[launch + 1]) - lo)
        return ny // 2 + ring_ij[idx, 0].astype(np.int64), nx // 2 + ring_ij[idx, 1].astype(
            np.int64)
    r = np.asarray(r)
    return np.full(r.shape, launch, np.int64), pick(r, nx)


def _occupied(grid, i, j, geometry) -> np.ndarray:
    """``grid[i, j] != 0`` with cells off the grid empty (columns wrap in seed001)."""
    ny, nx = grid.shape
    if geometry == SLAB:
        j = j % nx
    inside = (i >= 0) & (i < ny) & (j >= 0) & (j < nx)
    return inside & (grid[np.clip(i, 0, ny - 1), np.clip(j, 0, nx - 1)] != 0)


def walk_step(grid, pos, want, state, ring_start, ring_ij, *, t, key, geometry, thresh,
              margin) -> None:
    """One step of every walker (in place on ``pos`` and ``want``): see the module doc."""
    if state[DONE]:
        return
    ny, nx = grid.shape
    n = pos.shape[0]
    r0, r1, r2, _ = draw(np.arange(n), t, STEP, key)
    i, j = pos[:, 0].astype(np.int64), pos[:, 1].astype(np.int64)
    launch = int(state[EXT]) + margin
    on_object = grid[i, j] != 0
    d = r0 >> np.uint32(30)
    ni, nj = i + _DI[d], j + _DJ[d]
    if geometry == RADIAL:
        di, dj = ni - ny // 2, nj - nx // 2
        kill = (ni < 0) | (ni >= ny) | (nj < 0) | (nj >= nx) | (di * di + dj * dj > 4 * launch
                                                                    * launch)
    else:
        nj = nj % nx
        kill = ni > min(ny - 1, 2 * launch)
    kill |= on_object
    blocked = ~kill & _occupied(grid, ni, nj, geometry)
    ni, nj = np.where(blocked, i, ni), np.where(blocked, j, nj)
    ri, rj = release(r2, launch, geometry, grid.shape, ring_start, ring_ij)
    ni, nj = np.where(kill, ri, ni), np.where(kill, rj, nj)
    adjacent = np.zeros(n, bool)
    for a, b in zip(_DI, _DJ, strict=True):
        adjacent |= _occupied(grid, ni + a, nj + b, geometry)
    stick = r1.astype(np.int64) < thresh
    want[:] = (~kill & adjacent & stick).astype(want.dtype)
    pos[:, 0], pos[:, 1] = ni, nj


def extent_after(ext: int, i: int, j: int, geometry: int, shape) -> int:
    """The cluster's extent once cell ``(i, j)`` joins (module doc, ``EXT``)."""
    if geometry == SLAB:
        return max(ext, i)
    di, dj = i - shape[0] // 2, j - shape[1] // 2
    d2 = di * di + dj * dj
    while ext * ext < d2:
        ext += 1
    return ext


def resolve(grid, arrival, pos, want, state, ring_start, ring_ij, *, t, key, geometry,
            margin, particles, limit) -> None:
    """Add the cells of the walkers that want to stick, in walker id order (in place); see
    the module doc.  ``limit``: the largest launch distance the grid allows."""
    if state[DONE]:
        return
    state[STEPS] += 1
    for w in np.flatnonzero(want):
        i, j = int(pos[w, 0]), int(pos[w, 1])
        if grid[i, j] == 0:
            grid[i, j] = 1
            state[COUNT] += 1
            arrival[i, j] = state[COUNT]
            state[EXT] = extent_after(int(state[EXT]), i, j, geometry, grid.shape)
            if state[COUNT] >= particles:
                state[DONE] = 1
                return
            if state[EXT] + margin > limit:
                state[DONE] = 2
                return
        r = draw([w], t, RELEASE, key)[2]
        ri, rj = release(r, int(state[EXT]) + margin, geometry, grid.shape, ring_start, ring_ij)
        pos[w, 0], pos[w, 1] = ri[0], rj[0]
