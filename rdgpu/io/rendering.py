"""Off-screen pyvista rendering: per-vertex fields on meshes (`render_mesh`), fields
on graph surfaces (`render_surface`), and the renderer of 3-D grid isosurfaces that
`rdgpu.io.volumes` uses.  Every rendering runs in a child process
(`render_offscreen`)."""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.core.files import check_writable
from rdgpu.core.optional import check, require
from rdgpu.domains.base import is_domain
from rdgpu.io.images import colour_limits, flat_field
from rdgpu.io.writers import earlier_order, write_image

if TYPE_CHECKING:
    from rdgpu.domains.graph_surface import GraphSurface
    from rdgpu.domains.mesh.surface_mesh import SurfaceMesh

__all__ = ["render_frames", "render_main", "render_mesh", "render_mesh_png", "render_offscreen",
           "render_options", "render_surface", "surface_mesh"]

PathLike = str | os.PathLike


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
    """One off-screen pyvista plotter for a mesh; `image` renders a per-vertex field.

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
    grid's grey outline; `image` renders a ``[nz, ny, nx]`` field.

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


def render_frames(mesh: SurfaceMesh, frames: np.ndarray, options: dict) -> np.ndarray:
    """Render every frame (``[n, n_vertices]``) of a mesh field to ``[n, h, w, 3]`` uint8
    (see `render_offscreen`)."""
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
    return render_offscreen(arrays, {**options, "kind": "mesh"})


def render_offscreen(arrays: dict[str, np.ndarray], options: dict) -> np.ndarray:
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

    root = str(Path(__file__).resolve().parents[2])  # the folder that holds rdgpu/
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        p for p in (root, os.environ.get("PYTHONPATH")) if p)}
    with tempfile.TemporaryDirectory(prefix="rdgpu-render-") as tmp:
        src, dst = Path(tmp) / "in.npz", Path(tmp) / "out.npz"
        np.savez(src, **arrays, options=np.array(json.dumps(options)))
        code = "import sys; from rdgpu.io.rendering import render_main; render_main(*sys.argv[1:])"
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


def render_main(src: str, dst: str) -> None:
    """Entry point of the rendering child process (see `render_offscreen`)."""
    with np.load(src, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files if k != "options"}
        options = json.loads(str(z["options"]))
    options["clim"] = tuple(options["clim"])
    options["window_size"] = tuple(options["window_size"])
    np.savez(dst, images=_render_here(arrays, options))


def render_options(frames: np.ndarray, *, cmap: str, camera: Any, vmin: float | None,
                    vmax: float | None, window_size: tuple[int, int], background: str = "white",
                    show_edges: bool = False, scalar_bar: bool = False,
                    smooth: bool | None = None) -> dict:
    if isinstance(camera, (tuple, list)):
        camera = [list(map(float, p)) for p in camera]
    return {"cmap": cmap, "clim": list(colour_limits(frames, vmin, vmax)), "camera": camera,
            "window_size": [int(w) for w in window_size], "background": background,
            "show_edges": bool(show_edges), "scalar_bar": bool(scalar_bar),
            **({} if smooth is None else {"smooth": bool(smooth)})}


def render_mesh(
    mesh: SurfaceMesh,
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
    uint8 image (rendered in a child process, see `render_frames`).  ``smooth``:
    colours interpolated across faces with smooth shading (default), or flat faces coloured
    by their vertices' mean (see `_MeshRenderer`).

    ``camera``: ``None`` (isometric view, zoomed 1.3), a pyvista view name (``"xy"``,
    ``"iso"``, ...), a ``[position, focal_point, viewup]`` triple, or a dict with any of
    ``position``, ``focal_point``, ``viewup``, ``azimuth``, ``elevation``, ``roll``
    (degrees, added to the isometric view) and ``zoom``.

    Parameters
    ----------
    mesh : SurfaceMesh
        The mesh (a periodic one is drawn unwrapped at its seams).
    field : array
        One value per vertex (any shape of that many values).
    cmap : str, optional
        A Matplotlib colour map name; default ``"viridis"``.
    camera : str, sequence or dict, optional
        ``None`` (default: the isometric view, zoomed 1.3), a pyvista view name
        (``"xy"``, ``"iso"``, ...), a ``[position, focal_point, viewup]`` triple, or a
        dict (see above).
    vmin, vmax : float, optional
        The colour range; default None (the field's finite range; a field uniform to
        round-off is drawn in one flat colour).
    window_size : tuple of int, optional
        ``(width, height)`` in pixels; default ``(800, 800)``.
    background : str, optional
        The background colour (a pyvista colour name); default ``"white"``.
    show_edges : bool, optional
        Draw the triangles' edges; default False.
    scalar_bar : bool, optional
        Draw the colour bar; default False.
    smooth : bool, optional
        Interpolated colours with smooth shading (True, default) or flat faces (False).

    Returns
    -------
    ndarray
        uint8, shape ``(h, w, 3)``.

    Raises
    ------
    ValueError
        A field without one value per vertex.
    MissingExtraError
        pyvista is not installed.
    RuntimeError
        The rendering failed, a camera dict with other keys included (the message ends
        with the rendering process's last error line).
    """
    field, vmin, vmax = flat_field(np.asarray(field, dtype=np.float64).ravel(), vmin, vmax)
    options = render_options(field, cmap=cmap, camera=camera, vmin=vmin, vmax=vmax,
                              window_size=window_size, background=background,
                              show_edges=show_edges, scalar_bar=scalar_bar, smooth=smooth)
    return render_frames(mesh, field[None, :], options)[0]


def render_mesh_png(path: PathLike, field: np.ndarray, mesh: SurfaceMesh, *, cmap: str = "viridis",
                    camera: Any = None, **kwargs: Any) -> Path:
    """Write `render_mesh` of ``field`` on ``mesh`` to the PNG ``path`` (the earlier
    order ``(mesh, field, path)`` works, deprecated).

    Parameters
    ----------
    path : str or os.PathLike
        The PNG file; a missing folder is created, an existing regular file replaced.
    field : array
        One value per vertex.
    mesh : SurfaceMesh
        The mesh.
    cmap : str, optional
        A Matplotlib colour map name; default ``"viridis"``.
    camera : str, sequence or dict, optional
        As `render_mesh` takes it; default None (the isometric view).
    **kwargs
        The other options of `render_mesh` (``vmin``, ``vmax``, ``window_size``,
        ``background``, ``show_edges``, ``scalar_bar``, ``smooth``).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    TypeError
        ``path`` is not a ``str`` or ``os.PathLike``.
    ValueError
        ``path`` cannot be written, or what `render_mesh` refuses.
    MissingExtraError
        pyvista or imageio is not installed.
    RuntimeError
        The rendering failed (a camera dict with other keys included).
    """
    if earlier_order("render_mesh_png", path, "render_mesh_png(path, field, mesh)"):
        path, mesh = mesh, path
    path = check_writable(path, "the picture")
    return write_image(path, render_mesh(mesh, field, cmap=cmap, camera=camera, **kwargs))



# ---------------------------------------------------------------------- graph surfaces
def surface_mesh(surface: GraphSurface, warp_scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices, faces)`` of a graph surface drawn as ``z = warp_scale · h``: its cell
    centres ``(x, y) = ((j + ½) dx, (i + ½) dy)`` over one period, the first row and
    column repeated one period on (so the picture closes up), as the structured grid of
    ``[ny + 1, nx + 1]`` points (C order) cut into two triangles per quad.

    Parameters
    ----------
    surface : GraphSurface
        The graph surface (its ``shape``, ``dx``, ``dy`` and ``height``).
    warp_scale : float, optional
        The factor on the heights; default 1 (0 draws the flat parameter domain).

    Returns
    -------
    vertices : ndarray
        float64, shape ``((ny + 1)(nx + 1), 3)``.
    faces : ndarray
        int64, shape ``(2 ny nx, 3)``: vertex indices of each triangle.
    """
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
    surface: GraphSurface,
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
    surface ``z = warp_scale · h`` of the `GraphSurface` ``surface``:
    the field as point data of `surface_mesh`, rendered as a mesh is
    (`render_mesh`: pyvista, off-screen in a child process, smooth shading).
    ``camera`` as in `render_mesh`; ``vmin``/``vmax`` fix the colour scale.  The
    earlier order ``(surface, field, path)`` works, deprecated.

    Parameters
    ----------
    path : str or os.PathLike
        The PNG file; a missing folder is created, an existing regular file replaced.
    field : array
        ``[ny, nx]``, the surface's grid shape (a device array with ``numpy()`` is
        downloaded).
    surface : GraphSurface
        The surface.
    cmap : str, optional
        A Matplotlib colour map name; default ``"viridis"``.
    warp_scale : float, optional
        The factor on the heights (finite); default 1.
    camera : str, sequence or dict, optional
        As `render_mesh` takes it; default None (the isometric view).
    vmin, vmax : float, optional
        The colour range; default None (the field's finite range; a field uniform to
        round-off is drawn in one flat colour).
    window_size : tuple of int, optional
        ``(width, height)`` in pixels; default ``(800, 800)``.
    background : str, optional
        The background colour; default ``"white"``.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    TypeError
        ``path`` is not a ``str`` or ``os.PathLike``, or ``surface`` is not a
        `GraphSurface`.
    ValueError
        ``path`` cannot be written, a field not of the surface's shape, or a
        ``warp_scale`` that is not finite.
    MissingExtraError
        pyvista or imageio is not installed.
    RuntimeError
        The rendering failed (a camera dict with other keys included).
    """
    if earlier_order("render_surface", path, "render_surface(path, field, surface)"):
        path, surface = surface, path
    path = check_writable(path, "the picture")

    if not (is_domain(surface) and surface.kind == "graph-surface"):
        raise TypeError(f"render_surface draws on an rdgpu.domains.graph_surface.GraphSurface, "
                        f"got {type(surface).__name__}")
    f = np.asarray(field.numpy() if hasattr(field, "numpy") else field, dtype=np.float64)
    if f.shape != surface.shape:
        raise ValueError(f"the field has shape {f.shape}; the surface's grid is "
                         f"{surface.shape}")
    scale = float(warp_scale)
    if not math.isfinite(scale):
        raise ValueError(f"warp_scale must be a finite number, got {warp_scale!r}")
    f, vmin, vmax = flat_field(f, vmin, vmax)
    options = render_options(f, cmap=cmap, camera=camera, vmin=vmin, vmax=vmax,
                              window_size=window_size, background=background)
    vertices, faces = surface_mesh(surface, scale)
    arrays = {"vertices": vertices, "faces": faces, "frames": _wrap_closed(f).reshape(1, -1)}
    return write_image(path, render_offscreen(arrays, {**options, "kind": "mesh"})[0])
