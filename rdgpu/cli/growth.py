"""``rdgpu run dla``, ``rdgpu run random-walk-dla`` and ``rdgpu run turing-front``: the
growth models (seed 001) and the level-set front driven by a Turing pattern (seed 003
§4.2, `rdgpu.fronts.turing_front`; seed 003's label ``seed003-front`` is accepted as
an alias) on the command line, beside the reaction-diffusion models of ``rdgpu run``.

``--size NxM`` is the grid, ``--steps`` the growth steps (DLA by the nutrient field: cells
joining, ``k`` a step) or the particles (random walkers), ``--param`` their parameters
(``eta``, ``k``, ``tol`` / ``sticking``, ``walkers``; ``geometry=slab|radial`` for
both), ``--seed``, ``--backend``; ``--out`` a PNG coloured by arrival (empty cells white),
``--data`` an NPZ with the mask, the arrival steps and the settings.  ``turing-front``:
``--steps`` front steps, ``--param warmup=``, ``reinit_every=``, ``beta_scale=``,
``speed=laplace|offset``; ``--out`` the region ``φ < 0`` (black), ``--data`` φ and it.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from rdgpu import growth
from rdgpu.analysis import fractal_dimension
from rdgpu.growth.dla import dla, dla_image
from rdgpu.growth.fronts import turing_front
from rdgpu.growth.walkers import random_walk_dla

GEOMETRIES = (*growth.GEOMETRIES, *growth.GEOMETRY_ALIASES)
#: growth model -> (default steps, {parameter: (kind, default)}), kinds "float", "int" or
#: a tuple of the allowed words
GROWTH: dict[str, tuple[int, dict[str, tuple[Any, Any]]]] = {
    "dla": (1000, {"eta": ("float", 1.0), "k": ("int", 1), "tol": ("float", 1e-5),
                   "geometry": (GEOMETRIES, "slab")}),
    "random-walk-dla": (1000, {"sticking": ("float", 1.0), "walkers": ("int", None),
                               "geometry": (GEOMETRIES, "radial")}),
    "turing-front": (1000, {"warmup": ("int", 8000), "reinit_every": ("int", 20),
                            "beta_scale": ("float", 1.0),
                            "speed": (("laplace", "offset"), "laplace")}),
}
#: the papers' labels accepted for a growth model's name
GROWTH_ALIASES = {"seed003-front": "turing-front"}


def growth_name(name: str | None) -> str | None:
    """``name`` (``rdgpu run``'s MODEL) with a paper's label (`GROWTH_ALIASES`)
    replaced by the growth model's name."""
    return GROWTH_ALIASES.get(name, name) if isinstance(name, str) else name


def is_growth(args: argparse.Namespace) -> bool:
    return growth_name(getattr(args, "model", None)) in GROWTH \
        and not getattr(args, "equation", None)


def _params(args: argparse.Namespace, usage: type[Exception]) -> dict[str, Any]:
    _, known = GROWTH[args.model]
    out = {k: default for k, (_, default) in known.items()}
    for name, value in args.param or []:
        if name not in known:
            raise usage(f"--param {name}: {args.model} has the parameters "
                        f"{', '.join(known)}")
        kind = known[name][0]
        if isinstance(kind, tuple):
            if value not in kind:
                raise usage(f"--param {name}={value}: allowed: {', '.join(kind)}")
            out[name] = value
            continue
        try:
            number = float(value)
        except (TypeError, ValueError):
            raise usage(f"--param {name}={value}: {args.model} takes a number") from None
        if kind == "int":
            if number != int(number) or number < 1:
                raise usage(f"--param {name}={value}: a whole number >= 1")
            number = int(number)
        out[name] = number
    return out


def _unsupported(args: argparse.Namespace, usage: type[Exception]) -> None:
    """The run options that make no sense for a growth model: an error naming them."""
    given = [flag for flag, value in (
        ("--preset", args.preset), ("--mesh", args.mesh), ("--movie", args.movie),
        ("--dt", args.dt), ("--method", args.method), ("--stencil", args.stencil),
        ("--members", getattr(args, "members", None)), ("--checkpoint", args.checkpoint),
        ("--resume", args.resume), ("--block-steps", getattr(args, "block_steps", None)),
        *((f"--{o.replace('_', '-')}", getattr(args, o, None))
          for o in ("init", "bc", "dx", "length", "radius", "height", "roughen")))
        if value is not None and value is not False]
    if given:
        raise usage(f"{args.model} is a growth model: {', '.join(given)} "
                    f"{'does' if len(given) == 1 else 'do'} not apply; "
                    "it takes --size, --steps, --param, --seed, --backend, --dtype, --out, "
                    "--data, --cmap, --scale")
    for d in args.data or []:
        if Path(d).suffix.lower() != ".npz":
            raise usage(f"--data for {args.model} must end in .npz, got {d!r}")


def run_growth(args: argparse.Namespace, say, usage: type[Exception]) -> int:
    """Run ``args.model`` (a key of `GROWTH`, or an alias) and write its outputs."""
    args.model = growth_name(args.model)
    _unsupported(args, usage)
    size = args.size if args.size is not None else (256, 256)
    if len(size) != 2:
        raise usage(f"{args.model} grows on a 2-D grid; --size NxM, got {size}")
    params = _params(args, usage)
    steps = args.steps if args.steps is not None else GROWTH[args.model][0]
    seed = args.seed if args.seed is not None else 0
    if args.model == "turing-front":
        return _front(args, params, steps, say, usage)
    t0 = time.perf_counter()
    try:
        if args.model == "dla":
            result = dla(tuple(size), eta=params["eta"], steps=steps,
                         geometry=params["geometry"], seed=seed, backend=args.backend,
                         tol=params["tol"], k=params["k"], dtype=args.dtype or "float64")
            grown, stopped = int(result.mask.sum()), result.stopped
        else:
            result = random_walk_dla(tuple(size), particles=steps,
                                     sticking=params["sticking"],
                                     geometry=params["geometry"], seed=seed,
                                     backend=args.backend, walkers=params["walkers"])
            grown, stopped = int(result.mask.sum()), result.stopped
    except ValueError as exc:
        raise usage(str(exc)) from None
    seconds = time.perf_counter() - t0
    settings = {"model": args.model, "size": list(size), "steps": steps, "seed": seed,
                **params}
    say(args, f"{args.model} on a {size[0]}x{size[1]} grid, {steps} "
              f"{'growth steps' if args.model == 'dla' else 'particles'}, "
              + ", ".join(f"{k}={v}" for k, v in params.items() if v is not None))
    arrays = {"mask": result.mask, "arrival": result.arrival}
    if getattr(result, "c", None) is not None:
        arrays["c"] = result.c
    # the picture: coloured by arrival, empty cells white (any cluster's arrival)
    _write(args, say, lambda out: dla_image(result, out, args.cmap or "viridis",
                                            args.scale or 2), arrays, settings)
    dim = ""
    if grown >= 50:  # radial: mass-radius about the seed cell; slab: box counting
        radial = params["geometry"] == "radial"
        center = getattr(result, "center", None) or (size[0] // 2, size[1] // 2)
        try:
            d = (fractal_dimension(result.mask, center=center) if radial
                 else fractal_dimension(result.mask, method="box")).dimension
            what = "mass-radius" if radial else "box-counting"
            dim = f", {what} dimension {d:.2f}" if math.isfinite(d) else ""
        except ValueError:
            dim = ""
    say(args, f"{grown} cells ({stopped}){dim} ({seconds:.2f} s)")
    return 0


def _front(args: argparse.Namespace, params: dict, steps: int, say,
           usage: type[Exception]) -> int:
    """``rdgpu run turing-front``: the seed's Turing spots, then a front driven by Δu."""
    if args.size is not None or args.seed is not None:
        raise usage("turing-front runs the seed's own grid and initial state (preset "
                    "turing-seed003-spots): --size and --seed do not apply")
    t0 = time.perf_counter()
    try:
        result = turing_front(backend=args.backend, steps=steps, warmup=params["warmup"],
                              reinit_every=params["reinit_every"],
                              beta_scale=params["beta_scale"], speed=params["speed"])
    except ValueError as exc:
        raise usage(str(exc)) from None
    say(args, "turing-front: " + ", ".join(f"{k}={v}" for k, v in params.items())
        + f", {steps} front steps")
    _write(args, say, lambda out: result.save_png(out, scale=args.scale or 4),
           {"phi": result.phi, "mask": result.mask}, {"steps": steps, **params})
    say(args, f"inside the front: {result.mask.mean():.1%} of the grid, {result.substeps} "
              f"front substeps ({time.perf_counter() - t0:.2f} s)")
    return 0


def _write(args: argparse.Namespace, say, picture, arrays: dict, settings: dict) -> None:
    """``--out`` by ``picture(path)`` (default ``MODEL.png`` with ``_`` for ``-``, e.g.
    ``random_walk_dla.png``, when neither ``--out`` nor ``--data`` is given) and each
    ``--data`` NPZ with ``arrays`` and the JSON ``settings``; says what it wrote."""
    out = args.out
    if out is None and not args.data:
        out = f"{args.model.replace('-', '_')}.png"
    written = [] if out is None else [picture(out)]
    for d in args.data or []:
        np.savez_compressed(d, **arrays, settings=np.array(json.dumps(settings)))
        written.append(d)
    for path in written:
        say(args, f"wrote {path}")
