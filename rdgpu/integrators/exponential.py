"""Exponential time differencing: ``method="etdrk4"`` of the model layer (issue 22).

Each species' right-hand side splits as ``f_s = L_s s + N_s(x, t)``: ``L_s = α_s Δ + β_s Δ²
+ γ_s`` its own linear spatial part with constant coefficients (the split of the IMEX
schemes, `rdgpu.integrators.ModelStepper`) and its own linear damping ``γ_s s`` with a
constant ``γ_s < 0`` (`split_damping`), ``N_s`` everything else (reactions, other species'
Laplacians, the constant a non-zero Dirichlet value adds).  On a rectangular grid whose
axes are periodic, Neumann or Dirichlet, rdgpu's discrete Laplacian ``M`` is diagonal in
the transform of each axis (`rdgpu.ops.transforms`: FFT, DCT-II, DST-I) with eigenvalues
``λ``, so ``L_s`` is diagonal there too, ``L̂ = α λ + β λ² + γ``, exactly for the discrete system
the explicit methods step (no spectral/discrete mismatch).

ETDRK4 (Cox & Matthews 2002, J. Comput. Phys. 176, 430), per mode with ``z = h L̂``::

    â  = E₂ û + Q N̂(u, t)
    b̂  = E₂ û + Q N̂(a, t + h/2)
    ĉ  = E₂ â + Q (2 N̂(b, t + h/2) − N̂(u, t))
    û' = E û + f₁ N̂(u, t) + 2 f₂ (N̂(a, t + h/2) + N̂(b, t + h/2)) + f₃ N̂(c, t + h)

with ``E = e^z``, ``E₂ = e^{z/2}``, ``Q = (h/2) φ₁(z/2)`` and (Kassam & Trefethen 2005,
SIAM J. Sci. Comput. 26, 1214)::

    f₁ = h (−4 − z + e^z (4 − 3z + z²)) / z³ = h (φ₁ − 3φ₂ + 4φ₃)
    f₂ = h (2 + z + e^z (z − 2)) / z³        = h (φ₂ − 2φ₃)
    f₃ = h (−4 − 3z − z² + e^z (4 − z)) / z³ = h (−φ₂ + 4φ₃)

``φ₁(w) = (e^w − 1)/w`` and so on.  The closed forms cancel catastrophically as ``z → 0``
(Kassam and Trefethen's reason for their contour integral); here they are evaluated in
``numpy.longdouble`` for ``|z| >= 1`` and by their Taylor series ``f₁/h = Σ (j+1)² z^j/(j+3)!``,
``f₂/h = Σ (j+1) z^j/(j+3)!``, ``f₃/h = Σ (1−j) z^j/(j+3)!`` (no cancellation between
coefficients) for ``|z| < 1``, then rounded to float64 once per ``(h, mode)`` and cached;
the steps use them rounded to the working dtype.  (Where ``longdouble`` is ``double``, as
on Windows, the closed forms just above ``|z| = 1`` lose about two digits.)

Per step the device evaluates ``N`` four times, one fused program per stage (bilaplacians
in ``N`` lowered as in the explicit methods); everything else runs on the host: downloads,
the transforms of the direct implicit solves (`rdgpu.ops.transforms.TransformSolver`:
five forward and four inverse per species) and the linear combinations in the working
dtype, one upload per stage.  The spectra live in work arrays kept from step to step (the
transforms write into them; each product is formed as soon as its operands are known,
while they are in the cache), and the coefficients of the step are set up with the
stepper, each distinct symbol once (where a 256² step's time goes:
perf/results/etdrk4_goal.md).  A linear model (``N = 0``) is advanced exactly: ``û' =
e^{hL̂} û`` at any ``h``.  The model's bounds are applied to the new state.  Ensembles are
transformed member by member.  Symmetry: as in the direct implicit solves, an axis along
which ``u`` and ``N(u)`` are bit for bit constant (periodic or Neumann) is not
transformed, so a y-independent field stays y-independent bit for bit.

The first step of a run (taken at ``steps_done == 0``: a new stepper, or ``set_state(...,
steps=0)``) is graded: ETDRK4 substeps ``h/2^K, h/2^K, h/2^(K−1), ..., h/2`` (their sum
``h``), ``K`` the smallest with ``h max|L̂| / 2^K <= 1`` (at most `START_LEVELS`), so
that the smallest resolves the fastest mode.  From a rough start (white noise) the error
of Cox-Matthews' steps is made almost entirely in the first step, while the noise's high
modes relax on the time scale ``1/|L̂|`` far below ``h`` and ``N`` varies with them faster
than its polynomial interpolation in time follows (a stiff order reduction: the error
then falls only as ~h^1.5); the graded step resolves that transient, and the error of
Swift-Hohenberg from white noise at ~100× the explicit limit falls ~50× (64², T = 100:
1.5e-4 against 8.9e-3).  Later steps, and a run resumed with ``steps > 0``, are plain
ETDRK4 steps, so a resumed run is bit for bit the uninterrupted one; from a smooth start
the grading changes the error constant, not the order.

Stability: the linear part is exact, so it sets no step limit
(`rdgpu.integrators.stability.stability_limit` is ``inf``); ``N`` is explicit and limits
``h`` as the reactions do in every explicit method (cross-diffusion in ``N`` included,
which this limit does not check).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.backends.base import Backend, DeviceArray
from rdgpu.ir import equations as eq
from rdgpu.ops.implicit import operator_matrix
from rdgpu.ops.transforms import TransformSolver, grid_axes, transform_unavailable

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain

__all__ = ["SERIES_RADIUS", "START_LEVELS", "Etdrk4", "etdrk4_coefficients",
           "split_damping"]

#: below this ``|z|`` the coefficients come from their Taylor series (module doc)
SERIES_RADIUS = 1.0
#: the most halvings of a run's first step (`Etdrk4.start_steps`)
START_LEVELS = 16
#: Taylor terms: ``|z|^j/(j+3)!`` is below longdouble's round-off for ``|z| < 1`` by then
_TERMS = 24


def etdrk4_coefficients(lin: np.ndarray, h: float) -> dict[str, np.ndarray]:
    """The ETDRK4 coefficients (module doc) of the linear symbols ``lin`` over a step.

    Parameters
    ----------
    lin : numpy.ndarray
        ``L̂`` per mode (real, any shape; units 1/time).
    h : float
        The step (time units).

    Returns
    -------
    dict of str to numpy.ndarray
        float64 arrays of ``lin``'s shape: ``"E"`` (``e^{hL̂}``), ``"E2"`` (``e^{hL̂/2}``),
        ``"Q"`` (``(E₂ − 1)/L̂``), ``"f1"``, ``"f2"``, ``"f3"`` (each including its factor
        ``h``).  ``L̂ = 0`` gives their limits ``1, 1, h/2, h/6, h/6, h/6``.
    """
    lin = np.asarray(lin, dtype=np.float64)
    # each distinct value once (a grid's symbols repeat: on a square periodic grid ~8x)
    values, where = np.unique(lin, return_inverse=True)
    if values.size < lin.size:
        return {k: v[where].reshape(lin.shape)
                for k, v in etdrk4_coefficients(values, h).items()}
    ld = np.longdouble
    z = lin.astype(ld) * ld(h)
    small = np.abs(z) < SERIES_RADIUS
    f = [np.empty(z.shape, dtype=ld) for _ in range(3)]
    zb = z[~small]  # the closed forms
    with np.errstate(over="ignore", invalid="ignore"):
        ez, zb3 = np.exp(zb), zb ** 3
        f[0][~small] = (-4.0 - zb + ez * (4.0 - 3.0 * zb + zb * zb)) / zb3
        f[1][~small] = (2.0 + zb + ez * (zb - 2.0)) / zb3
        f[2][~small] = (-4.0 - 3.0 * zb - zb * zb + ez * (4.0 - zb)) / zb3
    zs = z[small]  # the series, by Horner from the smallest term
    series = [np.zeros_like(zs) for _ in range(3)]
    for j in reversed(range(_TERMS)):
        d = ld(math.factorial(j + 3))
        for acc, c in zip(series, ((j + 1) ** 2, j + 1, 1 - j), strict=True):
            acc *= zs
            acc += ld(c) / d
    for fi, si in zip(f, series, strict=True):
        fi[small] = si
        fi *= ld(h)
    half = z / 2.0
    phi1 = np.ones(z.shape, dtype=ld)
    nz = half != 0.0
    phi1[nz] = np.expm1(half[nz]) / half[nz]
    with np.errstate(over="ignore"):
        out = {"E": np.exp(z), "E2": np.exp(half), "Q": phi1 * ld(h / 2.0),
               "f1": f[0], "f2": f[1], "f3": f[2]}
    return {k: np.asarray(v, dtype=np.float64) for k, v in out.items()}


def split_damping(rest: eq.Node | None, s: str,
                  constants: Mapping[str, float | None]) -> tuple[float, eq.Node | None]:
    """``(γ, rest')`` with ``rest = γ s + rest'``: the terms ``c·s`` of the top-level sum
    ``rest`` (``c`` made of numbers and parameters that are numbers in ``constants``) when
    their total ``γ`` is negative, else ``(0, rest)``.

    A damping ``γ < 0`` joins the exact linear part: Swift-Hohenberg's ``(r − 1)u`` then
    leaves ``N = −u³``, small where ``u`` is, so the error from a smooth start shrinks (10×
    on Swift-Hohenberg, 64², h = 0.4) and the step the explicit ``N`` allows grows (its
    Jacobian ``−3u²`` instead of ``r − 1 − 3u²``).  A growth ``γ > 0``
    (Allen-Cahn's ``u − u³``) stays in ``N``, where it offsets the cubic's damping in the
    explicit stages (Kassam and Trefethen's choice too).
    """
    if rest is None:
        return 0.0, None
    gamma, kept = 0.0, []
    for sign, term in _signed_terms(rest, 1):
        c = _species_factor(term, s)
        value = None
        if c is not None and all(constants.get(p) is not None for p in eq.names(c, "param")):
            value = float(eq.evaluate(c, {p: constants[p] for p in eq.names(c, "param")}))
        if value is None or not math.isfinite(value):
            kept.append((sign, term))
        else:
            gamma += sign * value
    if not gamma < 0.0:
        return 0.0, rest
    out: eq.Node | None = None
    for sign, term in kept:
        if out is None:
            out = term if sign > 0 else eq.Neg(term)
        else:
            out = eq.Bin("+" if sign > 0 else "-", out, term)
    return gamma, out


def _signed_terms(node: eq.Node, sign: int) -> list[tuple[int, eq.Node]]:
    """The terms of a top-level sum with their signs."""
    if isinstance(node, eq.Bin) and node.op in "+-":
        return _signed_terms(node.a, sign) + _signed_terms(node.b,
                                                           sign if node.op == "+" else -sign)
    if isinstance(node, eq.Neg):
        return _signed_terms(node.a, -sign)
    return [(sign, node)]


def _species_factor(term: eq.Node, s: str) -> eq.Node | None:
    """``c`` where ``term`` is ``c·s`` (products and quotients with parameters and
    numbers around one ``s`` in the numerator), else None."""
    if isinstance(term, eq.Ref) and term.kind == "species" and term.name == s:
        return eq.Num(1.0)
    if isinstance(term, eq.Neg):
        inner = _species_factor(term.a, s)
        return None if inner is None else eq.Neg(inner)
    if isinstance(term, eq.Bin) and term.op in "*/":
        if term.op == "*" and eq.is_constant(term.a):
            inner = _species_factor(term.b, s)
            return None if inner is None else eq.Bin("*", term.a, inner)
        if eq.is_constant(term.b):
            inner = _species_factor(term.a, s)
            return None if inner is None else eq.Bin(term.op, inner, term.b)
    return None


class Etdrk4:
    """One ETDRK4 step of a model's fields (module doc).

    Parameters
    ----------
    domain : Grid
        A rectangular grid with periodic, Neumann or Dirichlet axes; anything else is a
        ``ValueError`` naming the method.
    shape : tuple of int
        The fields' device shape (``[members, *kernel_shape]`` for an ensemble).
    members : int or None
        The ensemble's members (None: one field per species).
    dt : float
        The step (time units).
    dtype : numpy.dtype
        The working dtype.
    backend : Backend
        Where the fields live.
    linear : mapping of str to (float, float, float)
        Per species ``(α, β, γ)`` of its own linear part ``α Δs + β Δ²s + γ s``, in
        species order.
    bounds : mapping of str to (float or None, float or None)
        The model's bounds per species (``(None, None)``: none).
    rates : callable
        ``rates(inputs, outputs, t)`` writes ``N_s`` of the fields ``inputs`` at time ``t``
        into ``outputs`` (device arrays, species order): the fused program of the stepper.
    method : str
        The method's name, for messages.
    """

    def __init__(self, domain: Domain, shape: Sequence[int], members: int | None, dt: float,
                 dtype: Any, backend: Backend,
                 linear: Mapping[str, tuple[float, float, float]],
                 bounds: Mapping[str, tuple[float | None, float | None]],
                 rates: Callable[[list[DeviceArray], list[DeviceArray], float], None],
                 method: str = "etdrk4"):
        why = transform_unavailable(domain)
        if why is not None:
            if getattr(domain, "kind", None) != "grid":
                why = f"the domain is a {domain.label}"
            raise ValueError(f"method {method!r} integrates the linear part exactly by fast "
                             "transforms, on rectangular grids only (periodic, Neumann or "
                             f"Dirichlet axes); {why}; use 'imex' (SOR on meshes and graph "
                             "surfaces) or an explicit method")
        self.species = tuple(linear)
        self.shape = tuple(shape)
        self.members = members
        self.dt = float(dt)
        self.dtype = np.dtype(dtype)
        self.backend = backend
        self.linear = {s: tuple(map(float, abc)) for s, abc in linear.items()}
        self.bounds = {s: tuple(bounds.get(s, (None, None))) for s in self.species}
        self.rates = rates
        self.transforms = TransformSolver(grid_axes(domain), dtype=self.dtype)
        self.axes = self.transforms.axes
        self._one = self.transforms.shape  # one member's kernel shape
        self._members = 1 if members is None else int(members)
        self._works: dict[tuple[bool, ...], tuple[list, list]] = {}
        self._n = [backend.empty(self.shape, self.dtype) for _ in self.species]
        self._coefficients: dict[tuple, dict[str, np.ndarray]] = {}
        self.constants = self._dirichlet_constants(domain)
        for s in self.species:  # the step's coefficients: set up here, not in a step
            self.coefficients((True,) * len(self.axes), s)

    # ------------------------------------------------------------------ setup
    def _dirichlet_constants(self, domain: Domain) -> dict[str, np.ndarray | None]:
        """Per species the constant part of ``L_s`` a non-zero Dirichlet value leaves,
        ``α b + β M b`` (``L u = M u + b``; the bilaplacian's outer Laplacian has ghost 0),
        in the working dtype, or None."""
        M, b = operator_matrix(domain)
        b = np.asarray(b, dtype=np.float64).ravel()
        if not np.any(b != 0.0):
            return {s: None for s in self.species}
        Mb = M @ b
        out: dict[str, np.ndarray | None] = {}
        for s, (alpha, beta, _) in self.linear.items():
            c = alpha * b + beta * Mb
            out[s] = c.reshape(self._one).astype(self.dtype) if np.any(c != 0.0) else None
        return out

    def coefficients(self, kept: tuple[bool, ...], s: str,
                     h: float | None = None) -> dict[str, np.ndarray]:
        """Species ``s``'s coefficients for the step ``h`` (default: ``dt``) on the
        coefficients' grid of ``kept`` (the axes transformed), in the working dtype,
        cached."""
        h = self.dt if h is None else float(h)
        alpha, beta, gamma = self.linear[s]
        key = (kept, alpha, beta, gamma, h)
        got = self._coefficients.get(key)
        if got is None:
            lam = self.transforms.spectrum(kept)
            table = etdrk4_coefficients(gamma + alpha * lam + beta * lam * lam, h)
            table["2f2"] = 2.0 * table["f2"]
            kind = self.transforms.coefficient_dtype(kept)
            got = {k: v.astype(self.dtype).astype(kind) for k, v in table.items()}
            if len(self._coefficients) > 64:
                self._coefficients.clear()
            self._coefficients[key] = got
        return got

    def start_steps(self) -> list[float]:
        """The substeps of a run's first step (module doc): ``[h/2^K, h/2^K, h/2^(K−1),
        ..., h/2]`` (sum ``h``), ``K`` the smallest with ``h max|L̂| / 2^K <= 1`` (at most
        `START_LEVELS`); ``[h]`` where the fastest mode is resolved already."""
        lam = self.transforms.spectrum((True,) * len(self.axes))
        fastest = max(float(np.max(np.abs(c + a * lam + b * lam * lam)))
                      for a, b, c in self.linear.values())
        levels = 0
        while levels < START_LEVELS and self.dt * fastest / 2.0**levels > 1.0:
            levels += 1
        if levels == 0:
            return [self.dt]
        return [self.dt / 2.0**levels] + [self.dt / 2.0**k for k in range(levels, 0, -1)]

    # ------------------------------------------------------------------ transforms
    def _batch(self, a: np.ndarray) -> np.ndarray:
        """``a`` as ``[members, *kernel_shape]`` (one member when not an ensemble)."""
        return a.reshape((-1, *self._one))

    def kept_axes(self, fields: Sequence[np.ndarray]) -> tuple[bool, ...]:
        """Per axis whether it is transformed: not a periodic or Neumann axis along which
        every batch of ``fields`` is bit for bit constant (module doc: symmetry)."""
        return self.transforms.constant_axes(fields, batched=True)

    def _work(self, kept: tuple[bool, ...]) -> tuple[list[dict[str, np.ndarray]],
                                                     list[np.ndarray]]:
        """The work arrays of a step in the transform space of ``kept``, reused from step
        to step (`_stages`): per species seven spectra, ``U`` (``Û``, then the new
        state's), ``NU`` (``N̂(u)``), ``EU`` (``E₂ Û``, then ``N̂(b)``), ``NA`` (``N̂(a)``,
        then ``N̂(c)``), ``EA`` (``E₂ â``), ``S`` (a stage's) and ``T`` (a temporary); and
        per species a field batch (dropped axes of length 1) the inverse transforms
        write."""
        got = self._works.get(kept)
        if got is None:
            ts, m, k = self.transforms, self._members, len(self.species)
            names = ("U", "NU", "EU", "NA", "EA", "S", "T")
            spectra = ts.scratch(("etdrk4", kept), (m, *ts.spectral_shape(kept)),
                                 ts.coefficient_dtype(kept), len(names) * k)
            reduced = tuple(n if keep else 1 for n, keep in zip(self._one, kept, strict=True))
            fields = ts.scratch(("etdrk4 fields", kept), (m, *reduced), self.dtype, k)
            work = [dict(zip(names, spectra[i * len(names):(i + 1) * len(names)],
                             strict=True)) for i in range(k)]
            got = self._works[kept] = (work, fields)
        return got

    def forward(self, a: np.ndarray, kept: tuple[bool, ...],
                out: np.ndarray | None = None) -> np.ndarray:
        """The coefficients of a batch ``a`` (dropped axes of length 1), member by member
        (`rdgpu.ops.transforms.TransformSolver.forward`), into ``out`` if given."""
        a = a[(slice(None), *(slice(None) if k else slice(0, 1) for k in kept))]
        if out is None:
            out = np.empty((a.shape[0], *self.transforms.spectral_shape(kept)),
                           self.transforms.coefficient_dtype(kept))
        for m, o in zip(a, out, strict=True):
            self.transforms.forward(m, kept, out=o)
        return out

    def inverse(self, c: np.ndarray, kept: tuple[bool, ...], out: np.ndarray | None = None,
                overwrite: bool = False) -> np.ndarray:
        """The batch of the coefficients ``c`` (:meth:`forward`'s inverse; into ``out``
        if given, dropped axes of length 1; ``overwrite``: ``c`` may serve as scratch),
        broadcast to the full shape (read-only where an axis was dropped)."""
        if out is None:
            out = np.empty((c.shape[0], *(n if k else 1 for n, k in zip(self._one, kept,
                                                                           strict=True))),
                           self.dtype)
        for m, o in zip(c, out, strict=True):
            self.transforms.inverse(m, kept, out=o, overwrite=overwrite)
        return np.broadcast_to(out, (c.shape[0], *self._one))

    # ------------------------------------------------------------------ stepping
    def _evaluate(self, fields: list[DeviceArray], t: float) -> list[np.ndarray]:
        """``N`` of every species at ``fields`` and ``t``, downloaded as batches."""
        self.rates(fields, self._n, t)
        out = []
        for s, n in zip(self.species, self._n, strict=True):
            a = self._batch(n.numpy())
            if self.constants[s] is not None:
                a += self.constants[s]  # a is this call's own download
            out.append(a)
        return out

    def _upload(self, batches: list[np.ndarray]) -> list[DeviceArray]:
        be = self.backend
        return [be.upload(np.ascontiguousarray(a, dtype=self.dtype).reshape(self.shape))
                for a in batches]

    def step(self, x: list[DeviceArray], y: list[DeviceArray], t0: float,
             first: bool = False) -> None:
        """``y`` ← one step from ``x`` at time ``t0`` (module doc); ``first``: a run's
        first step, taken in the substeps of `start_steps`."""
        fields, t = x, t0
        sizes = self.start_steps() if first else [self.dt]
        for i, h in enumerate(sizes):
            u = [self._batch(f.numpy()) for f in fields]
            nu = self._evaluate(fields, t)
            kept = self.kept_axes(u + nu)
            new = self._stages(u, nu, kept, t, h)
            if new is None:  # a later stage broke a symmetry of the first: every axis
                new = self._stages(u, nu, (True,) * len(self.axes), t, h)
            for k, s in enumerate(self.species):
                lo, hi = self.bounds[s]
                if lo is not None or hi is not None:
                    new[k] = np.clip(new[k], lo, hi)
            if i < len(sizes) - 1:
                fields, t = self._upload(new), t + h
                continue
            be = self.backend
            for a, out in zip(new, y, strict=True):
                be.copy(be.upload(np.ascontiguousarray(a, dtype=self.dtype)
                                  .reshape(self.shape)), out)

    def _stages(self, u: list[np.ndarray], nu: list[np.ndarray], kept: tuple[bool, ...],
                t0: float, h: float) -> list[np.ndarray] | None:
        """The new fields (batches, views of work arrays) of a step ``h`` in the transform
        space of ``kept``, or None when a stage's ``N`` varies along an axis ``kept``
        drops.

        Every product and sum is the module doc's, in its order, into the work arrays
        (`_work`), each as soon as its operands are known (while they are in the cache):
        ``û' = ((E Û + f₁ N̂(u)) + 2f₂ (N̂(a) + N̂(b))) + f₃ N̂(c)`` is summed in ``U`` over
        the stages, and ``E₂ Û`` serves both ``â`` and ``b̂``."""
        co = [self.coefficients(kept, s, h) for s in self.species]
        work, fields = self._work(kept)
        mul = np.multiply
        for a, na, w, c in zip(u, nu, work, co, strict=True):
            acc, tmp = w["U"], w["T"]
            self.forward(a, kept, out=acc)
            mul(c["E2"], acc, out=w["EU"])
            with np.errstate(over="ignore", invalid="ignore"):
                acc *= c["E"]  # Û is not needed further
            self.forward(na, kept, out=w["NU"])
            mul(c["Q"], w["NU"], out=w["S"])  # â = E₂ Û + Q N̂(u)
            w["S"] += w["EU"]
            mul(c["E2"], w["S"], out=w["EA"])
            with np.errstate(over="ignore", invalid="ignore"):
                mul(c["f1"], w["NU"], out=tmp)
                acc += tmp
        if not self._stage_rates(work, fields, kept, t0 + 0.5 * h, "NA"):
            return None
        for w, c in zip(work, co, strict=True):  # b̂ = E₂ Û + Q N̂(a)
            mul(c["Q"], w["NA"], out=w["S"])
            w["S"] += w["EU"]
        if not self._stage_rates(work, fields, kept, t0 + 0.5 * h, "EU"):  # N̂(b)
            return None
        for w, c in zip(work, co, strict=True):
            nb, tmp = w["EU"], w["T"]
            with np.errstate(over="ignore", invalid="ignore"):
                np.add(w["NA"], nb, out=tmp)
                tmp *= c["2f2"]
                w["U"] += tmp
            mul(nb, 2, out=tmp)  # ĉ = E₂ â + Q (2 N̂(b) − N̂(u))
            tmp -= w["NU"]
            mul(c["Q"], tmp, out=w["S"])
            w["S"] += w["EA"]
        if not self._stage_rates(work, fields, kept, t0 + h, "NA"):  # N̂(c)
            return None
        with np.errstate(over="ignore", invalid="ignore"):
            for w, c in zip(work, co, strict=True):
                mul(c["f3"], w["NA"], out=w["T"])
                w["U"] += w["T"]
        return [self.inverse(w["U"], kept, out=f, overwrite=True)
                for w, f in zip(work, fields, strict=True)]

    def _stage_rates(self, work: list[dict[str, np.ndarray]], fields: list[np.ndarray],
                     kept: tuple[bool, ...], t: float, into: str) -> bool:
        """``N̂`` at the stage whose coefficients are each species' ``S`` (used up) into
        its ``into``; False when ``N`` there is not constant along an axis ``kept``
        drops."""
        n = self._evaluate(self._upload([self.inverse(w["S"], kept, out=f, overwrite=True)
                                         for w, f in zip(work, fields, strict=True)]), t)
        if not all(kept) and any(not k and j for k, j in zip(kept, self.kept_axes(n),
                                                                strict=True)):
            return False
        for a, w in zip(n, work, strict=True):
            self.forward(a, kept, out=w[into])
        return True
