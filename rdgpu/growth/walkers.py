"""Monte Carlo diffusion-limited aggregation with random walkers (seed 001 §2).

``random_walk_dla`` releases ``walkers`` random walkers at once around a seed; they step on
the lattice, and one next to the object joins it with probability ``sticking``.  Every
random number is Philox-4x32-10 keyed by (seed, walker, step), and walkers that touch the
object in the same step join one at a time in walker id order, so every backend grows the
same cluster from the same seed.  The rules are in ``rdgpu/families/walkers/reference.py``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rdgpu.backends.registry import get_backend
from rdgpu.core import validation as check
from rdgpu.core.resources import check_memory
from rdgpu.families import load_module
from rdgpu.growth import geometry_name

#: why a run stopped: every particle added, the launch line/circle reached the grid edge,
#: or ``max_steps`` ran out
STOPS = ("particles", "edge", "max_steps")


@dataclass
class WalkDLAResult:
    """A grown cluster: ``mask`` (bool ``[ny, nx]``), ``arrival`` (int32: 0 for the seed
    cells, ``k`` for the k-th particle, −1 empty), ``particles_added``, ``walker_steps``
    (steps × walkers in flight), ``steps`` (lattice steps of the whole swarm), ``stopped``
    (one of ``STOPS``) and the ``settings`` it ran with."""

    mask: np.ndarray
    arrival: np.ndarray
    particles_added: int
    walker_steps: int
    steps: int
    stopped: str
    settings: dict = field(default_factory=dict)


#: host bytes per walker at the release (Philox counters and their temporaries, the
#: positions) and per cell (the uint8 grid and int32 arrival steps, on the host and on the
#: device, the result's mask); the ring table's set-up needs about RING_BYTES per cell of
#: the square around its largest ring
WALKER_BYTES, CELL_BYTES, RING_BYTES = 160, 15, 40


def _check(shape, particles, sticking, geometry, walkers, max_steps, margin, batch):
    if not isinstance(shape, (tuple, list)) or len(shape) != 2 or not all(
            isinstance(s, (int, np.integer)) and not isinstance(s, bool) for s in shape):
        raise ValueError(f"shape must be two integers (ny, nx), got {shape!r}")
    ny, nx = (int(s) for s in shape)
    margin = check.whole(margin, "margin", minimum=1)
    if geometry == "radial":
        limit = min(ny // 2, nx // 2, ny - 1 - ny // 2, nx - 1 - nx // 2)
    else:
        limit = ny - 1
    if min(ny, nx) < 3 or limit < margin + 1 or ny * nx >= 2**31:
        raise ValueError(
            f"shape {shape!r} is too small or too large for geometry {geometry!r} with "
            f"margin {margin}: each side needs at least {2 * margin + 3} cells "
            f"({margin + 2} rows for the slab), and fewer than 2**31 cells in all")
    capacity = ny * nx - (nx if geometry == "slab" else 1)
    try:
        check.whole(particles, "particles", minimum=1, maximum=capacity)
    except ValueError:
        raise ValueError(f"particles must be an integer from 1 to {capacity} (the empty "
                         f"cells of a {ny}x{nx} grid), got {particles!r}") from None
    sticking = check.scalar(sticking, "sticking", strict=True, maximum=1.0)
    if walkers is not None:
        check.whole(walkers, "walkers", minimum=1, maximum=2**31 - 1)
    for name, v in (("max_steps", max_steps), ("batch", batch)):
        check.whole(v, name, minimum=1, maximum=2**31 - 1)
    return ny, nx, limit


def _check_memory(ny: int, nx: int, n_walk: int, ring: int) -> None:
    """The shared memory estimate (`rdgpu.core.resources.check_memory`) of a run, before
    anything is allocated."""
    side = 2 * ring + 3
    need = n_walk * WALKER_BYTES + ny * nx * CELL_BYTES + side * side * RING_BYTES
    check_memory(f"random_walk_dla with {n_walk:,} walkers on a {ny}x{nx} grid", need,
                 f"{n_walk:,} walkers x {WALKER_BYTES} bytes, {ny * nx:,} cells x "
                 f"{CELL_BYTES} bytes, the release ring table")


def random_walk_dla(
    shape: tuple[int, int],
    *,
    particles: int = 1000,
    sticking: float = 1.0,
    geometry: str = "radial",
    seed: int = 0,
    backend=None,
    walkers: int | None = None,
    max_steps: int = 10**8,
    margin: int = 5,
    batch: int = 64,
) -> WalkDLAResult:
    """Grow a DLA cluster of ``particles`` cells from random walkers.

    The run stops when ``particles`` cells joined, the launch line/circle would leave the
    grid (``stopped == "edge"``), or after ``max_steps``.

    Parameters
    ----------
    shape : tuple of int
        ``(ny, nx)`` cells: at least ``2 * margin + 3`` a side (``margin + 2`` rows for the
        slab), fewer than 2**31 cells in all.
    particles : int
        Cells to add, from 1 to the empty cells of the grid (default 1000).
    sticking : float
        The probability in (0, 1] that a walker next to the object joins it (default 1).
    geometry : {"radial", "slab"}
        ``"radial"`` (default: one seed cell in the centre, walkers released on the lattice
        circle ``margin`` cells outside the cluster and re-released beyond twice that
        radius or off the grid) or ``"slab"`` (``"seed001"`` too; the seed is the bottom
        row 0, periodic in x, released on the row ``margin`` above the highest cell and
        re-released above twice that height).
    seed : int
        The Philox key, from 0 to 2**64 − 1 (default 0).
    backend : str or Backend, optional
        As `rdgpu.get_backend` takes it (default ``None``: the default backend).
    walkers : int, optional
        Walkers in flight at once, 1 to 2**31 − 1 (default: ``min(particles, 256)``).
    max_steps : int
        Swarm steps at most, from 1 to 2**31 − 1 (default 10**8).
    margin : int
        Cells between the cluster and the release line/circle, >= 1 (default 5).
    batch : int
        Steps launched between two reads of the 4-integer state, >= 1 (default 64).

    Returns
    -------
    WalkDLAResult
        The cluster, the arrival order, the counts, why it stopped and the settings.

    Raises
    ------
    ValueError
        An argument out of the ranges above or an unknown ``geometry``
        (`rdgpu.ResourceLimitError` where the run cannot fit in memory).
    TypeError
        A count or the seed that is not an integer, or ``sticking`` not a real number.
    """
    geometry = geometry_name(geometry)
    ny, nx, limit = _check(shape, particles, sticking, geometry, walkers, max_steps, margin,
                           batch)
    seed = check.whole(seed, "seed", maximum=2**64 - 1)
    n_walk = int(walkers) if walkers is not None else min(int(particles), 256)
    _check_memory(ny, nx, n_walk, limit + 1 if geometry == "radial" else 0)
    ref = load_module("walkers", "reference.py")
    be = get_backend(backend)
    geo = ref.RADIAL if geometry == "radial" else ref.SLAB
    key = ref.key_of(int(seed))
    ring_start, ring_ij = ref.ring_table(limit + 1 if geo == ref.RADIAL else 0)

    grid = np.zeros((ny, nx), np.uint8)
    arrival = np.full((ny, nx), -1, np.int32)
    if geo == ref.RADIAL:
        grid[ny // 2, nx // 2] = 1
        arrival[ny // 2, nx // 2] = 0
    else:
        grid[0] = 1
        arrival[0] = 0
    state = np.zeros(4, np.int32)
    r = ref.draw(np.arange(n_walk), 0, ref.FIRST, key)[2]
    pi, pj = ref.release(r, margin, geo, (ny, nx), ring_start, ring_ij)
    pos = np.ascontiguousarray(np.stack([pi, pj], axis=1).astype(np.int32))
    thresh = min(int(round(float(sticking) * 2.0**32)), 2**32)

    d = {name: be.upload(a) for name, a in (
        ("grid", grid), ("arrival", arrival), ("pos", pos), ("want", np.zeros(n_walk, np.int32)),
        ("state", state), ("ring_start", ring_start), ("ring_ij", ring_ij))}
    t = 0
    while True:
        n = min(int(batch), int(max_steps) - t)
        be.walker_steps(
            d["grid"], d["arrival"], d["pos"], d["want"], d["state"], d["ring_start"],
            d["ring_ij"], t0=t, n_steps=n, seed=int(seed), geometry=geo, thresh=thresh,
            margin=int(margin), particles=int(particles), limit=limit)
        t += n
        state = be.download(d["state"])
        if state[ref.DONE] or t >= max_steps:
            break
    arrival = be.download(d["arrival"])
    stopped = {0: "max_steps", 1: "particles", 2: "edge"}[int(state[ref.DONE])]
    steps = int(state[ref.STEPS])
    settings = dict(shape=(ny, nx), particles=int(particles), sticking=float(sticking),
                    geometry=geometry, seed=int(seed), backend=be.name, walkers=n_walk,
                    max_steps=int(max_steps), margin=int(margin), batch=int(batch))
    return WalkDLAResult(mask=arrival >= 0, arrival=arrival,
                         particles_added=int(state[ref.COUNT]), walker_steps=steps * n_walk,
                         steps=steps, stopped=stopped, settings=settings)
