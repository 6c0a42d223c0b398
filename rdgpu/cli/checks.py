"""The checks of ``rdgpu run`` made before the run starts: the output paths and formats,
the optional packages the outputs need, the picture's size (``--scale``), ``--view`` and
``--level``; and the domain in words for the messages.  Each failure is a
`UsageError` (exit status 2) or a
`MissingExtraError` naming the extra."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from rdgpu.cli.common import UsageError, check_output, grid_text
from rdgpu.cli.domain import check_init_file
from rdgpu.core.optional import MissingExtraError, check, require
from rdgpu.io.output import MESH_FORMATS, MOVIE_FORMATS, slices_size

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain

DEFAULT_SCALE = 2
#: the largest picture (pixels) and side (pixels) that --scale may ask for
MAX_PICTURE_PIXELS = 2**28
MAX_PICTURE_SIDE = 65_000


def describe_domain(domain: Domain) -> str:
    """The domain in words, from its description: ``256x256 grid (dx=1, periodic)``,
    ``graph surface over a 128x128 grid (dx=0.5)``, ``mesh of 2562 vertices, 5120
    faces``."""
    desc = domain.describe()
    if domain.unstructured:
        return f"mesh of {desc['n_vertices']} vertices, {desc['n_faces']} faces"
    shape = grid_text(domain.field_shape)
    if domain.kind == "graph-surface":
        return f"graph surface over a {shape} grid (dx={desc['dx']:g})"
    conds = [c if isinstance(c, str) else tuple(c) for c in desc["bc"]]
    names = [c if isinstance(c, str) else c[0] for c in conds]
    bcs = names[0] if len(set(conds)) == 1 else "/".join(names)
    what = f"1-D grid of {shape} cells" if len(domain.field_shape) == 1 else f"{shape} grid"
    return f"{what} (dx={desc['dx']:g}, {bcs})"


def is_grid_3d(domain: Domain) -> bool:
    """Whether ``domain`` is a 3-D grid (pictured by an isosurface or mid-plane slices)."""
    return not domain.unstructured and len(domain.field_shape) == 3


def check_options(args: argparse.Namespace) -> None:
    """Everything that can be checked before a model or a domain is built."""
    if args.movie and Path(args.movie).suffix.lower() not in MOVIE_FORMATS:
        raise UsageError(f"--movie must end in {' or '.join(MOVIE_FORMATS)}, got {args.movie!r}")
    for d in args.data or []:
        if Path(d).suffix.lower() not in (".npz", *MESH_FORMATS):
            raise UsageError(f"--data must end in .npz or a mesh format "
                             f"({', '.join(MESH_FORMATS)}), got {d!r}")
    if args.out and Path(args.out).suffix.lower() != ".png":
        raise UsageError(f"--out must end in .png, got {args.out!r}")
    outputs = [("--out", args.out), ("--movie", args.movie)]
    outputs += [("--data", d) for d in args.data or []]
    outputs += [("--checkpoint", args.checkpoint)]
    for option, path in outputs:
        if path:
            check_output(option, path)
    ckpt = args.checkpoint or args.resume
    if ckpt:
        for option, path in outputs[:-1]:
            if path and Path(path).resolve() == Path(ckpt).resolve():
                which = "--checkpoint" if args.checkpoint else "--resume"
                raise UsageError(f"{option} {path} is also the {which} file: the output "
                                 "would overwrite the checkpoint")
    if args.checkpoint_every is not None and not ckpt:
        raise UsageError("--checkpoint-every needs --checkpoint PATH (or --resume)")
    if args.movie and args.snapshot_every == 0:
        raise UsageError("--movie needs snapshots: --snapshot-every must be > 0")
    check_init_file(args)
    if args.cmap is not None:
        colormaps = require("matplotlib", "--cmap (a Matplotlib colour map)").colormaps
        if args.cmap not in colormaps:
            close = [c for c in sorted(colormaps) if c.lower().startswith(args.cmap[:3].lower())
                     and not c.endswith("_r")][:4]
            raise UsageError(f"--cmap {args.cmap!r} is not a Matplotlib colour map; e.g. "
                             f"{', '.join(close or ['viridis', 'magma', 'gray', 'RdBu'])}")


def picture_size(shape: tuple[int, ...], k: int) -> tuple[int, int]:
    """``(height, width)`` in pixels of the picture of a grid of ``shape`` at ``k`` pixels a
    cell: the grid itself in 2-D (one row in 1-D), the three mid-plane slices of a 3-D grid
    (the largest picture a 3-D field can get, see ``rdgpu.output.slices_rgb``)."""
    if len(shape) == 3:
        return slices_size(shape, k)
    ny, nx = (1, shape[0]) if len(shape) == 1 else shape[-2:]
    return ny * k, nx * k


def picture_scale(args: argparse.Namespace, shape: tuple[int, ...] | None) -> int:
    """--scale, or the default (2, or 1 for a grid too large for that); refuse a picture
    past MAX_PICTURE_PIXELS or MAX_PICTURE_SIDE."""
    if shape is None:  # a mesh: rendered at a fixed window size
        return args.scale or DEFAULT_SCALE

    def fits(k: int) -> bool:
        h, w = picture_size(shape, k)
        return h * w <= MAX_PICTURE_PIXELS and max(h, w) <= MAX_PICTURE_SIDE

    if args.scale is None:
        return DEFAULT_SCALE if fits(DEFAULT_SCALE) else 1
    if not fits(args.scale):
        most = max([k for k in range(1, args.scale) if fits(k)], default=None)
        h, w = picture_size(shape, args.scale)
        what = "slices of this" if len(shape) == 3 else "this"
        grid = grid_text((1, shape[0]) if len(shape) == 1 else shape)
        raise UsageError(f"--scale {args.scale} makes a {h}x{w}-"
                         f"pixel picture of {what} {grid} grid; the most is "
                         f"{MAX_PICTURE_SIDE} pixels a side and {MAX_PICTURE_PIXELS:,} in all"
                         + (f" (--scale {most} or less)" if most else ""))
    return args.scale


def frame_size(shape: tuple[int, ...], scale: int) -> tuple[int, int]:
    """``(height, width)`` of a movie frame of a grid: its picture at ``scale``, at least
    the 480 x 480 window of a 3-D isosurface frame."""
    h, w = picture_size(shape, scale)
    return (max(h, 480), max(w, 480)) if len(shape) == 3 else (h, w)


def check_view(args: argparse.Namespace, domain: Domain) -> None:
    """--view and --level picture 3-D grids only; --view isosurface needs pyvista."""
    if not is_grid_3d(domain):
        for option in ("--view", "--level"):
            if getattr(args, option[2:]) is not None:
                raise UsageError(f"{option} is for 3-D grids (--size NxMxK); this run is on "
                                 f"a {describe_domain(domain)}")
        return
    if args.view == "isosurface":
        check("pyvista", "--view isosurface (--view slices needs only the media extra)")


def check_extras(args: argparse.Namespace, is_mesh: bool) -> None:
    """The optional packages that the asked-for outputs need, checked before the run: a
    missing one raises `MissingExtraError` naming the extra (``--data PATH.npz``
    needs none)."""
    default_png = args.out is None and not args.movie and not args.data
    pictures = bool(args.out or args.movie or default_png)
    needs = []
    if pictures:
        what = "writing the PNG picture" if args.out or default_png else "writing the movie"
        needs += [("imageio", what), ("matplotlib", what)]
    if args.movie and Path(args.movie).suffix.lower() == ".mp4":
        needs.append(("imageio_ffmpeg", "writing MP4 movies"))
    if is_mesh and pictures:
        needs.append(("pyvista", "rendering the mesh"))
    if any(Path(d).suffix.lower() in (".vtk", ".vtp", ".vtu") for d in args.data or []):
        needs.append(("pyvista", "writing VTK files"))
    if any(Path(d).suffix.lower() in (".msh", ".xdmf", ".inp") for d in args.data or []):
        needs.append(("meshio", "writing gmsh/XDMF/Abaqus files"))
    for module, purpose in needs:
        try:
            check(module, purpose)
        except MissingExtraError as exc:
            if not default_png:
                raise
            raise MissingExtraError(f"{exc} (or give --data PATH.npz to write the fields "
                                    "and no picture)", module=exc.module, extra=exc.extra) from None
