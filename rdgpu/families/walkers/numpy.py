"""The walkers family on the NumPy backend: the reference on host arrays."""

from __future__ import annotations

import numpy as np

from rdgpu.families.walkers import reference as _reference


def walker_steps(rt, grid, arrival, pos, want, state, ring_start, ring_ij, *, t0, n_steps,
                 seed, geometry, thresh, margin, particles, limit) -> None:
    """Steps ``t0 … t0 + n_steps − 1`` (see :mod:`rdgpu.families.walkers`)."""
    ref = _reference
    key = ref.key_of(seed)
    tables = (ring_start.handle, ring_ij.handle)
    for t in range(t0, t0 + n_steps):
        ref.walk_step(grid.handle, pos.handle, want.handle, state.handle, *tables, t=t,
                      key=key, geometry=geometry, thresh=thresh, margin=margin)
        ref.resolve(grid.handle, arrival.handle, pos.handle, want.handle, state.handle,
                    *tables, t=t, key=key, geometry=geometry, margin=margin,
                    particles=particles, limit=limit)


def philox(rt, out, *, first, t, purpose, seed) -> None:
    """``out[n] = philox4x32((first + n, t low, t high, purpose), seed words)``."""
    ref = _reference
    w = np.arange(first, first + out.shape[0], dtype=np.uint64)
    out.handle[...] = np.stack(ref.draw(w, t, purpose, ref.key_of(seed)), axis=1)
