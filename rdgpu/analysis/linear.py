"""Linear stability of a homogeneous state: the steady state, the reaction Jacobian and the
dispersion relation.

* `steady_state` — the homogeneous steady state ``R(x*) = 0`` of a model (Newton /
  Powell hybrid from the model's guess), `jacobian` — ``∂R/∂x`` there, exact to
  round-off by the complex-step derivative (the functions of the equation language are
  analytic, so evaluating them with complex numbers is legitimate, except ``abs``, which
  is evaluated as ``sqrt(a*a)`` there, and ``min``/``max``, which select an argument);
* `dispersion` — the growth rate ``Re γ(k)`` of a Fourier mode of wavenumber ``k``:
  the largest real part of the eigenvalues of ``J − k² D + k⁴ B`` (`dispersion_matrix`;
  Quillen 2025, eq. 18, with cross-diffusion and fourth order), ``D`` and ``B`` the
  matrices of the coefficients of ``laplace`` and ``laplace(laplace(·))``
  (`rdgpu.models.Model.linear_operators`: ``D[s, r]`` multiplies ``laplace(r)`` in
  the equation of ``s``), since the symbol of ``laplace`` is ``−k²`` and that of the
  bilaplacian ``+k⁴``.  On a grid the 3-point (per axis) stencil's mode ``m`` of ``n``
  cells has ``k = (2/dx) sin(π m / n)`` (`grid_wavenumber`), not ``2π m/(n dx)``;
  the generated bilaplacian is that stencil applied twice, so its symbol is exactly the
  square; ``dispersion(..., dx=h)`` maps continuous wavenumbers to the grid's.

Parameters that are fields are replaced by their mean; parameters given as expressions
must be constants (no ``x, y, z, t``).
"""

from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.ir import equations as eq

if TYPE_CHECKING:
    from rdgpu.models.model import Model

__all__ = ["dispersion", "dispersion_matrix", "grid_wavenumber", "jacobian", "steady_state"]


def _scalar_params(model: Model, params: Mapping[str, Any] | None) -> dict[str, float]:
    merged = {**model.defaults, **dict(params or {})}
    out: dict[str, float] = {}
    texts: dict[str, str] = {}
    for k, v in merged.items():
        if isinstance(v, str):  # an expression of the other parameters: evaluated below
            texts[k] = v
            continue
        if isinstance(v, Mapping):  # a field spec: its mean value
            kind = v.get("kind")
            if kind == "random":
                v = 0.5 * (float(v["low"]) + float(v["high"]))
            elif kind == "sine":
                v = float(v["mean"])
            elif kind == "linear":
                v = 0.5 * (float(v["start"]) + float(v["stop"]))
            else:
                raise ValueError(f"unknown parameter field spec {v!r}")
        out[k] = float(np.mean(v))
    for k, text in texts.items():
        out[k] = _constant_expression(k, text, out)
    return out


def _constant_expression(name: str, text: str, scalars: Mapping[str, float]) -> float:
    """A parameter given as text: its value from the (numeric) parameters, or a
    ``ValueError`` if it varies in space or time."""
    tree = eq.parse(text, params=list(scalars), what=f"parameter {name!r}", laplace=False)
    varying = sorted(eq.names(tree, "coord") | eq.names(tree, "time")
                     | eq.names(tree, "length"))
    if varying:
        raise ValueError(
            f"parameter {name!r} = {text!r} depends on {', '.join(varying)}: the linear "
            "analysis needs a homogeneous medium; pass a number for it"
        )
    return float(eq.evaluate(tree, dict(scalars)))


def _rates(model: Model, x: Sequence[Any], params: dict[str, float], dtype) -> np.ndarray:
    r = model.rates([np.asarray(xi, dtype=dtype) for xi in x], params, dtype)
    return np.array([np.asarray(ri, dtype=dtype) for ri in r])


def _analytic(model: Model) -> Any:
    """The model for the complex step: ``abs(a)`` (not analytic: NumPy's complex ``abs`` is
    the modulus, whose imaginary part is 0) becomes ``sqrt(a*a)``, equal to ``|a|`` for
    real ``a`` and carrying ``sign(a)·h`` in the imaginary part."""
    trees = getattr(model, "trees", None)
    if not isinstance(trees, Mapping):
        return model

    def fix(node):
        if isinstance(node, eq.Call) and node.fn == "abs":
            a = eq.substitute(node.args[0], fix)
            return eq.Call("sqrt", (eq.Bin("*", a, a),))
        return None

    uses_abs = any(isinstance(n, eq.Call) and n.fn == "abs"
                   for t in trees.values() for n in eq.walk(t))
    if not uses_abs:
        return model
    shadow = copy.copy(model)
    shadow.trees = {s: eq.substitute(t, fix) for s, t in trees.items()}
    return shadow


def jacobian(model: Model, params: Mapping[str, Any] | None, state: Sequence[float]) -> np.ndarray:
    """``J_ij = ∂R_i/∂x_j`` at ``state`` by the complex step (float64, exact to round-off;
    ``min``/``max`` take the derivative of the selected argument, ``abs`` that of ``±a``).

    Parameters
    ----------
    model : Model
        A model of `rdgpu.models` (`rdgpu.models.define_model`, an entry of
        `rdgpu.models.MODELS`).
    params : mapping or None
        Parameter values over the model's defaults (None: the defaults).  A field is
        replaced by its mean (an array's mean; a ``"random"`` spec's ``(low + high)/2``,
        a ``"sine"`` spec's ``mean``, a ``"linear"`` spec's ``(start + stop)/2``); a
        parameter given as text must be a constant expression of the others.
    state : sequence of float
        The point: one value per species, in the order of ``model.species``.

    Returns
    -------
    ndarray
        float64, shape ``(n, n)`` for ``n`` species: row ``i`` the equation of species
        ``i``, column ``j`` the derivative by species ``j``.

    Raises
    ------
    ValueError
        A field spec of another kind, or a parameter given as text that depends on
        ``x``, ``y``, ``z``, ``t`` or the domain's lengths.
    """
    p = _scalar_params(model, params)
    x = np.asarray(state, dtype=np.float64)
    n = x.size
    h = 1e-30
    J = np.empty((n, n))
    m = _analytic(model)
    for j in range(n):
        xc = x.astype(np.complex128)
        xc[j] += 1j * h
        J[:, j] = _rates(m, list(xc), p, np.complex128).imag / h
    return J


def steady_state(
    model: Model,
    params: Mapping[str, Any] | None = None,
    guess: Sequence[float] | None = None,
    *,
    tol: float = 1e-10,
) -> np.ndarray:
    """A homogeneous steady state ``R(x*) = 0`` near ``guess`` (default: the model's
    ``steady_guess``, else 1 for every species).  Raises ``RuntimeError`` if the solver
    does not converge to ``max|R| < tol (1 + max|x*|)``.

    Parameters
    ----------
    model : Model
        A model of `rdgpu.models` (`rdgpu.models.define_model`, an entry of
        `rdgpu.models.MODELS`).
    params : mapping, optional
        Parameter values over the model's defaults (None: the defaults).  A field is
        replaced by its mean (an array's mean; a ``"random"`` spec's ``(low + high)/2``,
        a ``"sine"`` spec's ``mean``, a ``"linear"`` spec's ``(start + stop)/2``); a
        parameter given as text must be a constant expression of the others.
    guess : sequence of float, optional
        Where the solver starts: one value per species (order of ``model.species``);
        default None (the model's ``steady_guess``, else 1 for every species).
    tol : float, optional
        The residual allowed, relative to ``1 + max|x*|``; default ``1e-10``.

    Returns
    -------
    ndarray
        float64, shape ``(n,)``: the state ``x*``, one value per species.

    Raises
    ------
    RuntimeError
        The solver did not reach the residual ``tol`` (or it is not finite).
    ValueError
        A field spec of another kind, or a parameter given as text that depends on
        ``x``, ``y``, ``z``, ``t`` or the domain's lengths.
    """
    from scipy.optimize import root  # SciPy's optimize loads in 0.3 s: only when solving

    p = _scalar_params(model, params)
    if guess is None:
        g = model.steady_guess(p) if hasattr(model, "steady_guess") else None
        guess = g if g is not None else [1.0] * len(model.species)
    x0 = np.asarray(guess, dtype=np.float64)

    def fun(x):
        return _rates(model, list(x), p, np.float64)

    sol = root(fun, x0, jac=lambda x: jacobian(model, p, x), method="hybr", tol=1e-14)
    x = np.asarray(sol.x, dtype=np.float64)
    res = float(np.max(np.abs(fun(x))))
    if not np.isfinite(res) or res > tol * (1.0 + float(np.max(np.abs(x)))):
        raise RuntimeError(
            f"no steady state of {model.name!r} found near {list(x0)}: residual {res:.3g} "
            f"({sol.message}); pass a better guess"
        )
    return x


def _spatial_operators(model: Model, params: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """``(D, B)``: the coefficients of ``laplace(r)`` and ``laplace(laplace(r))`` in the
    equation of each species (rows) — `Model.linear_operators`, or the diagonal of
    ``diffusion_coefficients`` for a model object without it."""
    n = len(model.species)
    if hasattr(model, "linear_operators"):
        ops = model.linear_operators(params)
        if ops is None:
            linear = getattr(model, "linear", {})
            which = [s for s in model.species if linear.get(s, 0) is None]
            where = f" (the equation of {', '.join(map(repr, which))})" if which else ""
            raise ValueError(
                f"model {model.name!r} has a Laplacian with a state-dependent coefficient"
                f"{where}, such as u*laplace(u): the dispersion relation needs every "
                "laplace(s) and laplace(laplace(s)) multiplied by numbers and parameters "
                "only"
            )
        D, B = (np.asarray(a, dtype=np.float64) for a in ops)
    else:
        D = np.diag(np.asarray(model.diffusion_coefficients(params), dtype=np.float64))
        B = np.zeros((n, n))
    for name, a in (("laplace", D), ("laplace(laplace)", B)):
        if not np.isfinite(a).all():
            raise ValueError(f"model {model.name!r}: a coefficient of {name} is not finite "
                             f"with these parameters:\n{a}")
    return D, B


def dispersion_matrix(
    model: Model,
    params: Mapping[str, Any] | None,
    k: Any,
    *,
    state: Sequence[float] | None = None,
    dx: float | None = None,
) -> np.ndarray:
    """The linearisation ``J − k² D + k⁴ B`` about the homogeneous steady state (or
    ``state``) acting on a Fourier mode ``e^{ik·x}`` of every species: shape ``k.shape +
    (n, n)``, ``n`` the number of species; ``J`` the reaction Jacobian (`jacobian`),
    ``D[s, r]`` / ``B[s, r]`` the coefficients of ``laplace(r)`` / ``laplace(laplace(r))``
    in the equation of ``s``.  ``dx``: the grid's symbol instead, ``k² → (4/dx²)
    sin²(k dx/2)`` (the 3-point stencil along one axis; for a mode of several axes pass
    ``sqrt`` of the sum of the axes' ``grid_wavenumber²``).  ``ValueError`` if a Laplacian
    has a state-dependent coefficient.

    Parameters
    ----------
    model : Model
        A model of `rdgpu.models` (`rdgpu.models.define_model`, an entry of
        `rdgpu.models.MODELS`).
    params : mapping or None
        Parameter values over the model's defaults (None: the defaults).  A field is
        replaced by its mean (an array's mean; a ``"random"`` spec's ``(low + high)/2``,
        a ``"sine"`` spec's ``mean``, a ``"linear"`` spec's ``(start + stop)/2``); a
        parameter given as text must be a constant expression of the others.
    k : float or array
        Wavenumbers (1/length), any shape.
    state : sequence of float, optional
        The homogeneous state to linearise about, one value per species; default None
        (`steady_state` with ``params``).
    dx : float, optional
        The grid spacing (length) whose 3-point stencil's symbol replaces ``k²``;
        default None (the continuous symbol).

    Returns
    -------
    ndarray
        float64, shape ``k.shape + (n, n)`` for ``n`` species.

    Raises
    ------
    ValueError
        ``state`` without one value per species, a Laplacian with a state-dependent
        coefficient (``u*laplace(u)``), a coefficient of ``laplace`` or of the bilaplacian
        that is not finite with these parameters, or a parameter as `jacobian` rejects it.
    RuntimeError
        No ``state`` given and `steady_state` does not converge.
    """
    p = _scalar_params(model, params)
    D, B = _spatial_operators(model, p)
    x = steady_state(model, p) if state is None else np.asarray(state, dtype=np.float64)
    if x.shape != (len(model.species),):
        raise ValueError(f"state must hold one value per species {model.species}, got "
                         f"{list(np.ravel(x))}")
    J = jacobian(model, p, x)
    k = np.asarray(k, dtype=np.float64)
    if dx is not None:
        k = 2.0 / float(dx) * np.abs(np.sin(0.5 * k * float(dx)))
    k2 = (k * k)[..., None, None]
    return J - k2 * D + (k2 * k2) * B


def dispersion(
    model: Model,
    params: Mapping[str, Any] | None,
    k: Any,
    *,
    state: Sequence[float] | None = None,
    dx: float | None = None,
) -> np.ndarray:
    """Growth rate ``Re γ(k)``: the largest real part of the eigenvalues of
    ``J − k² D + k⁴ B`` (`dispersion_matrix`: cross-diffusion and bilaplacians
    included) at the homogeneous steady state (or at ``state``), for each wavenumber in
    ``k`` (any shape; the result has the same shape).  ``dx``: with the grid's symbol
    (`dispersion_matrix`); equivalently pass ``k = grid_wavenumber(m, n, dx)``.

    Parameters
    ----------
    model : Model
        A model of `rdgpu.models` (`rdgpu.models.define_model`, an entry of
        `rdgpu.models.MODELS`).
    params : mapping or None
        Parameter values over the model's defaults, as `jacobian` takes them.
    k : float or array
        Wavenumbers (1/length), any shape.
    state : sequence of float, optional
        The homogeneous state, one value per species; default None (`steady_state`).
    dx : float, optional
        The grid spacing (length) whose symbol is used; default None (the continuous
        one).

    Returns
    -------
    ndarray
        float64, the shape of ``k``: ``Re γ(k)``, positive where the mode grows.

    Raises
    ------
    ValueError
        As `dispersion_matrix` raises it.
    RuntimeError
        No ``state`` given and `steady_state` does not converge.
    """
    A = dispersion_matrix(model, params, k, state=state, dx=dx)
    return np.asarray(np.linalg.eigvals(A).real.max(axis=-1))


def grid_wavenumber(m: Any, n: int, dx: float = 1.0) -> np.ndarray:
    """Wavenumber of Fourier mode ``m`` on ``n`` periodic cells as the 3-point stencil
    (one axis of the 5- and 7-point ones) sees it: ``−Δ_h e^{2πimj/n} = k² e^{2πimj/n}``
    with ``k = (2/dx)|sin(π m/n)|``; the bilaplacian (the stencil twice) sees ``k⁴``.  On
    ``n`` Neumann cells the mode ``cos(π m (j + ½)/n)`` has ``grid_wavenumber(m, 2n, dx)``.

    Parameters
    ----------
    m : int or array
        The mode numbers, any shape (``m`` and ``n − m`` give the same wavenumber).
    n : int
        Periodic cells along the axis.
    dx : float, optional
        The grid spacing (length); default 1.

    Returns
    -------
    ndarray
        float64, the shape of ``m``: ``k`` in 1/length.
    """
    return (2.0 / dx) * np.abs(np.sin(np.pi * np.asarray(m, dtype=np.float64) / n))
