"""Writing what a run produced: pictures, movies, mesh files and one data file per run.

* :func:`save_png` -- a colour-mapped PNG of a field: a grid field pixel for pixel
  (:mod:`rdgpu.io.images`), a mesh field rendered off-screen with pyvista
  (:func:`render_mesh_png`), a 3-D grid field as an isosurface rendered with pyvista
  (:func:`render_volume`) or as three mid-plane slices (:func:`slices_rgb`).
* :func:`save_movie` -- a GIF or MP4 of the snapshots (imageio; MP4 needs
  ``imageio-ffmpeg``), with one colour scale and one renderer for all frames.
* :func:`save_mesh` -- VTK/VTP/VTU or PLY files of a mesh with its fields attached.
* :func:`save_npz` / :func:`load_npz` -- one NPZ per run with the final fields, the
  snapshots, their times and steps, the parameters, the model, the domain, the backend, the
  device, the dtype and the package versions.
* :func:`write_outputs` -- all of the above for a :class:`~rdgpu.simulation.Result`, by
  file extension (what the command line uses).

Every writer takes the path first (:mod:`rdgpu.io.writers`), writes atomically and refuses
a path that is not a regular file (:mod:`rdgpu.core.files`); a field uniform to round-off is
drawn in one flat colour (:func:`rdgpu.io.images.flat_field`).
"""

from __future__ import annotations

import json
import math
import os
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from rdgpu.core.files import atomic_path, check_writable, writing
from rdgpu.core.optional import available, check, require
from rdgpu.domains.grid import Grid
from rdgpu.io.datafile import load_npz, save_npz
from rdgpu.io.images import flat_field, to_rgb
from rdgpu.io.writers import FPS_RANGE, check_fps, earlier_order, write_image

__all__ = [
    "FPS_RANGE",
    "MESH_FORMATS",
    "MOVIE_FORMATS",
    "VIEWS_3D",
    "check_fps",
    "load_npz",
    "render_mesh",
    "render_mesh_png",
    "render_volume",
    "save_mesh",
    "save_movie",
    "save_npz",
    "save_png",
    "slices_rgb",
    "slices_size",
    "write_outputs",
]

MOVIE_FORMATS = (".gif", ".mp4")
#: mesh files that keep per-vertex fields (VTK and PLY by pyvista/rdgpu; gmsh, XDMF, Abaqus
#: by meshio, the ``[mesh]`` extra)
MESH_FORMATS = (".vtk", ".vtp", ".vtu", ".ply", ".msh", ".xdmf", ".inp")
#: how a field on a 3-D grid is pictured (see :func:`save_png`)
VIEWS_3D = ("auto", "isosurface", "slices")

PathLike = str | os.PathLike


def _is_mesh(domain: Any) -> bool:
    return hasattr(domain, "faces") and hasattr(domain, "vertices")


def _grid_field(field: np.ndarray, domain: Any) -> np.ndarray:
    a = np.asarray(field)
    if isinstance(domain, Grid) and a.ndim == 1 and a.size == domain.n_points:
        a = a.reshape(domain.shape)
    if a.ndim == 1:
        a = a[None, :]
    if a.ndim != 2:
        raise ValueError(f"a grid picture needs a 2-D field, got shape {a.shape}")
    return a


def _limits(a: np.ndarray, vmin: float | None, vmax: float | None) -> tuple[float, float]:
    finite = np.asarray(a)[np.isfinite(a)]
    lo = float(finite.min()) if vmin is None and finite.size else (vmin or 0.0)
    hi = float(finite.max()) if vmax is None and finite.size else (vmax if vmax is not None
                                                                    else 1.0)
    return lo, hi


# ------------------------------------------------------------------------- mesh renders
def _camera(plotter: Any, camera: Any) -> None:
    if camera is None:
        plotter.camera_position = "iso"
        plotter.camera.zoom(1.3)
    elif isinstance(camera, str):
        plotter.camera_position = camera
    elif isinstance(camera, Mapping):
        cam = dict(camera)
        allowed = {"position", "focal_point", "viewup", "azimuth", "elevation", "roll", "zoom"}
        unknown = set(cam) - allowed
        if unknown:
            raise ValueError(f"unknown camera key(s) {sorted(unknown)}; allowed: {sorted(allowed)}")
        if {"position", "focal_point", "viewup"} & set(cam):
            pos = plotter.camera_position
            plotter.camera_position = [cam.get("position", pos[0]),
                                       cam.get("focal_point", pos[1]),
                                       cam.get("viewup", pos[2])]
        else:
            plotter.camera_position = "iso"
        for key in ("azimuth", "elevation", "roll"):
            if key in cam:
                setattr(plotter.camera, key, getattr(plotter.camera, key) + float(cam[key]))
        if "zoom" in cam:
            plotter.camera.zoom(float(cam["zoom"]))
    else:
        plotter.camera_position = list(camera)


def _pyvista() -> Any:
    """pyvista, set to render off-screen, with VTK's display warnings silenced."""
    pv = require("pyvista", "rendering meshes and 3-D isosurfaces")
    pv.OFF_SCREEN = True
    try:  # VTK warns when no X display exists, then renders with EGL/OSMesa anyway
        from vtkmodules.vtkCommonCore import vtkLogger

        vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
    except ImportError:  # pragma: no cover
        pass
    return pv


def _screenshot(plotter: Any) -> np.ndarray:
    plotter.render()
    return np.asarray(plotter.screenshot(return_img=True))[..., :3].copy()


def _is_planar(vertices: np.ndarray) -> bool:
    """All vertices in the plane z = const (to 1e-9 of the mesh's size)."""
    v = np.asarray(vertices, dtype=np.float64)
    extent = float(np.ptp(v, axis=0).max()) if len(v) else 0.0
    return len(v) > 0 and float(np.ptp(v[:, 2])) <= 1e-9 * max(extent, 1e-300)


class _MeshRenderer:
    """One off-screen pyvista plotter for a mesh; :meth:`image` renders a per-vertex field.

    ``smooth=True`` (the default): the field is point data, its colours interpolated across
    every face (the scalars are interpolated before the colour map, so a face between a
    vertex at −1 and one at +1 shows the whole map in between) and lit with smooth (Phong,
    per-vertex normal) shading: a resolved interface looks like the smooth curve it is.
    ``smooth=False``: flat faces, each coloured by the mean of its three vertices (cell
    data), which shows the pattern as the mesh resolves it, triangle by triangle."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, *, cmap: str,
                 clim: tuple[float, float], camera: Any, window_size: tuple[int, int],
                 background: str, show_edges: bool, scalar_bar: bool,
                 smooth: bool = True) -> None:
        pv = _pyvista()
        faces = np.asarray(faces, dtype=np.int64)
        cells = np.hstack([np.full((len(faces), 1), 3, dtype=np.int64), faces]).ravel()
        self.pd = pv.PolyData(np.asarray(vertices, dtype=np.float64), cells)
        self.n = len(vertices)
        self.faces = faces
        self.smooth = bool(smooth)
        data = self.pd.point_data if self.smooth else self.pd.cell_data
        data["field"] = np.zeros(self.n if self.smooth else len(faces))
        self.plotter = pv.Plotter(off_screen=True, window_size=list(window_size))
        self.plotter.set_background(background)
        self.plotter.add_mesh(self.pd, scalars="field", cmap=cmap, clim=list(clim),
                              show_edges=show_edges, show_scalar_bar=scalar_bar,
                              preference="point" if self.smooth else "cell",
                              smooth_shading=self.smooth, interpolate_before_map=True)
        if camera is None and _is_planar(vertices):
            self.plotter.camera_position = "xy"  # a flat mesh (a disc, a plane): from above
            self.plotter.camera.zoom(1.3)
        else:
            _camera(self.plotter, camera)

    def image(self, field: np.ndarray) -> np.ndarray:
        f = np.asarray(field, dtype=np.float64).ravel()
        if self.smooth:
            arr = self.pd.point_data["field"]
            arr[:] = f
        else:
            arr = self.pd.cell_data["field"]
            arr[:] = f[self.faces].mean(axis=1)
        arr.Modified()
        return _screenshot(self.plotter)

    def close(self) -> None:
        self.plotter.close()


class _VolumeRenderer:
    """One off-screen pyvista plotter for fields on a 3-D grid: the isosurface
    ``field = level`` (one colour, the colour map's at ``level`` within ``clim``) inside the
    grid's grey outline; :meth:`image` renders a ``[nz, ny, nx]`` field.

    The grid is a ``pv.ImageData`` whose points are the cell centres ``((j + ½) dx,
    (i + ½) dy, (k + ½) dz)``; a C-order ``[nz, ny, nx]`` field is VTK's x-fastest point
    order.  The camera is set once from the outline, so movie frames share one view."""

    def __init__(self, shape: tuple[int, int, int], spacing: tuple[float, float, float], *,
                 cmap: str, clim: tuple[float, float], level: float, camera: Any,
                 window_size: tuple[int, int], background: str) -> None:
        pv = _pyvista()
        nz, ny, nx = (int(n) for n in shape)
        dz, dy, dx = (float(h) for h in spacing)
        self.grid = pv.ImageData(dimensions=(nx, ny, nz), spacing=(dx, dy, dz),
                                 origin=(dx / 2, dy / 2, dz / 2))
        self.level = float(level)
        self.colour = _level_colour(cmap, clim, self.level)
        self.plotter = pv.Plotter(off_screen=True, window_size=list(window_size))
        self.plotter.set_background(background)
        self.plotter.add_mesh(self.grid.outline(), color="gray", line_width=1)
        _camera(self.plotter, {"zoom": 1.0} if camera is None else camera)

    def image(self, field: np.ndarray) -> np.ndarray:
        self.grid.point_data["field"] = np.asarray(field, dtype=np.float64).ravel()
        surface = self.grid.contour([self.level], scalars="field")
        self.plotter.remove_actor("isosurface", render=False)
        if surface.n_points:  # a frame that does not reach the level shows the outline only
            self.plotter.add_mesh(surface, color=self.colour, smooth_shading=True,
                                  name="isosurface", reset_camera=False)
        return _screenshot(self.plotter)

    def close(self) -> None:
        self.plotter.close()


def _level_colour(cmap: str, clim: tuple[float, float], level: float) -> tuple:
    """The RGB colour (floats in [0, 1]) that ``cmap`` gives ``level`` on the scale ``clim``."""
    colormaps = require("matplotlib", "colouring the isosurface").colormaps
    lo, hi = clim
    t = (level - lo) / (hi - lo) if hi > lo else 0.5
    return tuple(float(c) for c in colormaps[cmap](min(max(t, 0.0), 1.0))[:3])


def _render_frames(mesh: Any, frames: np.ndarray, options: dict) -> np.ndarray:
    """Render every frame (``[n, n_vertices]``) of a mesh field to ``[n, h, w, 3]`` uint8
    (see :func:`_render`)."""
    frames = np.asarray(frames, dtype=np.float64)
    if frames.ndim != 2 or frames.shape[1] != mesh.n_vertices:
        raise ValueError(f"a mesh field needs one value per vertex ({mesh.n_vertices}), got "
                         f"shape {frames.shape[1:]}")
    if getattr(mesh, "period", None) is not None:  # periodic: draw it unwrapped at the seams
        V, F, source = mesh.unwrapped()
        arrays = {"vertices": V, "faces": F, "frames": frames[:, source]}
    else:
        arrays = {"vertices": np.asarray(mesh.vertices), "faces": np.asarray(mesh.faces),
                  "frames": frames}
    return _render(arrays, {**options, "kind": "mesh"})


def _render(arrays: dict[str, np.ndarray], options: dict) -> np.ndarray:
    """Render ``arrays["frames"]`` to ``[n, h, w, 3]`` uint8 images: a mesh
    (``options["kind"] == "mesh"``, arrays ``vertices`` and ``faces``) or a 3-D grid
    (``"volume"``, array ``spacing`` = ``(dz, dy, dx)``).

    The rendering runs in a child Python process: VTK's off-screen rendering loads Mesa's
    LLVM, and an OpenCL driver that links another LLVM (PoCL, Oclgrind) and initialises
    later in the same process aborts it ("LLVM ERROR: inconsistency in registered
    CommandLine options").  ``RDGPU_RENDER_INPROCESS=1`` renders in this process instead
    (faster; safe when no OpenCL device is opened after the first rendering)."""
    what = "the 3-D field" if options.get("kind") == "volume" else "the mesh"
    check("pyvista", f"rendering {what}")  # here: the child's traceback would bury the hint
    if os.environ.get("RDGPU_RENDER_INPROCESS"):
        return _render_here(arrays, options)
    import subprocess
    import sys
    import tempfile

    root = str(Path(__file__).resolve().parents[1])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        p for p in (root, os.environ.get("PYTHONPATH")) if p)}
    with tempfile.TemporaryDirectory(prefix="rdgpu-render-") as tmp:
        src, dst = Path(tmp) / "in.npz", Path(tmp) / "out.npz"
        np.savez(src, **arrays, options=np.array(json.dumps(options)))
        code = "import sys; from rdgpu.output import _render_main; _render_main(*sys.argv[1:])"
        proc = subprocess.run([sys.executable, "-c", code, str(src), str(dst)], env=env,
                              capture_output=True, text=True)
        if proc.returncode != 0 or not dst.exists():
            lines = [ln for ln in proc.stderr.strip().splitlines() if ln.strip()]
            raise RuntimeError(f"rendering {what} failed: "
                               + (lines[-1] if lines else f"exit status {proc.returncode}"))
        with np.load(dst) as z:
            return z["images"]


def _render_here(arrays: dict[str, np.ndarray], options: dict) -> np.ndarray:
    options = dict(options)
    kind = options.pop("kind", "mesh")
    frames = arrays["frames"]
    if kind == "volume":
        r: Any = _VolumeRenderer(frames.shape[1:], tuple(arrays["spacing"]), **options)
    else:
        r = _MeshRenderer(arrays["vertices"], arrays["faces"], **options)
    try:
        return np.stack([r.image(f) for f in frames])
    finally:
        r.close()


def _render_main(src: str, dst: str) -> None:
    """Entry point of the rendering child process (see :func:`_render`)."""
    with np.load(src, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files if k != "options"}
        options = json.loads(str(z["options"]))
    options["clim"] = tuple(options["clim"])
    options["window_size"] = tuple(options["window_size"])
    np.savez(dst, images=_render_here(arrays, options))


def _render_options(frames: np.ndarray, *, cmap: str, camera: Any, vmin: float | None,
                    vmax: float | None, window_size: tuple[int, int], background: str = "white",
                    show_edges: bool = False, scalar_bar: bool = False,
                    smooth: bool | None = None) -> dict:
    if isinstance(camera, (tuple, list)):
        camera = [list(map(float, p)) for p in camera]
    return {"cmap": cmap, "clim": list(_limits(frames, vmin, vmax)), "camera": camera,
            "window_size": [int(w) for w in window_size], "background": background,
            "show_edges": bool(show_edges), "scalar_bar": bool(scalar_bar),
            **({} if smooth is None else {"smooth": bool(smooth)})}


def render_mesh(
    mesh: Any,
    field: np.ndarray,
    *,
    cmap: str = "viridis",
    camera: Any = None,
    vmin: float | None = None,
    vmax: float | None = None,
    window_size: tuple[int, int] = (800, 800),
    background: str = "white",
    show_edges: bool = False,
    scalar_bar: bool = False,
    smooth: bool = True,
) -> np.ndarray:
    """Render a per-vertex ``field`` on ``mesh`` off-screen with pyvista; an ``(h, w, 3)``
    uint8 image (rendered in a child process, see :func:`_render_frames`).  ``smooth``:
    colours interpolated across faces with smooth shading (default), or flat faces coloured
    by their vertices' mean (see :class:`_MeshRenderer`).

    ``camera``: ``None`` (isometric view, zoomed 1.3), a pyvista view name (``"xy"``,
    ``"iso"``, ...), a ``[position, focal_point, viewup]`` triple, or a dict with any of
    ``position``, ``focal_point``, ``viewup``, ``azimuth``, ``elevation``, ``roll``
    (degrees, added to the isometric view) and ``zoom``."""
    field, vmin, vmax = flat_field(np.asarray(field, dtype=np.float64).ravel(), vmin, vmax)
    options = _render_options(field, cmap=cmap, camera=camera, vmin=vmin, vmax=vmax,
                              window_size=window_size, background=background,
                              show_edges=show_edges, scalar_bar=scalar_bar, smooth=smooth)
    return _render_frames(mesh, field[None, :], options)[0]


def render_mesh_png(path: PathLike, field: np.ndarray, mesh: Any, *, cmap: str = "viridis",
                    camera: Any = None, **kwargs: Any) -> Path:
    """Write :func:`render_mesh` of ``field`` on ``mesh`` to the PNG ``path`` (the earlier
    order ``(mesh, field, path)`` works, deprecated)."""
    if earlier_order("render_mesh_png", path, "render_mesh_png(path, field, mesh)"):
        path, mesh = mesh, path
    path = check_writable(path, "the picture")
    return write_image(path, render_mesh(mesh, field, cmap=cmap, camera=camera, **kwargs))


# ---------------------------------------------------------------------- 3-D grid fields
def _is_volume(field: np.ndarray, domain: Any) -> bool:
    """Whether ``field`` is pictured as a 3-D grid field: on a 3-D :class:`Grid`, or an
    array of three dimensions without a domain."""
    if isinstance(domain, Grid):
        return domain.ndim == 3
    return domain is None and np.ndim(field) == 3


def _volume_frames(frames: Any, domain: Any) -> np.ndarray:
    """``frames`` as a float64 ``[n, nz, ny, nx]`` array (flat frames reshaped to the grid)."""
    data = np.asarray(frames, dtype=np.float64)
    if isinstance(domain, Grid) and data.ndim == 2 and data.shape[1] == domain.n_points:
        data = data.reshape(len(data), *domain.shape)
    if data.ndim != 4 or (isinstance(domain, Grid) and data.shape[1:] != domain.shape):
        want = domain.shape if isinstance(domain, Grid) else "(nz, ny, nx)"
        raise ValueError(f"a 3-D picture needs fields of shape {want}, got {data.shape[1:]}")
    return data


def _spacing(domain: Any) -> tuple[float, float, float]:
    """``(dz, dy, dx)`` of a 3-D grid; 1 for a bare array."""
    return (domain.dz, domain.dy, domain.dx) if isinstance(domain, Grid) else (1.0, 1.0, 1.0)


def slices_size(shape: Sequence[int], scale: int = 1) -> tuple[int, int]:
    """``(height, width)`` in pixels of :func:`slices_rgb` of a field of ``shape``
    ``(nz, ny, nx)``."""
    nz, ny, nx = (int(n) for n in shape)
    gap = 2 * scale
    return max(ny, nz) * scale, (nx + nx + ny) * scale + 2 * gap


def slices_rgb(field: np.ndarray, cmap: str = "viridis", vmin: float | None = None,
               vmax: float | None = None, scale: int = 1) -> np.ndarray:
    """Three orthogonal mid-plane slices of a ``[nz, ny, nx]`` field side by side, as an
    ``(h, w, 3)`` uint8 image (sizes: :func:`slices_size`), on one colour scale
    (``vmin``/``vmax``, default the field's range).

    Left to right: the xy plane at ``z = nz // 2`` (rows y, columns x: a 2-D picture of
    that plane), the xz plane at ``y = ny // 2`` (rows z, columns x) and the yz plane at
    ``x = nx // 2`` (rows z, columns y); row 0 at the top, each cell ``scale``×``scale``
    pixels, panels top-aligned with white gaps of ``2 scale`` pixels and white below the
    shorter ones."""
    a = np.asarray(field, dtype=np.float64)
    if a.ndim != 3:
        raise ValueError(f"slices need a 3-D field [nz, ny, nx], got shape {a.shape}")
    a, vmin, vmax = flat_field(a, vmin, vmax)
    lo, hi = _limits(a, vmin, vmax)
    nz, ny, nx = a.shape
    panels = [a[nz // 2], a[:, ny // 2, :], a[:, :, nx // 2]]
    height, width = slices_size(a.shape, scale)
    out = np.full((height, width, 3), 255, dtype=np.uint8)
    left = 0
    for p in panels:
        rgb = to_rgb(p, cmap, lo, hi)
        rgb = np.repeat(np.repeat(rgb, scale, axis=0), scale, axis=1)
        out[:rgb.shape[0], left:left + rgb.shape[1]] = rgb
        left += rgb.shape[1] + 2 * scale
    return out


def _iso_level(level: float | None, lo: float, hi: float) -> float:
    """The isosurface level: ``level``, else the middle of the colour range ``[lo, hi]``."""
    return 0.5 * (lo + hi) if level is None else float(level)


def render_volume(
    field: np.ndarray,
    grid: Grid | None = None,
    *,
    level: float | None = None,
    cmap: str = "viridis",
    camera: Any = None,
    vmin: float | None = None,
    vmax: float | None = None,
    window_size: tuple[int, int] = (800, 800),
    background: str = "white",
) -> np.ndarray:
    """Render the isosurface ``field = level`` of a ``[nz, ny, nx]`` field off-screen with
    pyvista (``pv.ImageData`` of the cell centres, spaced by the grid's ``dx``, ``dy``,
    ``dz``; 1 without a grid); an ``(h, w, 3)`` uint8 image.

    ``level`` defaults to the middle of the colour range (``vmin``/``vmax``, default the
    field's range); the surface takes the colour map's colour at ``level``, inside the
    grid's grey outline.  ``camera`` as in :func:`render_mesh` (default: the isometric
    view).  Rendered in a child process (see :func:`_render`)."""
    frames, vmin, vmax = flat_field(_volume_frames(np.asarray(field)[None], grid), vmin, vmax)
    lo, hi = _limits(frames, vmin, vmax)
    return _render_volume(frames, grid, _iso_level(level, lo, hi), cmap=cmap, clim=(lo, hi),
                          camera=camera, window_size=window_size, background=background)[0]


def _render_volume(frames: np.ndarray, grid: Any, level: float, *, cmap: str,
                   clim: tuple[float, float], camera: Any, window_size: tuple[int, int],
                   background: str = "white") -> np.ndarray:
    """Isosurface images ``[n, h, w, 3]`` of ``[n, nz, ny, nx]`` frames (one camera)."""
    if min(frames.shape[1:]) < 2:
        raise ValueError(f"an isosurface needs at least 2 cells along every axis, got "
                         f"{frames.shape[1:]}; picture it as slices")
    if isinstance(camera, (tuple, list)):
        camera = [list(map(float, p)) for p in camera]
    options = {"kind": "volume", "cmap": cmap, "clim": [float(c) for c in clim],
               "level": float(level), "camera": camera,
               "window_size": [int(w) for w in window_size], "background": background}
    arrays = {"frames": frames, "spacing": np.asarray(_spacing(grid), dtype=np.float64)}
    return _render(arrays, options)


def _volume_view(view: str, frames: np.ndarray, level: float) -> str:
    """The renderer of 3-D frames: ``view`` itself, or for ``"auto"`` the isosurface when
    pyvista is installed, every side has 2 cells or more and some frame reaches ``level``
    (else there is nothing to draw), and the slices otherwise."""
    if view not in VIEWS_3D:
        raise ValueError(f"view must be one of {', '.join(VIEWS_3D)}, got {view!r}")
    if view != "auto":
        return view
    finite = frames[np.isfinite(frames)]
    crosses = finite.size > 0 and finite.min() < level < finite.max()
    if not available("pyvista") or min(frames.shape[1:]) < 2 or not crosses:
        return "slices"
    return "isosurface"


def _volume_images(frames: np.ndarray, domain: Any, *, view: str, level: float | None,
                   cmap: str, lo: float, hi: float, scale: int, camera: Any,
                   window_size: tuple[int, int]) -> list[np.ndarray]:
    """One picture per ``[nz, ny, nx]`` frame, all by one renderer (see :func:`save_png`);
    with ``view="auto"`` a failed isosurface rendering warns and falls back to slices."""
    level = _iso_level(level, lo, hi)
    if _volume_view(view, frames, level) == "isosurface":
        try:
            return list(_render_volume(frames, domain, level, cmap=cmap, clim=(lo, hi),
                                       camera=camera, window_size=window_size))
        except (RuntimeError, ImportError) as exc:  # a failed rendering, a broken VTK
            if view != "auto":
                raise
            warnings.warn(f"{exc}; drawing mid-plane slices instead", RuntimeWarning,
                          stacklevel=3)
    return [slices_rgb(f, cmap, lo, hi, scale) for f in frames]


# ------------------------------------------------------------------------------- PNG
def save_png(
    path: PathLike,
    field: np.ndarray,
    domain: Any = None,
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
    (:func:`render_mesh_png`), on a 1-D grid a plot of the field against x, on a 3-D grid
    (or a 3-D array without a domain) a picture chosen by ``view``, otherwise the grid
    field with each cell ``scale``×``scale`` pixels (row 0 at the top).

    3-D ``view``: ``"isosurface"`` -- the surface ``field = level`` rendered off-screen
    with pyvista at ``window_size`` (:func:`render_volume`; ``level`` defaults to the
    middle of the colour range ``vmin``..``vmax``); ``"slices"`` -- the xy, xz and yz
    mid-planes side by side, ``scale`` pixels a cell (:func:`slices_rgb`); ``"auto"``
    (default) -- the isosurface, except the slices where it would show nothing or cannot be
    drawn: pyvista missing, a side of fewer than 2 cells, a field that does not reach the
    level (e.g. uniform), or a failed rendering (with a ``RuntimeWarning``)."""
    path = check_writable(path, "the picture")
    field, vmin, vmax = flat_field(np.asarray(field), vmin, vmax)
    if _is_volume(field, domain):
        frames = _volume_frames(np.asarray(field)[None], domain)
        lo, hi = _limits(frames, vmin, vmax)
        return write_image(path, _volume_images(
            frames, domain, view=view, level=level, cmap=cmap, lo=lo, hi=hi, scale=scale,
            camera=camera, window_size=window_size)[0])
    if isinstance(domain, Grid) and domain.ndim == 1:
        return _save_line_plot(path, np.asarray(field).ravel(), domain, vmin, vmax)
    if _is_mesh(domain):
        return render_mesh_png(path, field, domain, cmap=cmap, camera=camera, vmin=vmin,
                               vmax=vmax, window_size=window_size)
    from rdgpu.io.images import save_png as _save

    return _save(path, _grid_field(field, domain), cmap=cmap, vmin=vmin, vmax=vmax,
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
    domain: Any = None,
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
    on a 3-D grid, pictured as :func:`save_png` does by ``view`` and ``level``, one
    renderer and one camera for all frames; ``"auto"`` takes the isosurface when some frame
    reaches the level) with one colour scale (``vmin``/``vmax``, default the range over
    all frames).  MP4 needs ``imageio-ffmpeg`` (H.264, frames padded to even sizes)."""
    path = check_writable(path, "the movie")
    ext = path.suffix.lower()
    if ext not in MOVIE_FORMATS:
        raise ValueError(f"a movie must be {' or '.join(MOVIE_FORMATS)}, got {str(path)!r}")
    fps = check_fps(fps)
    data = np.asarray(frames)
    if data.ndim < 2 or data.shape[0] == 0:
        raise ValueError("a movie needs at least one frame (take snapshots: snapshot_every)")
    data, vmin, vmax = flat_field(data, vmin, vmax)
    lo, hi = _limits(data, vmin, vmax)
    if _is_mesh(domain):
        options = _render_options(data, cmap=cmap, camera=camera, vmin=lo, vmax=hi,
                                  window_size=window_size)
        images = list(_render_frames(domain, data.reshape(len(data), -1), options))
    elif _is_volume(data[0], domain):
        images = _volume_images(_volume_frames(data, domain), domain, view=view, level=level,
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
def save_mesh(path: PathLike, mesh: Any, fields: Mapping[str, np.ndarray] | None = None) -> Path:
    """Write ``mesh`` with per-vertex ``fields`` attached (:data:`MESH_FORMATS`; see
    ``SurfaceMesh.save``), atomically except XDMF (whose data goes to a ``.h5`` beside
    it).  The earlier order ``(mesh, path, fields)`` works, deprecated."""
    if earlier_order("save_mesh", path, "save_mesh(path, mesh, fields)"):
        path, mesh = mesh, path
    path = check_writable(path, "the mesh file")
    if not _is_mesh(mesh):
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
    by ``gap`` cells of NaN (drawn black)."""
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
    flat = isinstance(domain, Grid) and domain.ndim <= 2
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
    :func:`save_png`)."""
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
    if png is not None:
        written.append(save_png(png, result.fields[name], result.domain, cmap=cmap, scale=scale,
                                camera=camera, vmin=vmin, vmax=vmax, view=view, level=level))
    if movie is not None:
        written.append(save_movie(movie, result.snapshots[name], result.domain, cmap=cmap,
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


# ---------------------------------------------------------------------- graph surfaces
def surface_mesh(surface: Any, warp_scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices, faces)`` of a graph surface drawn as ``z = warp_scale · h``: its cell
    centres ``(x, y) = ((j + ½) dx, (i + ½) dy)`` over one period, the first row and
    column repeated one period on (so the picture closes up), as the structured grid of
    ``[ny + 1, nx + 1]`` points (C order) cut into two triangles per quad."""
    ny, nx = surface.shape
    x = (np.arange(nx + 1) + 0.5) * surface.dx
    y = (np.arange(ny + 1) + 0.5) * surface.dy
    yy, xx = np.meshgrid(y, x, indexing="ij")
    z = warp_scale * _wrap_closed(surface.height)
    vertices = np.stack([xx, yy, z], axis=-1).reshape(-1, 3)
    a = (np.arange(ny)[:, None] * (nx + 1) + np.arange(nx)[None, :]).ravel()
    b, c = a + 1, a + nx + 1
    faces = np.concatenate([np.stack([a, b, c + 1], axis=1), np.stack([a, c + 1, c], axis=1)])
    return vertices, faces.astype(np.int64)


def _wrap_closed(a: Any) -> np.ndarray:
    """An ``[ny, nx]`` array with its first row and column appended (periodic closure)."""
    return np.pad(np.asarray(a, dtype=np.float64), ((0, 1), (0, 1)), mode="wrap")


def render_surface(
    path: PathLike,
    field: np.ndarray,
    surface: Any,
    *,
    cmap: str = "viridis",
    warp_scale: float = 1.0,
    camera: Any = None,
    vmin: float | None = None,
    vmax: float | None = None,
    window_size: tuple[int, int] = (800, 800),
    background: str = "white",
) -> Path:
    """Write a PNG of ``field`` (``[ny, nx]``, on the parameter grid) drawn on the 3-D
    surface ``z = warp_scale · h`` of the :class:`~rdgpu.GraphSurface` ``surface``:
    the field as point data of :func:`surface_mesh`, rendered as a mesh is
    (:func:`render_mesh`: pyvista, off-screen in a child process, smooth shading).
    ``camera`` as in :func:`render_mesh`; ``vmin``/``vmax`` fix the colour scale.  The
    earlier order ``(surface, field, path)`` works, deprecated."""
    from rdgpu.domains.graph_surface import GraphSurface

    if earlier_order("render_surface", path, "render_surface(path, field, surface)"):
        path, surface = surface, path
    path = check_writable(path, "the picture")

    if not isinstance(surface, GraphSurface):
        raise TypeError(f"render_surface draws on an rdgpu.domains.graph_surface.GraphSurface, got "
                        f"{type(surface).__name__}")
    f = np.asarray(field.numpy() if hasattr(field, "numpy") else field, dtype=np.float64)
    if f.shape != surface.shape:
        raise ValueError(f"the field has shape {f.shape}; the surface's grid is "
                         f"{surface.shape}")
    scale = float(warp_scale)
    if not math.isfinite(scale):
        raise ValueError(f"warp_scale must be a finite number, got {warp_scale!r}")
    f, vmin, vmax = flat_field(f, vmin, vmax)
    options = _render_options(f, cmap=cmap, camera=camera, vmin=vmin, vmax=vmax,
                              window_size=window_size, background=background)
    vertices, faces = surface_mesh(surface, scale)
    arrays = {"vertices": vertices, "faces": faces, "frames": _wrap_closed(f).reshape(1, -1)}
    return write_image(path, _render(arrays, {**options, "kind": "mesh"})[0])
