"""Seed 002 §4.2's experiment: Turing spots and stripes on flat and rough surfaces.

The seed (Realistic pattern formations on surfaces by adding arbitrary roughness) grows
patterns on graph surfaces ``z = h(x, y)`` of random waves and concludes that "the number
of spots increases as the frequencies and the amplitude increase".  Here the reaction is
the BVAM system (``rdgpu.models.MODELS["bvam"]``) with the `PATTERNS` parameters, on
an ``n × n`` periodic grid over the square ``[0, SIDE)²``, IMEX Euler with ``dt =``
`DT`, float64, every run from the same random data.  `experiment` runs every
(pattern, amplitude, frequency) of a configuration and measures the final ``u``
(`measure`: `rdgpu.analysis.spot_statistics` and
`rdgpu.analysis.stripe_orientation` on the surface).  The whole study, its table and
mosaic are ``examples/seed002_roughness.py``'s (``docs/data/seed002_roughness.md``).
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from rdgpu.analysis.spots import spot_statistics, stripe_orientation
from rdgpu.domains.graph_surface import GraphSurface
from rdgpu.domains.surfaces import random_waves
from rdgpu.models import MODELS
from rdgpu.simulation.driver import Simulation

__all__ = ["DT", "experiment", "measure", "PATTERNS", "run_simulation", "SIDE", "slope_of",
           "surface_height", "WAVELENGTH"]

SIDE = 2.0  # the parameter square [0, 2)², periodic
PATTERNS = {  # r1, r2 and the end time of each pattern (the seed's t)
    "spots": ({"r1": 0.02, "r2": 0.2}, 800.0),
    "stripes": ({"r1": 3.5, "r2": 0.0}, 2000.0),
}
DT = 0.5
#: the flat fastest-growing wavelength (δ = 6.6e-4: about 8 wavelengths across the square)
WAVELENGTH = 0.256


def surface_height(n: int, amplitude: float, frequency: tuple[int, int], seed: int) -> np.ndarray:
    """The random-wave height over the ``n × n`` grid of side `SIDE` (absolute units:
    ``max|h| = amplitude · SIDE``)."""
    if amplitude == 0.0:
        return np.zeros((n, n))
    return random_waves((n, n), amplitude=amplitude * SIDE, max_frequency=frequency,
                        seed=seed, dx=SIDE / n)


def run_simulation(height: np.ndarray, params: dict[str, float], u0: np.ndarray,
                   v0: np.ndarray, steps: int, backend: str) -> np.ndarray:
    """The same run through `rdgpu.Simulation` on the graph surface.  Returns u."""
    n = height.shape[0]
    sim = Simulation("bvam", {"grid": (n, n), "dx": SIDE / n, "height": height},
                     params, dt=DT, backend=backend, dtype="float64",
                     fields={"u": u0, "v": v0}, options={"method": "imex"})
    return np.asarray(sim.run(steps, progress=False).fields["u"], dtype=np.float64)


def measure(u: np.ndarray, height: np.ndarray) -> dict[str, float]:
    """The spot and stripe measures of the final ``u`` on its surface (spots: the high-u
    regions, threshold the midrange)."""
    n = u.shape[0]
    surface = GraphSurface((n, n), dx=SIDE / n, height=height)
    spots = spot_statistics(u, surface, high=True, min_cells=2)
    angle, coherence = stripe_orientation(u, surface)
    return {"count": spots.count, "size_spread": spots.size_spread,
            "elongation": spots.elongation,
            "mean_area": float(spots.areas.mean()) if spots.count else float("nan"),
            "coherence": coherence, "angle_deg": math.degrees(angle),
            "range": float(np.ptp(u))}


def slope_of(height: np.ndarray) -> float:
    """The steepest slope ``max |∇h|`` (centred differences)."""
    n = height.shape[0]
    gx = (np.roll(height, -1, 1) - np.roll(height, 1, 1)) * n / (2.0 * SIDE)
    gy = (np.roll(height, -1, 0) - np.roll(height, 1, 0)) * n / (2.0 * SIDE)
    return float(np.hypot(gx, gy).max())


def experiment(config: dict[str, Any], backend: str, seed: int,
               progress: bool = True) -> list[dict]:
    """Every (pattern, amplitude, frequency) run, flat once per pattern.  ``config``:
    ``n`` (grid side), ``amplitudes`` (fractions of `SIDE`, 0 is flat),
    ``frequencies`` (``(M, N)`` pairs), optionally ``time_scale`` (a factor on the end
    times) and ``patterns`` (names of `PATTERNS`; default all).  One row per run: the
    surface's slope and area, the measures, spots per area, ``u``; a line per run printed
    when ``progress``."""
    n = config["n"]
    rng = np.random.default_rng(seed)
    u0, v0 = rng.uniform(-0.5, 0.5, (2, n, n))
    rows = []
    for pattern, (extra, t_end) in PATTERNS.items():
        if pattern not in config.get("patterns", PATTERNS):
            continue
        params = {**MODELS["bvam"].defaults, **extra}
        steps = int(round(t_end * config.get("time_scale", 1.0) / DT))
        for amp in config["amplitudes"]:
            for freq in (config["frequencies"][:1] if amp == 0.0 else config["frequencies"]):
                h = surface_height(n, amp, freq, seed + 1)
                start = time.perf_counter()
                u = run_simulation(h, params, u0, v0, steps, backend)
                row = {"pattern": pattern, "amplitude": amp, "M": freq[0], "N": freq[1],
                       "max_slope": slope_of(h), "area": float(
                           GraphSurface((n, n), dx=SIDE / n, height=h).total_area),
                       "t": steps * DT, "seconds": time.perf_counter() - start,
                       **measure(u, h), "u": u}
                row["density"] = row["count"] / row["area"]
                # where the surface is steepest a surface wavelength spans fewer cells
                row["cells_per_wavelength"] = WAVELENGTH / (SIDE / n) / math.sqrt(
                    1.0 + row["max_slope"] ** 2)
                rows.append(row)
                if progress:
                    print(f"{pattern:8s} a={amp:<6g} (M,N)=({freq[0]:2d},{freq[1]:2d}) "
                          f"slope={row['max_slope']:6.2f} spots={row['count']:3d} "
                          f"cv={row['size_spread']:.3f} elong={row['elongation']:.3f} "
                          f"coh={row['coherence']:.3f} angle={row['angle_deg']:6.1f} "
                          f"[{row['seconds']:.1f} s]", flush=True)
    return rows
