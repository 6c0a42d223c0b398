"""Where and from what ``rdgpu run`` starts: the domain spec of ``--size``/``--mesh``
(with ``--dx``/``--length``, ``--bc``, ``--height``, ``--mesh NAME:LEVEL``, ``--radius``,
``--roughen``) over the preset's or the model's default domain, and the initial condition
of ``--init`` (`init_for`).  Errors are `rdgpu.cli.common.UsageError` (exit
2), raised before anything is built."""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.cli.common import UsageError
from rdgpu.cli.options import bc_value, mesh_level
from rdgpu.core.errors import ResourceLimitError
from rdgpu.core.resources import check_memory
from rdgpu.domains.specs import MESH_GENERATORS
from rdgpu.simulation import default_init

if TYPE_CHECKING:
    from rdgpu.models.model import Model

#: generators a --radius sets, and how
_RADIUS = {"sphere": ("radius",), "icosphere": ("radius",), "uv-sphere": ("radius",),
           "uv_sphere": ("radius",), "disc": ("radius",), "disk": ("radius",),
           "torus": ("R", "r")}
#: the share of the tube radius r of a torus in its radius R (SurfaceMesh.torus's default)
_TORUS_TUBE = 0.3


def generator_names() -> list[str]:
    """The --mesh generators, without the spelling variants."""
    return [k for k in MESH_GENERATORS if "_" not in k and k != "disk"]


def domain_spec(args: argparse.Namespace, preset: Any, model: Model, default_size: tuple,
                ) -> dict:
    """The domain spec of the command line (`rdgpu.simulation.build_domain`)."""
    base = dict(preset.domain) if preset is not None else dict(
        getattr(model, "default_domain", None) or {
            "grid": default_size, "dx": float(getattr(model, "spacing", 1.0)),
            "bc": "periodic"})
    if args.size is not None:
        keep = {k: base[k] for k in ("dx", "dy", "dz", "bc") if "grid" in base and k in base}
        if len(args.size) == 3:
            keep["bc"] = _bc_for_3d(keep.get("bc", "periodic"))
        elif len(args.size) == 2 and "dz" in keep:
            del keep["dz"]
        base = {"grid": args.size, **keep}
    elif args.mesh is not None:
        base = mesh_base(args.mesh, base)
    if "grid" in base:
        base = _grid_options(args, base)
    else:
        base = mesh_options(args, base)
    return _surface_options(args, base)


def mesh_base(text: str, base: dict) -> dict:
    """The spec of ``--mesh NAME[:LEVEL]`` (a generator and its options, or a file) over
    ``base`` (kept where it is the same mesh)."""
    try:
        name, options = mesh_level(text, MESH_GENERATORS)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    if name.lower() not in MESH_GENERATORS and not Path(name).exists():
        raise UsageError(f"--mesh {text!r}: no such file (or use a generator: "
                     f"{', '.join(generator_names())}; sphere:LEVEL sets the subdivisions)")
    if "mesh" not in base or str(base["mesh"]) != name:
        base = {"mesh": name}
    return {**base, **options}


def _grid_options(args: argparse.Namespace, spec: dict) -> dict:
    """--dx, --length and --bc on a grid; --radius refused."""
    if getattr(args, "radius", None) is not None:
        raise UsageError("--radius is for a generated mesh (--mesh sphere, uv-sphere, torus or "
                     "disc); a grid's size is --size with --dx or --length")
    g = spec["grid"]
    shape = (int(g), int(g)) if isinstance(g, int) else tuple(int(n) for n in g)
    spacing = getattr(args, "dx", None)
    if getattr(args, "length", None) is not None:
        spacing = args.length / shape[-1]
    if spacing is not None:
        spec = {k: v for k, v in spec.items() if k not in ("dy", "dz")}
        spec["dx"] = float(spacing)
    if getattr(args, "bc", None) is not None:
        text = "/".join(b if isinstance(b, str) else f"dirichlet:{b[1]:g}" for b in args.bc)
        try:
            spec["bc"] = bc_value(args.bc, len(shape) if len(shape) != 1 else 1, text)
        except ValueError as exc:
            raise UsageError(str(exc)) from None
    return spec


def mesh_options(args: argparse.Namespace, spec: dict) -> dict:
    """--radius on a generated mesh; --dx, --length and --bc refused."""
    for option in ("dx", "length", "bc"):
        if getattr(args, option, None) is not None:
            why = ("a mesh's boundary is natural (Neumann)" if option == "bc" else
                   "a mesh's spacing comes from --mesh NAME:LEVEL and --radius")
            raise UsageError(f"--{option} is for a grid (--size); {why}")
    radius = getattr(args, "radius", None)
    if radius is None:
        return spec
    keys = _RADIUS.get(str(spec["mesh"]).lower())
    if keys is None:
        raise UsageError(f"--radius is for a generated mesh (sphere, uv-sphere, torus or disc), "
                     f"not {spec['mesh']}")
    spec = dict(spec)
    spec[keys[0]] = float(radius)
    if len(keys) == 2:
        spec[keys[1]] = _TORUS_TUBE * float(radius)
    return spec


def _surface_options(args: argparse.Namespace, spec: dict) -> dict:
    """``--height`` on a grid, ``--roughen`` on a mesh."""
    height = getattr(args, "height", None)
    rough = getattr(args, "roughen", None)
    if height is not None:
        if "grid" not in spec:
            raise UsageError("--height needs a 2-D grid (--size NxM); for a mesh use --roughen")
        spec = {**spec, "height": height}
    if rough is not None:
        if "mesh" not in spec:
            raise UsageError("--roughen needs a mesh (--mesh); for a grid use --height")
        spec = {**spec, "roughen": rough}
    return spec


def _bc_for_3d(bc: Any) -> Any:
    """The boundary condition of a 3-D ``--size`` from a 2-D default: a pair
    ``(y_bc, x_bc)`` becomes ``(y_bc, y_bc, x_bc)`` (z takes the rows' condition); one
    condition or a triple stays as it is."""
    pair = isinstance(bc, (tuple, list)) and len(bc) == 2 and not (
        isinstance(bc[0], str) and bc[0].lower() == "dirichlet")  # not ("dirichlet", value)
    return (bc[0], bc[0], bc[1]) if pair else bc


# ------------------------------------------------------------------------------ --init
def check_init_file(args: argparse.Namespace) -> None:
    """An --init FILE.npz that exists (checked with the other paths, before the run)."""
    spec = getattr(args, "init", None)
    if spec and spec["kind"] == "file":
        p = Path(spec["path"])
        if not p.is_file():
            raise UsageError(f"--init {spec['path']}: no such file" if not p.exists() else
                         f"--init {spec['path']} is not a file")


#: --init spots:COUNT on a mesh (whose size is not known before it is built): at most this
MAX_SPOTS = 100_000


def init_for(args: argparse.Namespace, model: Model, params: dict, domain: dict | None = None,
             ) -> tuple[Any, Any]:
    """``(init, fields)`` of --init for ``model``: ``(None, None)`` without --init (the
    preset's or the model's default), an init dict, or fields read from a file.  With the
    ``domain`` spec, a spot count past the grid's cells is refused."""
    spec = getattr(args, "init", None)
    if spec is None:
        return None, None
    if spec["kind"] == "spots" and spec["number"] is not None:
        g = (domain or {}).get("grid")
        most = MAX_SPOTS if g is None else (int(g) ** 2 if isinstance(g, int)
                                            else math.prod(int(n) for n in g))
        if spec["number"] > most:
            raise UsageError(f"--init {spec['text']}: at most {most} spots ("
                         + ("one a cell" if g is not None else "on a mesh") + ")")
    species = tuple(model.species)
    if spec["kind"] == "file":
        return None, _fields_from(spec["path"], species)
    unknown = [s for s in spec["values"] if s not in species]
    if unknown:
        raise UsageError(f"--init: model {model.name} has fields {', '.join(species)}, got "
                     f"{', '.join(unknown)}")
    base = default_init(model, {**model.defaults, **params})
    background = _per_species(base.get("values", 0.0), species)
    noise = base.get("noise", 0.0)
    if spec["kind"] == "noise":
        amplitude = spec["number"] if spec["number"] is not None else (noise or 0.05)
        return {"kind": "uniform", "values": {**background, **spec["values"]},
                "noise": amplitude}, None
    inside = dict(spec["values"])
    if not inside:
        if base.get("kind") not in ("square", "spots") or base.get("inside") is None:
            raise UsageError(f"--init {spec['text']}: give the values inside, e.g. --init "
                         f"{spec['kind']},{species[0]}=1 (model {model.name} has no default "
                         "square or spots to take them from)")
        inside = _per_species(base["inside"], species)
    out = {"kind": spec["kind"], "values": background, "inside": inside, "noise": noise}
    if spec["kind"] == "square":
        out["size"] = spec["number"] if spec["number"] is not None else base.get("size", 0.1)
    else:
        out["count"] = spec["number"] if spec["number"] is not None else base.get("count", 10)
    return out, None


def _per_species(values: Any, species: tuple[str, ...]) -> dict:
    if isinstance(values, dict):
        return {s: float(values[s]) for s in species if s in values}
    return dict.fromkeys(species, float(values))


def _fields_from(path: str, species: tuple[str, ...]) -> dict:
    """The fields of an rdgpu data file (``--data``), a checkpoint or an NPZ file of one
    array per species."""
    try:
        with np.load(path, allow_pickle=False) as z:
            names = set(z.files)
            for pattern in ("final_{}", "field__{}", "{}"):
                if all(pattern.format(s) in names for s in species):
                    fields = {s: np.asarray(z[pattern.format(s)]) for s in species}
                    break
            else:
                raise UsageError(f"--init {path}: no fields {', '.join(species)} in it (an "
                             "rdgpu --data file, a checkpoint or an NPZ file of one array "
                             f"per field); it holds {', '.join(sorted(names)) or 'nothing'}")
    except UsageError:
        raise
    except (OSError, ValueError, EOFError) as exc:
        raise UsageError(f"--init {path} is not a readable NPZ file ({exc})") from None
    for s, a in fields.items():
        if a.dtype.kind not in "iuf" or not np.isfinite(a).all():
            raise UsageError(f"--init {path}: field {s!r} must hold finite real numbers")
    return fields


def check_block_memory(k: int | None, spec: dict, n_species: int, itemsize: int) -> None:
    """--block-steps K: the scratch of the blocked passes (``K - 1`` levels of 3 rows per
    species for each work-item, 3 planes in 3-D, two work-items per core;
    `rdgpu.integrators.blocking`) through the shared memory estimate."""
    if not k or k < 2 or "grid" not in spec:
        return
    g = spec["grid"]
    shape = (int(g),) if isinstance(g, int) else tuple(int(n) for n in g)
    unit = shape[-1] * (shape[-2] if len(shape) == 3 else 1)  # a row, or a plane in 3-D
    what = "rows" if len(shape) < 3 else "planes"
    items = 2 * (os.cpu_count() or 1)
    need = (k - 1) * n_species * 3 * unit * itemsize * items
    try:
        check_memory(f"--block-steps {k}", need, f"scratch {what} of {items} work-items on "
                     f"{what} of {unit} cells")
    except ResourceLimitError as exc:
        raise UsageError(str(exc)) from None
