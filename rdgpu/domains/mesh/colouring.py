"""Greedy (Jones-Plassmann) colouring of a sparse matrix's graph: the colours of
multicolour SOR (`rdgpu.domains.mesh.SurfaceMesh.colouring`, implicit solves)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from rdgpu.core.csr import checked_csr

__all__ = ["greedy_colouring"]


def greedy_colouring(
    matrix: sp.spmatrix | sp.sparray, *, seed: int = 0, symmetric: bool = False
) -> np.ndarray:
    """Greedy colouring of the sparsity graph of a square sparse matrix.

    Vertices ``i != j`` are adjacent when entry ``(i, j)`` or ``(j, i)`` is *stored* (explicit
    zeros count; the diagonal is ignored). Returns an ``int32`` array of colours ``0..c-1``
    such that adjacent vertices never share a colour, so in multicolour Gauss-Seidel/SOR the
    rows of one colour can be updated in parallel.

    Jones-Plassmann rounds with random priorities (``seed``): in each round every uncoloured
    vertex whose priority beats all its uncoloured neighbours takes the smallest colour not
    used by its coloured neighbours. The result is a greedy colouring in priority order, so
    vertex ``i`` gets a colour ``<= degree(i)`` and at most ``max degree + 1`` colours are
    used. Fully vectorised; about O(log n) rounds. Pass ``symmetric=True`` when the pattern
    is known to be symmetric to skip symmetrisation.
    """
    M = checked_csr(matrix, "matrix", values=False)  # indices in range before they are used
    if M.shape[0] != M.shape[1]:
        raise ValueError(f"greedy_colouring needs a square matrix, got shape {M.shape}")
    n = M.shape[0]
    if n == 0:
        return np.zeros(0, dtype=np.int32)
    P = sp.csr_matrix((np.ones(M.nnz, dtype=np.int8), M.indices, M.indptr), shape=M.shape)
    if not symmetric:
        P = sp.csr_matrix(P + P.T)
    P.sum_duplicates()
    indptr = P.indptr.astype(np.int64)
    indices = P.indices.astype(np.int64)
    src = np.repeat(np.arange(n, dtype=np.int64), np.diff(indptr))
    off = src != indices
    src, dst = src[off], indices[off]

    rng = np.random.default_rng(seed)
    prio = rng.permutation(n).astype(np.int64)
    colour = np.full(n, -1, dtype=np.int32)
    uncoloured = np.arange(n, dtype=np.int64)
    a_src, a_dst = src, dst  # directed edges between uncoloured vertices, sorted by src
    nbmax = np.empty(n, dtype=np.int64)
    while uncoloured.size:
        nbmax[uncoloured] = -1
        if a_src.size:
            starts = np.flatnonzero(np.r_[True, a_src[1:] != a_src[:-1]])
            nbmax[a_src[starts]] = np.maximum.reduceat(prio[a_dst], starts)
        win = uncoloured[prio[uncoloured] > nbmax[uncoloured]]
        colour[win] = _smallest_free_colour(win, indptr, indices, colour)
        uncoloured = uncoloured[colour[uncoloured] < 0]
        if a_src.size:
            keep = (colour[a_src] < 0) & (colour[a_dst] < 0)
            a_src, a_dst = a_src[keep], a_dst[keep]
    return colour


def _smallest_free_colour(
    win: np.ndarray, indptr: np.ndarray, indices: np.ndarray, colour: np.ndarray
) -> np.ndarray:
    """For each vertex in ``win``, the smallest colour not taken by a coloured neighbour."""
    k = win.size
    out = np.zeros(k, dtype=np.int32)
    if k == 0:
        return out
    starts = indptr[win]
    counts = indptr[win + 1] - starts
    total = int(counts.sum())
    if total == 0:
        return out
    owner = np.repeat(np.arange(k, dtype=np.int64), counts)
    seg0 = np.cumsum(counts) - counts
    pos = np.arange(total, dtype=np.int64) - np.repeat(seg0 - starts, counts)
    c = colour[indices[pos]].astype(np.int64)
    taken = c >= 0
    if not taken.any():
        return out
    base = int(c.max()) + 2
    keys = np.unique(owner[taken] * base + c[taken])  # sorted, distinct (owner, colour)
    o = keys // base
    cc = keys % base
    first = np.flatnonzero(np.r_[True, o[1:] != o[:-1]])
    seglen = np.diff(np.r_[first, keys.size])
    rank = np.arange(keys.size) - np.repeat(first, seglen)
    cand = np.where(cc != rank, rank, np.repeat(seglen, seglen))
    out[o[first]] = np.minimum.reduceat(cand, first)
    return out
