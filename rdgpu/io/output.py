"""Writing what a run produced: pictures, movies, mesh files and one data file per run.

* `save_png` -- a colour-mapped PNG of a field: a grid field pixel for pixel
  (`rdgpu.io.images`), a mesh field rendered off-screen with pyvista
  (`render_mesh_png`), a 3-D grid field as an isosurface rendered with pyvista
  (`render_volume`) or as three mid-plane slices (`slices_rgb`).
* `save_movie` -- a GIF or MP4 of the snapshots (imageio; MP4 needs
  ``imageio-ffmpeg``), with one colour scale and one renderer for all frames.
* `save_mesh` -- VTK/VTP/VTU or PLY files of a mesh with its fields attached.
* `save_npz` / `load_npz` -- one NPZ per run with the final fields, the
  snapshots, their times and steps, the parameters, the model, the domain, the backend, the
  device, the dtype and the package versions.
* `write_outputs` -- all of the above for a `Result`, by
  file extension (what the command line uses).

Every writer takes the path first (`rdgpu.io.writers`), writes atomically and refuses
a path that is not a regular file (`rdgpu.core.files`); a field uniform to round-off is
drawn in one flat colour (`rdgpu.io.images.flat_field`).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.core.files import atomic_path, check_writable, writing
from rdgpu.core.optional import require
from rdgpu.domains.base import is_domain
from rdgpu.io import images
from rdgpu.io.datafile import load_npz, save_npz
from rdgpu.io.images import colour_limits, flat_field, to_rgb
from rdgpu.io.rendering import (
    render_frames,
    render_mesh,
    render_mesh_png,
    render_options,
    render_surface,
    surface_mesh,
)
from rdgpu.io.volumes import (
    VIEWS_3D,
    is_volume,
    render_volume,
    slices_rgb,
    slices_size,
    volume_frames,
    volume_images,
)
from rdgpu.io.writers import FPS_RANGE, check_fps, earlier_order, write_image

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain
    from rdgpu.domains.grid import Grid
    from rdgpu.domains.mesh.surface_mesh import SurfaceMesh

__all__ = [
    "FPS_RANGE",
    "MESH_FORMATS",
    "MOVIE_FORMATS",
    "VIEWS_3D",
    "check_fps",
    "ensemble_mosaic",
    "load_npz",
    "render_mesh",
    "render_mesh_png",
    "render_surface",
    "render_volume",
    "save_mesh",
    "save_movie",
    "save_npz",
    "save_png",
    "slices_rgb",
    "slices_size",
    "surface_mesh",
    "write_outputs",
]

MOVIE_FORMATS = (".gif", ".mp4")
#: mesh files that keep per-vertex fields (VTK and PLY by pyvista/rdgpu; gmsh, XDMF, Abaqus
#: by meshio, the ``[mesh]`` extra)
MESH_FORMATS = (".vtk", ".vtp", ".vtu", ".ply", ".msh", ".xdmf", ".inp")

PathLike = str | os.PathLike


def _on_mesh(domain: Domain | None) -> bool:
    """Whether ``domain`` is unstructured (a mesh: fields are per-vertex values)."""
    return is_domain(domain) and domain.unstructured


def _on_grid(domain: Domain | None) -> bool:
    """Whether ``domain`` is a grid or a graph surface (fields on cells)."""
    return is_domain(domain) and not domain.unstructured


def _grid_field(field: np.ndarray, domain: Domain | None) -> np.ndarray:
    a = np.asarray(field)
    if _on_grid(domain) and a.ndim == 1 and a.size == domain.n_points:
        a = a.reshape(domain.kernel_shape)
    if a.ndim == 1:
        a = a[None, :]
    if a.ndim != 2:
        raise ValueError(f"a grid picture needs a 2-D field, got shape {a.shape}")
    return a



# ------------------------------------------------------------------------------- PNG
def save_png(
    path: PathLike,
    field: np.ndarray,
    domain: Domain | None = None,
    *,
    cmap: str = "viridis",
    vmin: float | None = None,
    vmax: float | None = None,
    scale: int = 1,
    camera: Any = None,
    window_size: tuple[int, int] = (800, 800),
    view: str = "auto",
    level: float | None = None,
) -> Path:
    """A colour-mapped PNG of ``field``: on a mesh ``domain`` a pyvista rendering
    (`render_mesh_png`), on a 1-D grid a plot of the field against x, on a 3-D grid
    (or a 3-D array without a domain) a picture chosen by ``view``, otherwise the grid
    field with each cell ``scale``×``scale`` pixels (row 0 at the top).

    3-D ``view``: ``"isosurface"`` -- the surface ``field = level`` rendered off-screen
    with pyvista at ``window_size`` (`render_volume`; ``level`` defaults to the
    middle of the colour range ``vmin``..``vmax``); ``"slices"`` -- the xy, xz and yz
    mid-planes side by side, ``scale`` pixels a cell (`slices_rgb`); ``"auto"``
    (default) -- the isosurface, except the slices where it would show nothing or cannot be
    drawn: pyvista missing, a side of fewer than 2 cells, a field that does not reach the
    level (e.g. uniform), or a failed rendering (with a ``RuntimeWarning``).

    Parameters
    ----------
    path : str or os.PathLike
        The PNG file: a missing folder is created, an existing regular file replaced,
        anything else refused.
    field : array
        A grid field ``[ny, nx]`` or ``[nx]`` (or flat, as many values as the grid's
        cells), one value per vertex on a mesh, ``[nz, ny, nx]`` on a 3-D grid.
    domain : Domain, optional
        The `Grid`, `GraphSurface` (pictured as its grid) or `SurfaceMesh` the field
        lives on; default None (a 2-D array is a grid picture, a 1-D one a single row, a
        3-D one a 3-D grid of spacing 1).
    cmap : str, optional
        A Matplotlib colour map name; default ``"viridis"``.
    vmin, vmax : float, optional
        The colour range (on a 1-D grid, the plot's y limits); default None (the
        finite values' range; a field uniform to round-off is drawn in one flat colour).
    scale : int, optional
        Pixels per cell along each side of a grid picture or of the slices; default 1.
    camera : str, sequence or dict, optional
        The view of a pyvista rendering (a mesh, a 3-D isosurface), as `render_mesh`
        takes it; default None (the isometric view).
    window_size : tuple of int, optional
        ``(width, height)`` in pixels of a pyvista rendering; default ``(800, 800)``.
    view : {"auto", "isosurface", "slices"}, optional
        How a 3-D grid field is pictured (`VIEWS_3D`); default ``"auto"``.
    level : float, optional
        The isosurface's value; default None (the middle of the colour range).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    TypeError
        ``path`` that is not a ``str`` or ``os.PathLike``.
    ValueError
        A path that cannot be written (a folder, an empty name...), a grid field that is
        not 1- or 2-D, a 3-D field not of the grid's shape, an unknown ``view``, or
        ``view="isosurface"`` with fewer than 2 cells along an axis.
    MissingExtraError
        imageio, Matplotlib or (meshes, isosurfaces) pyvista is not installed.
    RuntimeError
        A pyvista rendering failed (``view="auto"`` draws slices instead).
    """
    path = check_writable(path, "the picture")
    field, vmin, vmax = flat_field(np.asarray(field), vmin, vmax)
    if is_volume(field, domain):
        frames = volume_frames(np.asarray(field)[None], domain)
        lo, hi = colour_limits(frames, vmin, vmax)
        return write_image(path, volume_images(
            frames, domain, view=view, level=level, cmap=cmap, lo=lo, hi=hi, scale=scale,
            camera=camera, window_size=window_size)[0])
    if _on_grid(domain) and len(domain.field_shape) == 1:
        return _save_line_plot(path, np.asarray(field).ravel(), domain, vmin, vmax)
    if _on_mesh(domain):
        return render_mesh_png(path, field, domain, cmap=cmap, camera=camera, vmin=vmin,
                               vmax=vmax, window_size=window_size)
    return images.save_png(path, _grid_field(field, domain), cmap=cmap, vmin=vmin, vmax=vmax,
                 scale=scale)


def _save_line_plot(path: Path, field: np.ndarray, grid: Grid, vmin: float | None,
                    vmax: float | None) -> Path:
    """A 1-D field as a curve over the cell centres ``x = (j + ½) dx``."""
    matplotlib = require("matplotlib", "plotting a 1-D field")
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    x = (np.arange(field.size) + 0.5) * grid.dx
    fig, ax = plt.subplots(figsize=(8, 3), dpi=100)
    ax.plot(x, field, lw=1.2)
    ax.set_xlim(0, field.size * grid.dx)
    if vmin is not None or vmax is not None:
        ax.set_ylim(vmin, vmax)
    ax.set_xlabel("x")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    try:
        with atomic_path(path, "the picture") as tmp:
            fig.savefig(tmp, format="png")
    finally:
        plt.close(fig)
    return path


# ---------------------------------------------------------------------------- movies
def _even(img: np.ndarray) -> np.ndarray:
    """Pad an image by edge replication to even height and width (for H.264)."""
    h, w = img.shape[:2]
    return np.pad(img, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge")


def save_movie(
    path: PathLike,
    frames: Sequence[np.ndarray] | np.ndarray,
    domain: Domain | None = None,
    *,
    cmap: str = "viridis",
    vmin: float | None = None,
    vmax: float | None = None,
    fps: float = 10.0,
    scale: int = 1,
    camera: Any = None,
    window_size: tuple[int, int] = (480, 480),
    view: str = "auto",
    level: float | None = None,
) -> Path:
    """A GIF or MP4 (by extension) of ``frames`` (``[n, ny, nx]`` grid fields,
    ``[n, n_vertices]`` on a mesh ``domain``, rendered with pyvista, or ``[n, nz, ny, nx]``
    on a 3-D grid, pictured as `save_png` does by ``view`` and ``level``, one
    renderer and one camera for all frames; ``"auto"`` takes the isosurface when some frame
    reaches the level) with one colour scale (``vmin``/``vmax``, default the range over
    all frames).  MP4 needs ``imageio-ffmpeg`` (H.264, frames padded to even sizes).

    Parameters
    ----------
    path : str or os.PathLike
        The movie file, ``.gif`` or ``.mp4``.
    frames : array or sequence of arrays
        ``[n, *field]``: the frames, each a field as `save_png` takes it (``n >= 1``).
    domain : Domain, optional
        As in `save_png`; default None.
    cmap : str, optional
        A Matplotlib colour map name; default ``"viridis"``.
    vmin, vmax : float, optional
        The colour range; default None (the range over all frames; a field uniform to
        round-off is drawn in one flat colour).
    fps : float, optional
        Frames per second, within `FPS_RANGE`; default 10.
    scale : int, optional
        Pixels per cell along each side of a grid picture or of the slices; default 1.
    camera : str, sequence or dict, optional
        The view of a pyvista rendering (a mesh, a 3-D isosurface), as `render_mesh`
        takes it; default None (the isometric view).
    window_size : tuple of int, optional
        ``(width, height)`` in pixels of a pyvista rendering; default ``(480, 480)``.
    view : {"auto", "isosurface", "slices"}, optional
        How 3-D grid frames are pictured; default ``"auto"``.
    level : float, optional
        The isosurface's value; default None (the middle of the colour range).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    TypeError
        ``path`` that is not a path, or ``fps`` that is not a number.
    ValueError
        A path that cannot be written or not ``.gif``/``.mp4``, ``fps`` outside
        `FPS_RANGE`, no frames, or frames `save_png` would refuse.
    MissingExtraError
        imageio (MP4: ``imageio-ffmpeg``), Matplotlib or (meshes, isosurfaces) pyvista
        is not installed.
    RuntimeError
        A pyvista rendering failed (``view="auto"`` draws slices instead).
    """
    path = check_writable(path, "the movie")
    ext = path.suffix.lower()
    if ext not in MOVIE_FORMATS:
        raise ValueError(f"a movie must be {' or '.join(MOVIE_FORMATS)}, got {str(path)!r}")
    fps = check_fps(fps)
    data = np.asarray(frames)
    if data.ndim < 2 or data.shape[0] == 0:
        raise ValueError("a movie needs at least one frame (take snapshots: snapshot_every)")
    data, vmin, vmax = flat_field(data, vmin, vmax)
    lo, hi = colour_limits(data, vmin, vmax)
    if _on_mesh(domain):
        options = render_options(data, cmap=cmap, camera=camera, vmin=lo, vmax=hi,
                                  window_size=window_size)
        images = list(render_frames(domain, data.reshape(len(data), -1), options))
    elif is_volume(data[0], domain):
        images = volume_images(volume_frames(data, domain), domain, view=view, level=level,
                                cmap=cmap, lo=lo, hi=hi, scale=scale, camera=camera,
                                window_size=window_size)
    else:
        images = []
        for f in data:
            rgb = to_rgb(_grid_field(f, domain), cmap, lo, hi)
            if scale > 1:
                rgb = np.repeat(np.repeat(rgb, scale, axis=0), scale, axis=1)
            images.append(rgb)
    if ext == ".gif":
        iio = require("imageio.v3", "writing GIF movies")
        with atomic_path(path, "the movie") as tmp:
            iio.imwrite(tmp, np.stack(images), extension=".gif", duration=1000.0 / fps, loop=0)
        return path
    require("imageio_ffmpeg", "writing MP4 movies")
    iio2 = require("imageio.v2", "writing MP4 movies")
    with atomic_path(path, "the movie") as tmp:
        with iio2.get_writer(tmp, format="FFMPEG", mode="I", fps=fps, codec="libx264",
                             pixelformat="yuv420p", macro_block_size=1, quality=8) as w:
            for img in images:
                w.append_data(_even(img))
    return path


# ------------------------------------------------------------------------ mesh files
def save_mesh(path: PathLike, mesh: SurfaceMesh,
              fields: Mapping[str, np.ndarray] | None = None) -> Path:
    """Write ``mesh`` with per-vertex ``fields`` attached (`MESH_FORMATS`; see
    ``SurfaceMesh.save``), atomically except XDMF (whose data goes to a ``.h5`` beside
    it).  The earlier order ``(mesh, path, fields)`` works, deprecated.

    Parameters
    ----------
    path : str or os.PathLike
        The file; its extension (one of `MESH_FORMATS`) picks the format.
    mesh : SurfaceMesh
        The mesh.
    fields : mapping of str to array, optional
        Per-vertex fields by name; default None (the mesh alone).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    TypeError
        ``path`` that is not a ``str`` or ``os.PathLike``.
    ValueError
        A path that cannot be written or of another extension, or ``mesh`` that is not a
        mesh (a grid).
    """
    if earlier_order("save_mesh", path, "save_mesh(path, mesh, fields)"):
        path, mesh = mesh, path
    path = check_writable(path, "the mesh file")
    if not _on_mesh(mesh):
        raise ValueError("mesh files (VTK, PLY, gmsh...) need a mesh domain; use save_npz or "
                         "save_png for a grid")
    if path.suffix.lower() not in MESH_FORMATS:
        raise ValueError(f"a mesh file with fields must be one of {', '.join(MESH_FORMATS)}, "
                         f"got {str(path)!r}")
    arrays = {k: np.asarray(v) for k, v in (fields or {}).items()}
    if path.suffix.lower() == ".xdmf":
        with writing(path, "the mesh file"):
            path.parent.mkdir(parents=True, exist_ok=True)
            mesh.save(path, arrays)
        return path
    with atomic_path(path, "the mesh file") as tmp:
        mesh.save(tmp, arrays)
    return path


# ----------------------------------------------------------------------- ensembles
def ensemble_mosaic(fields: np.ndarray, columns: int | None = None, gap: int = 1) -> np.ndarray:
    """One 2-D picture of an ensemble's fields ``[M, ny, nx]`` (2-D grids) or ``[M, 1, nx]``
    / ``[M, nx]`` (1-D grids: one row per member, top to bottom).  2-D members are tiled
    row by row, member 0 at the top left, ``columns`` a row (default: about √M), separated
    by ``gap`` cells of NaN (drawn grey).

    Parameters
    ----------
    fields : array
        ``[M, ny, nx]``, ``[M, 1, nx]`` or ``[M, nx]``: one field per member.
    columns : int, optional
        Members per row of the mosaic (2-D grids); default None (``ceil(√M)``).
    gap : int, optional
        Cells between neighbouring members (2-D grids); default 1.

    Returns
    -------
    ndarray
        float64, 2-D: ``[M, nx]`` for 1-D grids; for 2-D grids ``rows (ny + gap) − gap``
        by ``columns (nx + gap) − gap``, NaN in the gaps and unused tiles.

    Raises
    ------
    ValueError
        ``fields`` of another number of dimensions.
    """
    a = np.asarray(fields, dtype=np.float64)
    if a.ndim == 3 and a.shape[1] == 1:
        a = a[:, 0, :]
    if a.ndim == 2:
        return a
    if a.ndim != 3:
        raise ValueError(f"a mosaic needs members of a 1-D or 2-D grid, got shape {a.shape}")
    m, ny, nx = a.shape
    cols = max(1, int(columns) if columns else math.ceil(math.sqrt(m)))
    rows = -(-m // cols)
    out = np.full((rows * (ny + gap) - gap, cols * (nx + gap) - gap), np.nan)
    for k in range(m):
        r, c = divmod(k, cols)
        out[r * (ny + gap): r * (ny + gap) + ny, c * (nx + gap): c * (nx + gap) + nx] = a[k]
    return out


def _member_path(path: PathLike, m: int) -> Path:
    p = Path(path)
    return p.with_name(f"{p.stem}-m{m:04d}{p.suffix}")


def _ensemble_pictures(result: Any, name: str, png: Any, movie: Any, kw: dict,
                       fps: float) -> list[Path]:
    """Pictures of an ensemble: one mosaic on 1-D and 2-D grids; one file per member
    (``NAME-m0000.png``...) on meshes and 3-D grids, which have no mosaic."""
    domain, written = result.domain, []
    flat = _on_grid(domain) and len(domain.field_shape) <= 2
    if png is not None:
        if flat:
            written.append(save_png(png, ensemble_mosaic(result.fields[name]), None, **kw))
        else:
            for m, f in enumerate(result.fields[name]):
                written.append(save_png(_member_path(png, m), f, domain, **kw))
    if movie is not None:
        if not flat:
            raise ValueError("a movie of an ensemble needs a 1-D or 2-D grid (a mosaic of the "
                             "members); on meshes and 3-D grids write --data and pictures")
        frames = np.stack([ensemble_mosaic(f) for f in result.snapshots[name]]) \
            if len(result.snapshots[name]) else result.snapshots[name]
        written.append(save_movie(movie, frames, None, fps=fps, **kw))
    return written


# ----------------------------------------------------------------------- everything
def write_outputs(
    result: Any,
    *,
    png: PathLike | None = None,
    movie: PathLike | None = None,
    data: PathLike | Sequence[PathLike] | None = None,
    field: str | None = None,
    cmap: str = "viridis",
    scale: int = 1,
    fps: float = 10.0,
    camera: Any = None,
    vmin: float | None = None,
    vmax: float | None = None,
    view: str = "auto",
    level: float | None = None,
) -> list[Path]:
    """Write the outputs of a run, by extension: ``png`` (the final ``field``), ``movie``
    (``.gif``/``.mp4`` of that field's snapshots), ``data`` (``.npz`` data files and
    ``.vtk``/``.vtp``/``.vtu``/``.ply`` meshes with every final field).  ``field`` defaults
    to the first species; ``vmin``/``vmax`` fix the colour scale (default: the field's
    range); ``view`` and ``level`` say how a 3-D grid field is pictured (see
    `save_png`).

    Every path and ``fps`` are checked before anything is written.  An ensemble's
    result (``result.members`` set) is pictured as one mosaic of its members
    (`ensemble_mosaic`) on 1-D and 2-D grids, and as one picture per member
    (``NAME-m0000.png``, ...) on meshes and 3-D grids, where it has no movie.

    Parameters
    ----------
    result : Result
        A run's result (`rdgpu.simulation.Simulation.run`, `load_npz`).
    png : str or os.PathLike, optional
        The picture of the final ``field`` (`save_png`); default None (none).
    movie : str or os.PathLike, optional
        The ``.gif``/``.mp4`` of ``field``'s snapshots (`save_movie`); default None.
    data : str, os.PathLike or a sequence of them, optional
        Data files: ``.npz`` (`save_npz`) or mesh files of `MESH_FORMATS` with every final
        field (`save_mesh`); default None.
    field : str, optional
        The species pictured; default None (the first).
    cmap : str, optional
        A Matplotlib colour map name; default ``"viridis"``.
    scale : int, optional
        Pixels per cell along each side of grid pictures; default 1.
    fps : float, optional
        The movie's frames per second (`FPS_RANGE`); default 10.
    camera : str, sequence or dict, optional
        The view of a pyvista rendering (a mesh, a 3-D isosurface), as `render_mesh`
        takes it; default None (the isometric view).
    vmin, vmax : float, optional
        The colour range; default None (the field's finite range; a field uniform to
        round-off is drawn in one flat colour).
    view : {"auto", "isosurface", "slices"}, optional
        How a 3-D grid field is pictured; default ``"auto"``.
    level : float, optional
        The isosurface's value; default None (the middle of the colour range).

    Returns
    -------
    list of Path
        The files written, in the order picture, movie, data files.

    Raises
    ------
    TypeError
        A path that is not a ``str`` or ``os.PathLike``, or ``fps`` that is not a number
        (with a movie).
    ValueError
        A ``field`` the result does not have, a path that cannot be written, ``fps``
        outside `FPS_RANGE` (with a movie), a data file of another extension, a movie of
        an ensemble on a mesh or a 3-D grid, or what the writers refuse.
    """
    species = list(result.fields)
    name = species[0] if field is None else field
    if name not in result.fields:
        raise ValueError(f"no field {name!r}; the model has {species}")
    datas = [] if data is None else [data] if isinstance(data, (str, os.PathLike)) else data
    for p, what in [(png, "the picture"), (movie, "the movie"), *((d, "the data file")
                                                                  for d in datas)]:
        if p is not None:  # every path and the frame rate checked before anything is written
            check_writable(p, what)
    if movie is not None:
        check_fps(fps)
    written: list[Path] = []
    if getattr(result, "members", None) is not None:
        kw = {"cmap": cmap, "scale": scale, "camera": camera, "vmin": vmin, "vmax": vmax,
              "view": view, "level": level}
        written += _ensemble_pictures(result, name, png, movie, kw, fps)
        png = movie = None
    mask = getattr(result, "mask", None)  # a masked run: outside it grey (NaN)
    hide = (lambda a: a) if mask is None else (lambda a: np.where(mask, a, np.nan))
    if png is not None:
        written.append(save_png(png, hide(result.fields[name]), result.domain, cmap=cmap,
                                scale=scale, camera=camera, vmin=vmin, vmax=vmax, view=view,
                                level=level))
    if movie is not None:
        written.append(save_movie(movie, hide(result.snapshots[name]), result.domain, cmap=cmap,
                                  fps=fps, scale=scale, camera=camera, vmin=vmin, vmax=vmax,
                                  view=view, level=level))
    if data is not None:
        for p in [data] if isinstance(data, (str, os.PathLike)) else data:
            ext = Path(p).suffix.lower()
            if ext == ".npz":
                written.append(save_npz(p, result))
            elif ext in MESH_FORMATS:
                written.append(save_mesh(p, result.domain, result.fields))
            else:
                raise ValueError(f"a data file must be .npz or a mesh file "
                                 f"({', '.join(MESH_FORMATS)}), got {str(p)!r}")
    return written

