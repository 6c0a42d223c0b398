"""Row group ``growth``: DLA by the nutrient field (radial, η = 1, tol 1e-5; growth steps
per second and SOR sweeps per growth step, each solve starting from the previous field
(warm) or from scratch (cold)) and random walkers (1024 walkers, sticking 0.02 so they
mostly walk; walker steps per second), against the same algorithms written the obvious
way in NumPy (`plain_numpy_dla`, `plain_numpy_walkers`).
"""

from __future__ import annotations

import math
import time

import numpy as np

from rdgpu.bench.context import Context
from rdgpu.growth.dla import dla
from rdgpu.growth.walkers import random_walk_dla

__all__ = ["markdown", "plain_numpy_dla", "plain_numpy_walkers", "run"]


def plain_numpy_dla(shape, eta=1.0, steps=100, seed=0, tol=1e-5, geometry="radial"):
    """The obvious implementation: a Python loop over growth steps, vectorised NumPy
    red-black SOR (slices of both colours), candidates by shifted masks, and
    ``rng.choice`` over the candidates.  Returns ``(mask, sweeps per step)``."""
    ny, nx = shape
    i, j = np.indices(shape)
    if geometry == "radial":
        ci, cj = ny // 2, nx // 2
        fixed_one = np.hypot(i - ci, j - cj) >= 0.45 * min(shape)
        held = fixed_one.copy()
        c = np.where(fixed_one, 1.0, 0.0)
    else:
        ci, cj = 0, nx // 2
        fixed_one = i == ny - 1
        held = (i == 0) | fixed_one
        c = i / (ny - 1.0)
    obj = np.zeros(shape, bool)
    obj[ci, cj] = True
    c[obj] = 0.0
    omega = 2.0 / (1.0 + math.sin(math.pi / max(shape)))
    red = (i + j) % 2 == 0
    rng = np.random.default_rng(seed)
    sweeps = []
    for _ in range(steps):
        free = ~(held | obj)
        c, n = _plain_sor(c, free, red, omega, tol)
        sweeps.append(n)
        near = (np.roll(obj, 1, 0) | np.roll(obj, -1, 0) | np.roll(obj, 1, 1)
                | np.roll(obj, -1, 1))
        cand = np.flatnonzero(near & free)
        w = np.clip(c.ravel()[cand], 0.0, 1.0) ** eta
        pick = rng.choice(cand, p=w / w.sum())
        obj.flat[pick] = True
        c.flat[pick] = 0.0
    return obj, np.asarray(sweeps)


def _plain_sor(c, free, red, omega, tol):
    n = 0
    while True:
        n += 1
        change = 0.0
        for colour in (red, ~red):
            nb = 0.25 * (np.roll(c, 1, 1) + np.roll(c, -1, 1)
                         + np.vstack([c[:1], c[:-1]]) + np.vstack([c[1:], c[-1:]]))
            new = (1 - omega) * c + omega * nb
            upd = colour & free
            change = max(change, float(np.abs(new - c)[upd].max(initial=0.0)))
            c = np.where(upd, new, c)
        if change < tol:
            return c, n


def plain_numpy_walkers(shape, particles, walkers, sticking=1.0, margin=5, seed=0,
                        max_steps=None):
    """Radial walker DLA the obvious way; returns ``(mask, walker steps, seconds)``."""
    rng = np.random.default_rng(seed)
    ny, nx = shape
    cy, cx = ny // 2, nx // 2
    limit = min(cy, cx, ny - 1 - cy, nx - 1 - cx)
    grid = np.zeros(shape, bool)
    grid[cy, cx] = True
    rad, added, steps = 0, 0, 0
    moves = np.array([[0, 1], [0, -1], [1, 0], [-1, 0]])

    def launch(n, radius):
        a = rng.uniform(0, 2 * np.pi, n)
        return (np.stack([cy + np.rint(radius * np.sin(a)), cx + np.rint(radius * np.cos(a))],
                         axis=1).astype(np.int64))

    pos = launch(walkers, rad + margin)
    start = time.perf_counter()
    while added < particles and (max_steps is None or steps < max_steps):
        steps += 1
        r = rad + margin
        on = grid[pos[:, 0], pos[:, 1]]
        new = pos + moves[rng.integers(0, 4, walkers)]
        d2 = ((new - [cy, cx]) ** 2).sum(axis=1)
        out = (new[:, 0] < 0) | (new[:, 0] >= ny) | (new[:, 1] < 0) | (new[:, 1] >= nx)
        kill = on | out | (d2 > 4 * r * r)
        new = np.clip(new, 0, [ny - 1, nx - 1])
        blocked = ~kill & grid[new[:, 0], new[:, 1]]
        new[blocked] = pos[blocked]
        new[kill] = launch(int(kill.sum()), r)
        p = np.pad(grid, 1)
        adj = (p[new[:, 0] + 1, new[:, 1]] | p[new[:, 0] + 1, new[:, 1] + 2]
               | p[new[:, 0], new[:, 1] + 1] | p[new[:, 0] + 2, new[:, 1] + 1])
        stick = ~kill & adj & (rng.random(walkers) < sticking)
        pos = new
        for w in np.flatnonzero(stick):
            i, j = pos[w]
            if not grid[i, j]:
                grid[i, j] = True
                added += 1
                rad = max(rad, int(np.ceil(np.hypot(i - cy, j - cx))))
                if added >= particles or rad + margin > limit:
                    return grid, steps * walkers, time.perf_counter() - start
            pos[w] = launch(1, rad + margin)[0]
    return grid, steps * walkers, time.perf_counter() - start


def _dla_rows(ctx: Context, n: int, dla_steps: int) -> list[dict]:
    steps = max(2, dla_steps * 256 // n)
    t = time.perf_counter()
    _, sweeps = plain_numpy_dla((n, n), steps=steps)
    plain = steps / (time.perf_counter() - t)
    rows = [dict(kernel="dla", size=n, backend="plain NumPy", start="warm", rate=plain,
                 sweeps=float(np.mean(sweeps[1:])), vs_plain=1.0)]
    for label, be in ctx.backends.items():
        if label == "numpy" and n > 256:
            continue  # the reference: ~0.15 growth steps/s at 512²
        for warm in (True, False):
            kw = dict(eta=1.0, geometry="radial", seed=0, backend=be, warm_start=warm)
            dla((n, n), steps=2, **kw)  # compile
            t = time.perf_counter()
            r = dla((n, n), steps=steps, **kw)
            rate = steps / (time.perf_counter() - t)
            rows.append(dict(kernel="dla", size=n, backend=label,
                             start="warm" if warm else "cold", rate=rate,
                             sweeps=float(r.sweeps[1:].mean()), vs_plain=rate / plain))
            ctx.say(f"  dla {n}² {rows[-1]['start']} {label:12s} {rate:8.2f} growth steps/s "
                    f"{rows[-1]['sweeps']:.0f} sweeps/step")
    return rows


def _walker_rows(ctx: Context, n: int, walkers: int, walker_steps: int) -> list[dict]:
    shape, stick, particles = (n, n), 0.02, min(2000, n * n // 4)
    _, ws, sec = plain_numpy_walkers(shape, particles, walkers, stick, max_steps=walker_steps)
    plain = ws / sec
    rows = [dict(kernel="walkers", size=n, backend="plain NumPy", walkers=walkers, rate=plain,
                 vs_plain=1.0)]
    for label, be in ctx.backends.items():
        random_walk_dla((32, 32), particles=5, walkers=8, backend=be)  # compile
        t = time.perf_counter()
        r = random_walk_dla(shape, particles=particles, walkers=walkers, sticking=stick,
                            max_steps=walker_steps, backend=be)
        rate = r.walker_steps / (time.perf_counter() - t)
        rows.append(dict(kernel="walkers", size=n, backend=label, walkers=walkers, rate=rate,
                         vs_plain=rate / plain))
        ctx.say(f"  walkers {n}² {label:12s} {rate:.3g} walker steps/s")
    return rows


def run(ctx: Context, dla_sizes: list[int], dla_steps: int, walker_size: int,
        walkers: int, walker_steps: int) -> list[dict]:
    """DLA at every size of ``dla_sizes`` (``dla_steps`` growth steps at 256², fewer on
    larger grids), then walkers on ``walker_size²``."""
    rows = []
    for n in dla_sizes:
        rows += _dla_rows(ctx, n, dla_steps)
    if walker_size > 0:
        rows += _walker_rows(ctx, walker_size, walkers, walker_steps)
    return rows


def markdown(rows: list[dict], ctx: Context) -> list[str]:
    """The growth table."""
    walkers = next((r for r in rows if r["kernel"] == "walkers"), None)
    what = (f"random walkers ({walkers['size']}², {walkers['walkers']} walkers, sticking "
            "0.02 so they mostly walk)" if walkers else "no walkers")
    lines = ["DLA by the nutrient field (radial, η = 1, tol 1e-5; warm: each solve starts "
             f"from the previous field, cold: from scratch) and {what}, against the same "
             "algorithms written the obvious way in NumPy (`rdgpu.bench.rows_growth`).", "",
             ctx.ran_on(), "",
             "| kind | size | backend | start | rate | SOR sweeps / growth step | × plain "
             "NumPy |", "|---|---|---|---|---:|---:|---:|"]
    for r in rows:
        if r["kernel"] == "dla":
            lines.append(f"| DLA | {r['size']}² | {r['backend']} | {r['start']} | "
                         f"{r['rate']:.2f} growth steps/s | {r['sweeps']:.0f} | "
                         f"{r['vs_plain']:.2f} |")
        else:
            lines.append(f"| walkers | {r['size']}² | {r['backend']} | — | "
                         f"{r['rate']:.3g} walker steps/s | — | {r['vs_plain']:.2f} |")
    return lines
