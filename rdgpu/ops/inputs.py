"""The input checks of the functional API (`rdgpu.ops.api`): fields of any array kind,
per-cell parameters, meshes, grids, SOR and level-set problems.

Every check runs before any work: a field's kind, dtype, rank and size first -- the
backend's cell limit and the shared memory estimate (`rdgpu.core.validation.check_size`)
-- and its values only then, in place (`rdgpu.core.validation`), so that a request too
large is refused before anything is read, copied or uploaded.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.backends import interop
from rdgpu.backends.base import Backend, DeviceArray
from rdgpu.core import validation as check
from rdgpu.domains.base import is_domain
from rdgpu.domains.boundary import PERIODIC
from rdgpu.domains.grid import Grid

if TYPE_CHECKING:
    from rdgpu.domains.mesh.surface_mesh import SurfaceMesh


class _Unread(np.ndarray):
    """A zero-strided stand-in of the shape and dtype of an array that stays on its device
    (its values are not read: that would be the copy the caller avoids; `on_backend` checks
    them there); ``what`` is the argument's name."""

    what = "the array"

    def __array_finalize__(self, obj: Any) -> None:  # views keep the name
        self.what = getattr(obj, "what", "the array")


def host_field(u: Any, name: str, ndim: tuple[int, ...], be: Backend | None) -> np.ndarray:
    """``check.as_field`` for an array of any kind: read in place where the host can (one
    copy for a device array elsewhere); an array resident on ``be`` that the host cannot
    see is checked for dtype, rank and size only, and given as an `_Unread`.  The
    size (``be``'s cell limit, the memory estimate) is checked before any value is read
    or copied."""
    try:
        kind = interop.kind_of(u)
    except interop.NotAnArray:
        return check.as_field(u, name, ndim=ndim)  # its message: what is allowed
    except TypeError as exc:
        raise TypeError(f"{name}: {exc}") from None
    if kind == "list" and not isinstance(u, (list, tuple)):
        check.not_masked(u, name)
        u = np.asarray(u)
    if kind in ("numpy", "list"):
        return check.as_field(u, name, ndim=ndim, backend=be)
    shape, dtype = interop.shape_dtype(u)
    if dtype not in check.DTYPES:
        raise TypeError(f"{name} has unsupported dtype {dtype}; allowed: float32, float64")
    if len(shape) not in ndim:
        allowed = " or ".join(f"{d}-D" for d in ndim)
        raise ValueError(f"{name} must be {allowed}, got shape {shape}")
    if 0 in shape:
        raise ValueError(f"{name} is empty (shape {shape}); every axis needs a cell")
    view = interop.host_view(u)
    if view is None and be is not None and interop.resident(u, be):
        check.check_size(shape, dtype, name, backend=be, memory=False)  # already there
        unread = np.broadcast_to(np.zeros((), dtype), shape).view(_Unread)
        unread.what = name
        return unread
    check.check_size(shape, dtype, name, backend=be)  # before the copy to the host
    return check.as_field(view if view is not None else interop.to_numpy(u), name, ndim=ndim,
                          backend=be)


def on_backend(be: Backend, given: Any, field: np.ndarray) -> DeviceArray:
    """The checked ``field`` of the caller's ``given`` array on ``be``: ``given``'s own
    memory where it lives there and the checks made no copy, else one upload.  An
    `_Unread` array (resident on ``be``, unseen by the host) is checked for NaN and
    Inf here, by one reduction on the device."""
    unread = isinstance(field, _Unread)
    d = interop.to_device(given, None if unread else field, be, field.shape)
    if unread and not math.isfinite(be.max_abs(d)):
        raise ValueError(f"{field.what} contains NaN or Inf value(s); all values must be "
                         "finite")
    return d


def given_shape(x: Any) -> tuple[int, ...]:
    """The shape of the caller's array of any kind (a list's as NumPy reads it)."""
    return interop.shape_dtype(x)[0] if interop.is_array(x) else np.shape(x)


def param_value(x: Any, name: str, like: np.ndarray) -> float | np.ndarray:
    """``check.scalar_or_field`` for a number or an array of any kind (read on the host,
    after its size is found to be ``like``'s: no copy of a device array of another size)."""
    if interop.is_array(x) and not isinstance(x, np.ndarray):
        shape = interop.shape_dtype(x)[0]
        if shape and math.prod(shape) != like.size:
            raise ValueError(f"{name} has shape {shape}; it must be a scalar or match "
                             f"{like.shape}")
        x = interop.to_numpy(x)
    return check.scalar_or_field(x, name, like)


def _check_mesh(mesh: SurfaceMesh | None) -> Any:
    if not (is_domain(mesh) and mesh.unstructured):
        raise TypeError(f"mesh must be an rdgpu.SurfaceMesh, got {type(mesh).__name__}")
    return mesh


def mesh_field(u: Any, mesh: SurfaceMesh | None, name: str,
               be: Backend | None = None) -> np.ndarray:
    """A per-vertex field of ``mesh``: 1-D, ``n_vertices`` long, float32/float64, finite
    (``be``: see `host_field`)."""
    n = _check_mesh(mesh).n_vertices
    shape = given_shape(u)
    if len(shape) != 1 or shape[0] != n:
        raise ValueError(
            f"{name} has shape {shape}; on a mesh of {n} vertices it must be a 1-D array of "
            f"{n} values (one per vertex, in the order of mesh.vertices)"
        )
    return host_field(u, name, (1,), be)


def no_grid_args(dx: Any, dy: Any, bc: Any, stencil: int = 5) -> None:
    """With ``mesh=``, the grid arguments must keep their defaults."""
    given = [name for name, value, default in (("dx", dx, 1.0), ("dy", dy, None),
                                               ("bc", bc, "periodic"), ("stencil", stencil, 5))
             if not (value is default or (isinstance(value, (int, float, str))
                                         and not isinstance(value, bool) and value == default))]
    if given:
        raise ValueError(
            f"{', '.join(given)} given together with mesh=: a mesh carries its own geometry "
            "(its boundary, if open, is zero-flux), so the grid arguments dx, dy, bc and "
            "stencil do not apply"
        )


def grid_problem(u: Any, name: str, dx: Any, dy: Any, bc: Any,
                  be: Backend | None = None) -> tuple[np.ndarray, Grid]:
    """``(field [ny, nx], Grid)`` of a 1-D ``u[nx]`` or 2-D ``u[ny, nx]`` grid field
    (``be``: see `host_field`)."""
    field = host_field(u, name, (1, 2), be)
    dx, dy = check.spacing(dx, dy)
    if field.ndim == 1:
        if dy != dx:
            raise ValueError(f"dy={dy} given for the 1-D array {name}: a 1-D problem has only "
                             "the x axis (spacing dx); leave dy out")
        grid = Grid(field.shape, dx=dx, bc=bc)
    else:
        grid = Grid(field.shape, dx=dx, dy=dy, bc=bc)
    check.spacing_fits(grid.dx, grid.dy, field.dtype)
    return field.reshape(grid.shape), grid


def grid_or_mesh(u: Any, mesh: SurfaceMesh | None, dx: Any, dy: Any, bc: Any, name: str = "u",
                  be: Backend | None = None):
    """``(field, domain)``: a per-vertex field and the mesh, or a grid field and its Grid."""
    if mesh is not None:
        no_grid_args(dx, dy, bc)
        return mesh_field(u, mesh, name, be), mesh
    return grid_problem(u, name, dx, dy, bc, be)


def sor_inputs(c, fixed, omega, rhs, dx, dy, bc, be=None):
    """Checked SOR inputs: ``(c [ny, nx], mask uint8, omega, rhs or None, dx, dy, bcs)``."""
    grid, domain = grid_problem(c, "c", dx, dy, bc, be)
    check.not_masked(fixed, "fixed")
    if isinstance(fixed, (list, tuple)) or interop.is_array(fixed):
        fixed = interop.to_numpy(fixed)
    if not isinstance(fixed, np.ndarray):
        raise TypeError(f"fixed must be a NumPy boolean (or integer) mask, got "
                        f"{type(fixed).__name__}")
    if fixed.dtype != bool and fixed.dtype.kind not in "iu":
        raise TypeError(f"fixed must be a boolean mask (or integers, non-zero = fixed), got "
                        f"dtype {fixed.dtype}")
    if fixed.shape != given_shape(c):
        raise ValueError(f"fixed has shape {fixed.shape} but c has shape {given_shape(c)}; "
                         "they must match")
    mask = np.ascontiguousarray((fixed != 0).reshape(grid.shape), dtype=np.uint8)
    omega = check.scalar(omega, "omega", minimum=None)
    if not 0.0 < omega < 2.0:
        raise ValueError(f"omega must lie in the open interval (0, 2), got {omega}")
    f = None
    if rhs is not None:
        f = host_field(rhs, "rhs", (1, 2), None)
        if f.shape != given_shape(c):
            raise ValueError(f"rhs has shape {f.shape} but c has shape {given_shape(c)}; "
                             "they must match")
        f = np.ascontiguousarray(f.reshape(grid.shape).astype(grid.dtype, copy=False))
    bcs = domain.bcs
    axes = (("x", grid.shape[1], bcs.x),) if domain.ndim == 1 else (
        ("y", grid.shape[0], bcs.y), ("x", grid.shape[1], bcs.x))
    for name, n, axis_bc in axes:
        if axis_bc.kind == PERIODIC and n % 2 == 1:
            raise ValueError(
                f"red-black SOR needs an even size along a periodic axis, but the {name} axis "
                f"has {n} cells; use an even size or a 'neumann'/('dirichlet', g) boundary on "
                "that axis"
            )
    return grid, mask, omega, f, domain.dx, domain.dy, domain.bcs


def levelset_problem(phi: Any, dx: Any, dy: Any, dz: Any, bc: Any,
                      be: Backend | None = None) -> tuple[np.ndarray, Grid]:
    """``(field, Grid)`` of a 1-D, 2-D or (with ``dz``, default ``dx``) 3-D level-set field."""
    field = host_field(phi, "phi", (1, 2, 3), be)
    if field.ndim < 3:
        if dz is not None:
            raise ValueError(f"dz={dz!r} given for a {field.ndim}-D phi of shape {field.shape}: "
                             "only a 3-D phi [nz, ny, nx] has a z axis; leave dz out")
        return grid_problem(field, "phi", dx, dy, bc)
    dx, dy = check.spacing(dx, dy)
    grid = Grid(field.shape, dx=dx, dy=dy, dz=dz, bc=bc)
    check.spacing_fits(grid.dx, grid.dy, field.dtype)
    check.spacing_fits(grid.dz, grid.dz, field.dtype)
    return field, grid
