"""The argument types of ``rdgpu run`` and ``rdgpu sweep``: each turns one option's text
into a value, or raises `argparse.ArgumentTypeError` naming what is wrong and what
is allowed (argparse prefixes the option).  Nothing here imports NumPy or a model: the
command line is checked before anything heavy loads.

New with issue 19: ``--init`` (`_init`), ``--bc`` (`_bc`), ``--fps``
(`parse_fps`), ``--block-steps`` (`parse_block_steps`) and ``--mesh NAME[:LEVEL]``
(`mesh_level`); ``--height`` and ``--roughen`` check every part of their specs.
"""

from __future__ import annotations

import argparse
import math
import re
from pathlib import Path
from typing import Any

from rdgpu.io.writers import FPS_RANGE, check_fps

#: --block-steps: a pass recomputes 2 (K - 1) halo rows around each band of 512 rows
#: (rdgpu.integrators.blocking.ROWS), so K past that recomputes more than it advances
MAX_BLOCK_STEPS = 512
#: --height AMPLITUDE (units of dx): beyond this the surface's metric overflows long
#: before a pattern could be resolved on it
MAX_HEIGHT = 1e6
#: --mesh sphere:LEVEL: icosphere(10) has 10 485 762 vertices
MAX_LEVEL = 10
#: generators whose resolution --mesh NAME:LEVEL sets, and the option it sets
LEVEL_OPTIONS = {"sphere": "subdivisions", "icosphere": "subdivisions",
                 "uv-sphere": "n_lat", "torus": "n_major", "disc": "rings"}

Bad = argparse.ArgumentTypeError


class Given(dict):
    """A spec parsed from an option, with the option's text (for messages)."""

    def __init__(self, text: str, **items: Any) -> None:
        super().__init__(**items)
        self.text = text

_SIZE_FORMS = ("256 or 256x128 (rows x columns), or 32x48x64 (planes x rows x columns) "
               "for a 3-D grid")


def parse_size(text: str) -> tuple[int, ...]:
    """``--size``: ``N`` is an N x N grid, ``NxM`` a 2-D grid of N rows (y) and M columns
    (x), ``NxMxK`` a 3-D grid of N planes (z), M rows and K columns: the order of
    `Grid`'s shape, ``(ny, nx)`` or ``(nz, ny, nx)``."""
    try:
        parts = [int(p) for p in text.lower().split("x")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"size must look like {_SIZE_FORMS}, got {text!r}") from None
    if len(parts) == 1:
        parts *= 2
    if len(parts) not in (2, 3) or min(parts) < 1:
        raise argparse.ArgumentTypeError(
            f"size must look like {_SIZE_FORMS}, got {text!r}")
    return tuple(parts)


def parse_param(text: str) -> tuple[str, float | str]:
    """``NAME=VALUE``: a number, or an expression of x, y, z, t, Lx, Ly, Lz, pi and the
    other parameters (checked when the model is built)."""
    name, sep, value = text.partition("=")
    name, value = name.strip(), value.strip()
    if not sep or not name:
        raise argparse.ArgumentTypeError(f"--param needs NAME=VALUE, got {text!r}")
    if not value:
        raise argparse.ArgumentTypeError(f"--param {name}: no value after '='")
    try:
        v = float(value)
    except ValueError:
        return name, value  # an expression
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"--param {name}: value must be finite")
    return name, v


def parse_sweep_param(text: str) -> tuple[str, Any]:
    """``--param`` of ``rdgpu sweep``: ``NAME=START:STOP:N``, ``NAME=A,B,C`` or
    ``NAME=VALUE`` (see `rdgpu.sweep.parse_axis`)."""
    # lazy: rdgpu.runs.sweep loads the simulation (about a second), which `rdgpu --help`
    # does not need; it needs no optional package to import
    from rdgpu.runs.sweep import parse_axis

    try:
        return parse_axis(text)
    except (TypeError, ValueError) as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def parse_equation(text: str) -> tuple[str, str]:
    """``SPECIES=RIGHT-HAND SIDE`` of ``--equation``."""
    name, sep, rhs = text.partition("=")
    name, rhs = name.strip(), rhs.strip()
    if not sep or not name or not rhs:
        raise argparse.ArgumentTypeError(
            f"--equation needs SPECIES=EXPRESSION, e.g. 'u=Du*laplace(u) - u*v**2 + "
            f"F*(1 - u)', got {text!r}")
    return name, rhs


def positive_int(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if n < 0:
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {n}")
    return n


def at_least_1(text: str) -> int:
    n = positive_int(text)
    if n < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {n}")
    return n


def parse_seed(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 0, got {text!r}") \
            from None
    if n < 0:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 0, got {n}")
    return n


def parse_colour_range(text: str) -> tuple[float, ...]:
    if text.strip().lower() == "auto":
        return ()
    parts = text.split(":")
    try:
        lo, hi = (float(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected LO:HI (e.g. --range=-1:1) or auto, got {text!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise argparse.ArgumentTypeError(f"expected finite LO < HI, got {text!r}")
    return lo, hi


def finite_float(text: str) -> float:
    try:
        x = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(x):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return x


def positive_float(text: str) -> float:
    try:
        x = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(x) and x > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return x



def parse_fps(text: str) -> float:
    """--fps: the movie writers' own check (``rdgpu.io.writers.check_fps``), before the run."""
    try:
        x = float(text)
    except ValueError:
        x = math.nan
    try:
        return check_fps(x)
    except ValueError:
        lo, hi = FPS_RANGE
        raise Bad(f"expected a frame rate from {lo:g} to {hi:g} frames a second, got "
                  f"{text!r}") from None


def parse_block_steps(text: str) -> int:
    try:
        k = int(text)
    except ValueError:
        k = 0
    if not 1 <= k <= MAX_BLOCK_STEPS:
        raise Bad(f"expected a whole number from 1 (off) to {MAX_BLOCK_STEPS}, got {text}")
    return k


# ------------------------------------------------------------------- parts of a spec
def _whole_part(spec: str, name: str, text: str, least: int = 0) -> int:
    try:
        n = int(text)
    except ValueError:
        n = least - 1
    if n < least:
        raise Bad(f"{spec!r}: {name} must be a whole number >= {least}, got {text!r}")
    return n


def _number_part(spec: str, name: str, text: str, lo: float, hi: float) -> float:
    try:
        x = float(text)
    except ValueError:
        x = math.nan
    if not lo <= x <= hi:
        raise Bad(f"{spec!r}: {name} must be a number from {lo:g} to {hi:g}, got {text!r}")
    return x


_HEIGHT_FORMS = ("expected waves:AMPLITUDE:M[xN][:SEED] (e.g. waves:0.5:5x15), "
                 "heat:AMPLITUDE:STEPS[:SEED] (e.g. heat:0.5:15) or FILE.npy")


def parse_height(text: str) -> Any:
    """``--height``: ``waves:A:M[xN][:SEED]``, ``heat:A:STEPS[:SEED]`` or ``FILE.npy``."""
    kind, _, rest = text.partition(":")
    parts = rest.split(":") if rest else []
    if kind in ("waves", "heat") and len(parts) in (2, 3):
        amplitude = _number_part(text, "AMPLITUDE", parts[0], 0.0, MAX_HEIGHT)
        seed = _whole_part(text, "SEED", parts[2]) if len(parts) == 3 else 0
        if kind == "heat":
            return Given(text, kind="heat-filtered", amplitude=amplitude,
                         filter_steps=_whole_part(text, "STEPS", parts[1]), seed=seed)
        freq = [_whole_part(text, "M and N", f) for f in parts[1].lower().split("x")]
        if len(freq) not in (1, 2):
            raise Bad(f"{text!r}: the frequencies are M or MxN, got {parts[1]!r}")
        return Given(text, kind="random-waves", amplitude=amplitude,
                     max_frequency=freq if len(freq) == 2 else freq[0], seed=seed)
    if kind not in ("waves", "heat") and text.endswith(".npy"):
        return _height_file(text)
    raise Bad(f"{text!r}: {_HEIGHT_FORMS}")


def _height_file(text: str) -> Any:
    import numpy as np

    if not Path(text).is_file():
        raise Bad(f"no such file: {text}")
    try:
        h = np.load(text, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise Bad(f"{text} is not a readable .npy array ({exc})") from None
    if not (isinstance(h, np.ndarray) and h.ndim == 2 and h.dtype.kind in "iuf"):
        raise Bad(f"{text}: expected an [ny, nx] array of real numbers, got "
                  f"{getattr(h, 'dtype', type(h).__name__)} of shape {getattr(h, 'shape', '?')}")
    if not np.isfinite(h).all():
        raise Bad(f"{text}: the heights must be finite")
    return h


def parse_roughen(text: str) -> dict:
    """``--roughen AMPLITUDE[:STEPS[:SEED]]``."""
    parts = text.split(":")
    form = "expected AMPLITUDE[:STEPS[:SEED]], e.g. 0.05:15:3"
    if not 1 <= len(parts) <= 3:
        raise Bad(f"{text!r}: {form}")
    try:
        return _roughen_parts(text, parts)
    except Bad as exc:
        raise Bad(f"{exc} ({form})") from None


def _roughen_parts(text: str, parts: list[str]) -> Given:
    return Given(text, amplitude=_number_part(text, "AMPLITUDE", parts[0], 0.0, MAX_HEIGHT),
                 filter_steps=_whole_part(text, "STEPS", parts[1]) if len(parts) > 1 else 15,
                 seed=_whole_part(text, "SEED", parts[2]) if len(parts) > 2 else 0)


# ------------------------------------------------------------------------- --init
_INIT_FORMS = ("expected square[:SIZE], spots[:COUNT], noise[:AMPLITUDE] (each optionally "
               "followed by ,SPECIES=VALUE...) or FILE.npz")


def _init(text: str) -> dict:
    """``--init``: ``square[:SIZE]``, ``spots[:COUNT]``, ``noise[:AMPLITUDE]``, each with
    ``,SPECIES=VALUE`` parts (the values inside the square or spots; with noise, the
    uniform values), or ``FILE.npz`` (the fields of an rdgpu data file, or one array per
    species).  Returns ``{"kind": ..., "number": ..., "values": {...}}`` or
    ``{"kind": "file", "path": ...}``; `rdgpu.cli.domain` makes the init of it."""
    if text.lower().endswith(".npz"):
        return {"kind": "file", "path": text}
    head, *pairs = text.split(",")
    kind, sep, number = head.partition(":")
    kind = kind.strip().lower()
    if kind not in ("square", "spots", "noise"):
        raise Bad(f"{_INIT_FORMS}, got {text!r}")
    out: dict[str, Any] = {"kind": kind, "number": None, "values": {}, "text": text}
    if sep:
        if kind == "spots":
            out["number"] = _whole_part(text, "COUNT", number, least=1)
        elif kind == "square":
            out["number"] = _number_part(text, "SIZE (a fraction of each side)", number,
                                         1e-12, 1.0)
        else:
            out["number"] = _number_part(text, "AMPLITUDE", number, 0.0, 1e30)
    for pair in pairs:
        name, eq, value = pair.partition("=")
        try:
            v = float(value)
        except ValueError:
            v = math.nan
        if not eq or not name.strip() or not math.isfinite(v):
            raise Bad(f"{text!r}: {pair} is not SPECIES=NUMBER")
        out["values"][name.strip()] = v
    return out


# --------------------------------------------------------------------------- --bc
_BC_FORMS = ("expected periodic, neumann or dirichlet:VALUE, or one per axis joined by / "
             "(y/x, or z/y/x on a 3-D grid), e.g. neumann/periodic")


def _one_bc(whole: str, text: str) -> Any:
    name, sep, value = text.strip().lower().partition(":")
    if name in ("periodic", "neumann") and not sep:
        return name
    if name == "dirichlet" and sep:
        try:
            v = float(value)
        except ValueError:
            v = math.nan
        if math.isfinite(v):
            return ("dirichlet", v)
    raise Bad(f"{_BC_FORMS}, got {whole!r}")


def _bc(text: str) -> tuple:
    """``--bc``: one condition, or one per axis (``y/x``, ``z/y/x``): a tuple of them."""
    return tuple(_one_bc(text, part) for part in text.split("/"))


_FIELD_FORMS = ("SPECIES[:SIDE]=KIND[:VALUE], SIDE one of x- x+ y- y+ z- z+ x y z (default: "
                "every non-periodic side), KIND periodic, neumann, dirichlet, value or robin:A "
                "(each VALUE a number or an expression of x, y, z, t and the parameters), "
                "e.g. u:x-=value:1+sin(t), v=neumann:0.5 or u:x=periodic")


def field_bc(text: str) -> tuple[str, str, Any]:
    """``--bc SPECIES[:SIDE]=KIND[:VALUE...]``: ``(species, side or "*", condition)`` as
    `rdgpu.domains.boundary.parse_side` takes it."""
    where, _, cond = text.partition("=")
    species, sep, side = where.strip().partition(":")
    parts = [p.strip() for p in cond.split(":")]
    kind = parts[0].lower()
    if not species.strip() or (sep and not side.strip()) or not kind:
        raise Bad(f"expected {_FIELD_FORMS}; got {text!r}")

    def value(v: str) -> Any:
        try:
            x = float(v)
        except ValueError:
            return v
        return x if math.isfinite(x) else v

    if len(parts) == 1:
        return species.strip(), side.strip() or "*", kind
    return species.strip(), side.strip() or "*", (kind, *(value(v) for v in parts[1:]))


class BcAction(argparse.Action):
    """``--bc``, repeatable: the grid's conditions (`_bc`; once), or with ``=`` one
    species' condition on some sides (`field_bc`), gathered in ``field_bc``."""

    def __call__(self, parser: Any, namespace: Any, values: Any, option_string: Any = None):
        if "=" not in values:
            if getattr(namespace, self.dest, None) is not None:
                raise argparse.ArgumentError(self, "the grid's conditions are given once; "
                                             f"per species use {_FIELD_FORMS}")
            try:
                setattr(namespace, self.dest, _bc(values))
            except Bad as exc:
                raise argparse.ArgumentError(self, str(exc)) from None
            return
        try:
            species, side, cond = field_bc(values)
        except Bad as exc:
            raise argparse.ArgumentError(self, str(exc)) from None
        found = dict(getattr(namespace, "field_bc", None) or {})
        found.setdefault(species, {})[side] = cond
        namespace.field_bc = found


class NoiseAction(argparse.Action):
    """``--noise``, repeatable: ``VARIANCE`` for every species (py-pde's ``"*"``) or
    ``SPECIES=VARIANCE``, each a number or an expression, gathered in one mapping."""

    def __call__(self, parser: Any, namespace: Any, values: Any, option_string: Any = None):
        name, value = "*", values.strip()
        head, sep, rest = value.partition("=")
        if sep and re.fullmatch(r"[A-Za-z]\w*", head.strip()) and not rest.startswith("="):
            name, value = head.strip(), rest.strip()
        if not value:
            raise argparse.ArgumentError(self, f"{values!r}: give a variance, e.g. 0.01, "
                                         "'0.1*u' or u=0.02*u*v")
        found = dict(getattr(namespace, self.dest, None) or {})
        if name in found:
            raise argparse.ArgumentError(self, f"the noise of {name!r} is given twice")
        try:
            found[name] = float(value)
        except ValueError:
            found[name] = value
        setattr(namespace, self.dest, found)


def bc_value(bcs: tuple, ndim: int, text: str) -> Any:
    """The ``bc`` of a grid of ``ndim`` axes from `_bc`'s tuple (a ValueError where
    the count does not fit)."""
    if len(bcs) == 1:
        return bcs[0]
    if len(bcs) != ndim:
        axes = "y/x" if ndim == 2 else "z/y/x" if ndim == 3 else "x"
        raise ValueError(f"--bc {text}: a {ndim}-D grid takes one condition or {ndim} "
                         f"({axes})")
    return tuple(bcs)


# ------------------------------------------------------------------------- --mesh
def mesh_level(text: str, generators: Any) -> tuple[str, dict]:
    """``--mesh NAME[:LEVEL]``: the generator (or file) and the options LEVEL sets."""
    name, sep, level = text.partition(":")
    key = name.lower()
    if not sep or key not in generators:
        return text, {}
    if key not in LEVEL_OPTIONS:
        allowed = ", ".join(list(LEVEL_OPTIONS)[:-1]) + f" and {list(LEVEL_OPTIONS)[-1]}"
        raise ValueError(f"--mesh {text}: only {allowed} take a LEVEL")
    try:
        n = int(level)
    except ValueError:
        n = -1
    least = 0 if LEVEL_OPTIONS[key] == "subdivisions" else 3
    most = MAX_LEVEL if least == 0 else 4096
    if not least <= n <= most:
        raise ValueError(f"--mesh {text}: LEVEL must be a whole number from {least} to "
                         f"{most}, got {level!r}")
    option = LEVEL_OPTIONS[key]
    extra = {"n_lon": 2 * n} if key == "uv-sphere" else {"n_minor": max(3, n // 2)} \
        if key == "torus" else {}
    return key, {option: n, **extra}


# ------------------------------------------------------------------ the new options
def add_domain_options(group: Any) -> None:
    """--dx/--length, --bc, --radius and --init of ``rdgpu run``."""
    spacing = group.add_mutually_exclusive_group()
    spacing.add_argument("--dx", type=positive_float, metavar="H",
                         help="grid spacing, the same along every axis (default: the "
                         "preset's or the model's, 1 for most)")
    spacing.add_argument("--length", type=positive_float, metavar="L",
                         help="the grid's length along x (columns): dx = L / columns, the "
                         "same spacing along every axis")
    group.add_argument("--bc", action=BcAction, metavar="BC[/BC...]",
                       help="grid boundary conditions: periodic, neumann (zero flux) or "
                       "dirichlet:VALUE, one for every axis or one per axis joined by / "
                       "(y/x, or z/y/x on a 3-D grid), e.g. neumann/periodic (default: the "
                       "preset's, else periodic); repeat it with SPECIES[:SIDE]=KIND[:VALUE] "
                       "for one species' condition on non-periodic sides: KIND neumann "
                       "(VALUE the outward derivative), dirichlet, value (the face's value) "
                       "or robin:A (du/dn + A u = VALUE), each VALUE a number or an "
                       "expression of x, y, z, t, e.g. --bc neumann --bc u:x-=value:sin(t)")
    group.add_argument("--mask", metavar="EXPR|PICTURE",
                       help="evolve only inside a mask on a 2-D or 3-D grid: an indicator "
                       "expression of x, y, z, Lx, Ly, Lz and the parameters, e.g. "
                       "'(x-Lx/2)**2 + (y-Ly/2)**2 < (Lx/3)**2', or a picture (.png, .jpg) "
                       "whose bright pixels are inside; zero flux across its edge, the "
                       "cells outside grey in the pictures (explicit methods)")
    group.add_argument("--radius", type=positive_float, metavar="R",
                       help="radius of a generated mesh: sphere, uv-sphere, disc; torus: "
                       "the ring radius R, the tube 0.3 R (default 1)")
    group.add_argument("--init", type=_init, metavar="SPEC",
                       help="initial condition: square[:SIZE] (a square of SIZE times each "
                       "side, default 0.1), spots[:COUNT] (COUNT discs of radius 3 cells, "
                       "default 10), noise[:AMPLITUDE] (the start values plus uniform noise); "
                       ",SPECIES=VALUE... after it sets the values inside the square or spots "
                       "(default: the model's own, e.g. Gray-Scott u=0.5,v=0.25) or, with "
                       "noise, the start values; or FILE.npz: the fields of a --data file, a "
                       "checkpoint or an NPZ of one array per field. E.g. --init spots:20, "
                       "--init square:0.2,u=0.5,v=0.25, --init noise:0.01")
