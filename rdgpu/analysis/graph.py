"""The domain as the pattern measures see it, asked through the Domain protocol
(`rdgpu.domains.base`): a field as a float64 array, which grid axes wrap, and the
neighbour pairs of the domain's graph.  ``domain=None`` stands for a non-periodic grid of
the field's own shape."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain


def as_array(field: Any) -> np.ndarray:
    """``field`` (an array, or a device array with ``numpy()``) as a float64 array."""
    return np.asarray(field.numpy() if hasattr(field, "numpy") else field, dtype=np.float64)


def is_grid(domain: Domain | None) -> bool:
    """Whether fields on ``domain`` are grid arrays (a grid, a graph surface, or None)."""
    return domain is None or not domain.unstructured


def periodic_xy(domain: Domain | None) -> tuple[bool, bool]:
    """Whether the x (columns) and y (rows) axes of a grid wrap: from the boundary
    conditions of its description, one per axis of its field shape (a 1-D grid has no y
    axis: ``False``)."""
    if domain is None:
        return False, False
    bc = domain.describe()["bc"]
    return bc[-1] == "periodic", len(bc) >= 2 and bc[-2] == "periodic"


def graph_edges(domain: Domain | None, shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Neighbour pairs of the domain's graph: 4-neighbours on a grid (wrapped along
    periodic axes), the edges of a mesh."""
    if not is_grid(domain):
        edges = np.asarray(domain.edges)
        return edges[:, 0], edges[:, 1]
    if len(shape) == 1:
        shape = (1, shape[0])
    ny, nx = shape
    idx = np.arange(ny * nx).reshape(ny, nx)
    px, py = periodic_xy(domain)
    a = [idx[:, :-1].ravel(), idx[:-1, :].ravel()]
    b = [idx[:, 1:].ravel(), idx[1:, :].ravel()]
    if px and nx > 2:
        a.append(idx[:, -1])
        b.append(idx[:, 0])
    if py and ny > 2:
        a.append(idx[-1, :])
        b.append(idx[0, :])
    return np.concatenate(a), np.concatenate(b)
