"""The modified Allen-Cahn model (Dascal, Pai & Kimmel, equations §2): defined by its
equation like every model, stepped by Strang splitting with the exact Bernoulli substep
(`rdgpu.integrators.allen_cahn.AllenCahnStepper`), explicit or implicit diffusion in
between; `allen_cahn`, its form in the functional API (``rdgpu.allen_cahn``)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from rdgpu.backends.base import Backend, DeviceArray
from rdgpu.backends.registry import get_backend
from rdgpu.core import validation as check
from rdgpu.domains.boundary import DIRICHLET, NEUMANN, PERIODIC
from rdgpu.integrators.allen_cahn import AllenCahnStepper
from rdgpu.models.model import Model, check_dt, domain_shape, resolve_params, scalar_param
from rdgpu.ops.inputs import given_shape, grid_or_mesh, param_value
from rdgpu.ops.results import BackendSpec, check_finite, expect_out, give_host

if TYPE_CHECKING:
    from rdgpu.domains.base import Domain
    from rdgpu.domains.mesh.surface_mesh import SurfaceMesh

__all__ = ["AllenCahn", "allen_cahn"]


def _is_surface(domain: Domain) -> bool:
    return domain.kind == "graph-surface"


def _grid_face_differences(u: np.ndarray, axis: int, bc) -> np.ndarray:
    """Differences across every face of ``axis`` under its boundary condition (the faces
    the 5-point stencil couples): periodic wraps, Neumann has no boundary face, a
    Dirichlet ghost ``g`` adds the two faces to it."""
    if bc.kind == PERIODIC:
        return np.roll(u, -1, axis=axis) - u
    d = np.diff(u, axis=axis)
    if bc.kind == NEUMANN:
        return d
    if bc.kind == DIRICHLET:
        first = np.take(u, [0], axis=axis) - bc.value
        last = bc.value - np.take(u, [-1], axis=axis)
        return np.concatenate([first, d, last], axis=axis)
    raise ValueError(f"unknown boundary kind {bc.kind}")  # pragma: no cover


class AllenCahn(Model):
    """Modified Allen-Cahn ``u_t = Δu − (u³ − u + b)/ε²`` (Dascal et al., equations §2) by Strang
    splitting: the exact Bernoulli substep for ``dt/2`` → diffusion ``ū_t = Δū − b/ε²`` for
    ``dt`` → Bernoulli ``dt/2``.

    ``method="explicit"``: forward-Euler diffusion (one Laplacian + the pointwise kernel),
    stable for ``dt ≤ dx²/4`` on a square grid (``1/(2 Σ 1/h²)`` over its axes) or
    ``mesh.max_stable_dt(1)`` on a mesh.  ``method="implicit"`` (backward Euler) or
    ``"crank-nicolson"``: θ-scheme diffusion solved by `rdgpu.ops.implicit.ImplicitDiffusion`
    (fast transforms on a grid, multicolour SOR on the device on a mesh; unconditionally
    stable).  ``eps`` must be
    a number; ``b`` may be a field.  The equation itself is the model's definition (for
    `rdgpu.analysis` and py-pde); only the stepping is special.
    """

    methods = ("explicit", "implicit", "crank-nicolson")
    #: ε follows the spacing (domain_defaults): the mesh rule of mesh_lengths is not applied
    fits_domain_itself = True
    #: the default ε is this times the spacing (grid: min(dx, dy); mesh: mean edge length):
    #: interfaces pinned by the discretisation, the regime of Dascal et al. where b ≠ 0 gives
    #: spots (b < 0) or inverted spots (b > 0) that do not shrink away because they cannot
    #: move; the presets use 0.15 (global) and 0.3 (localized).  With the interface resolved
    #: (ε ≥ 0.5 h) every b ≠ 0 goes uniform (how fast: docs/seed000.md)
    eps_per_spacing = 0.3

    def __init__(self) -> None:
        super().__init__(
            "allen-cahn", {"u": "laplace(u) - (u**3 - u + b)/eps**2"}, {"b": 0.0, "eps": 1.0},
            description="modified Allen-Cahn u_t = Δu − (u³ − u + b)/ε²: b < 0 spots, b > 0 "
            "inverted spots, b = 0 stripes (Strang splitting with the exact Bernoulli "
            "substep)",
            source="Dascal, Pai & Kimmel, equations §2",
            steady_guess=lambda p: (1.0,),
            value_range={"u": (-1.0, 1.0)},
            default_method="explicit",
        )
        self.default_dt = self._default_dt
        self.default_time = self._default_time

    def domain_defaults(self, domain: Domain) -> dict[str, float]:
        """``eps`` = `eps_per_spacing` times the spacing of ``domain``."""
        domain_shape(domain)  # a domain, or a clear error
        return {"eps": self.eps_per_spacing * domain.spacing_scale}

    def _default_dt(self, params: Mapping[str, Any]) -> float:
        """ε²/2: the step of the presets, where the splitting is accurate."""
        return 0.5 * float(np.max(params.get("eps", self.defaults["eps"]))) ** 2

    def _default_time(self, params: Mapping[str, Any]) -> float:
        """1500 ε² (the presets' 3000 steps of ε²/2): the phases have separated and the
        pinned pattern has settled."""
        return 1500.0 * float(np.max(params.get("eps", self.defaults["eps"]))) ** 2

    def dt_limit(
        self, domain: Domain, params: Mapping[str, Any] | None = None, method: str = "explicit"
    ) -> float:
        if method != "explicit":
            return math.inf
        domain_shape(domain)  # a domain, or a clear error
        return domain.explicit_diffusion_limit()

    def stepper(
        self,
        domain: Domain,
        params: Mapping[str, Any] | None = None,
        *,
        dt: float,
        backend: Backend | str | None = None,
        dtype: Any = np.float64,
        check_stability: bool = True,
        seed: int = 0,
        method: str = "explicit",
    ) -> AllenCahnStepper:
        if method not in self.methods:
            raise ValueError(f"method must be one of {self.methods}, got {method!r}")
        p = resolve_params(self, domain, params, seed=seed)
        eps = scalar_param(p, "eps", "parameter")
        if not eps > 0:
            raise ValueError(f"eps must be > 0, got {eps}")
        what = ("explicit diffusion, dx²/4 on a grid, 2/λ_max(−L) on a mesh or a graph "
                "surface")
        dt = check_dt(dt, self.dt_limit(domain, p, method), what, check_stability)
        return AllenCahnStepper(self, domain, p, dt, get_backend(backend), np.dtype(dtype),
                                method)

    @staticmethod
    def energy(domain: Domain, u: Any, params: Mapping[str, Any] | None = None) -> float:
        """``J(u) = ∫ ½|∇u|² + ((u² − 1)²/4 + b u)/ε²`` (float64).

        Graph surface: ``½ uᵀ(−a Δ_Γ)u + Σ a_i ((u_i² − 1)²/4 + b u_i)/ε²`` with ``a`` its
        `rdgpu.domains.graph_surface.GraphSurface.area_weights` (``a Δ_Γ`` is symmetric), so
        ``−∂J/∂u = a (Δ_Γ u − (u³ − u + b)/ε²)``.
        Grid: ``dx dy [½ Σ_faces (Δ_face u / h)² + Σ_cells ((u²−1)²/4 + b u)/ε²]`` with the
        faces of the 5-point stencil and its boundary conditions, so ``−∂J/∂u = dx dy
        (Δ_h u − (u³ − u + b)/ε²)`` exactly.  Mesh: ``½ uᵀ(−W)u + Σ A_i ((u_i² − 1)²/4 +
        b u_i)/ε²`` (cotangent form).

        The continuous flow decreases J; the Strang-split explicit scheme does so step by
        step (to round-off) at ``dt ≤ dt_limit/2`` when the interface is resolved (ε ≳ the
        spacing).  With ε well below the spacing (the pinned regime of the sphere presets)
        the split step can raise J slightly near its discrete equilibrium: a splitting
        error that falls faster than dt (its size on the presets: docs/equations.md §2);
        use a smaller dt where a strictly monotone J matters.

        Parameters
        ----------
        domain : Domain
            A grid (1-, 2- or 3-D, with its boundary conditions and spacings), a
            `rdgpu.SurfaceMesh` or a graph surface.
        u : array
            The field: the grid's shape (or any array of as many values), one value per
            vertex on a mesh or a graph surface; a `DeviceArray` is downloaded first.
        params : mapping, optional
            ``b`` (a number or a field like ``u``) and ``eps`` (a number); default
            ``b = 0``, ``eps = 1``.

        Returns
        -------
        float
            ``J(u)``, computed in float64."""
        p = {"b": 0.0, "eps": 1.0, **dict(params or {})}
        if isinstance(u, DeviceArray):
            u = u.numpy()
        u = np.asarray(u, dtype=np.float64)
        b = np.asarray(p["b"], dtype=np.float64)
        eps = float(p["eps"])
        if _is_surface(domain):
            a = domain.area_weights.ravel()
            u = u.ravel()
            pot = ((u * u - 1.0) ** 2 / 4.0 + b.ravel() * u) / eps**2
            return 0.5 * float(u @ (-(a * (domain.laplacian @ u)))) + float(np.sum(a * pot))
        if not domain.unstructured:
            u = u.reshape(domain.shape)
            b = b.reshape(domain.shape) if b.size > 1 else b
            # faces along x (last axis), y and, on a 3-D grid, z (the 7-point stencil's)
            axes = [(-1, domain.bcs.x, domain.dx), (-2, domain.bcs.y, domain.dy)]
            if domain.ndim == 3:
                axes.append((-3, domain.bcs.z, domain.dz))
            grad = sum(float(np.sum((_grid_face_differences(u, a, bc) / h) ** 2))
                       for a, bc, h in axes)
            pot = ((u * u - 1.0) ** 2 / 4.0 + b * u) / eps**2
            return float(domain.cell_volume * (0.5 * grad + np.sum(pot)))
        domain_shape(domain)
        u = u.ravel()
        grad = 0.5 * float(u @ (-(domain.weights @ u)))
        pot = ((u * u - 1.0) ** 2 / 4.0 + b.ravel() * u) / eps**2 if b.size > 1 else \
            ((u * u - 1.0) ** 2 / 4.0 + float(b) * u) / eps**2
        return grad + float(np.sum(domain.areas * pot))


def allen_cahn(
    u: np.ndarray,
    *,
    eps: float,
    dt: float,
    b: float | np.ndarray = 0.0,
    steps: int = 1,
    method: str = "explicit",
    mesh: SurfaceMesh | None = None,
    dx: float = 1.0,
    dy: float | None = None,
    bc: Any = "periodic",
    check_stability: bool = True,
    backend: BackendSpec = None,
    out: Any = None,
) -> Any:
    """Advance the modified Allen-Cahn equation ``u_t = Δu − (u³ − u + b)/ε²`` (Dascal et al.,
    equations §2) by ``steps`` Strang-split steps.

    Each step is Bernoulli ``dt/2`` → diffusion with the source ``−b/ε²`` for ``dt`` →
    Bernoulli ``dt/2`` (`AllenCahn`'s stepper,
    `rdgpu.integrators.allen_cahn.AllenCahnStepper`).

    Parameters
    ----------
    u : array
        ``[nx]`` or ``[ny, nx]`` on a grid, one value per vertex on a mesh.
    eps : float
        The interface width ε (length), > 0.
    dt : float
        The time step (time units).
    b : float or array, optional
        A number or a field of u's shape; default 0.
    steps : int, optional
        Steps to take (>= 0); default 1.
    method : {"explicit", "implicit", "crank-nicolson"}, optional
        The diffusion step: ``"explicit"`` (limit ``1/(2(1/dx² + 1/dy²))`` on a grid,
        ``mesh.max_stable_dt(1)`` on a mesh), ``"implicit"`` (backward Euler) or
        ``"crank-nicolson"`` (solved by `rdgpu.ops.implicit.ImplicitDiffusion`: fast
        transforms on a grid, multicolour SOR on a mesh; any ``dt``); default
        ``"explicit"``.
    mesh : SurfaceMesh, optional
        A `rdgpu.SurfaceMesh` in place of ``dx``/``dy``/``bc``.
    dx, dy, bc
        As `rdgpu.laplacian` takes them.
    check_stability : bool, optional
        ``"explicit"`` raises `rdgpu.StabilityError` above its limit, and a non-finite
        result raises, unless ``False``; default ``True``.
    backend : str or Backend, optional
        As `rdgpu.get_backend` takes it.
    out : array, optional
        As in `rdgpu.ops.api` (the state crosses the host once each way: the stepper's
        own).

    Returns
    -------
    array
        ``u`` after ``steps`` steps.

    Raises
    ------
    ValueError
        ``eps`` or ``dt`` not a finite number > 0, ``eps`` so small that ``1/ε²``
        overflows the dtype, or an unknown ``method``.
    StabilityError
        An explicit ``dt`` above the limit (unless ``check_stability=False``).
    FloatingPointError
        A state that is no longer finite after the steps (unless
        ``check_stability=False``).
    """
    field, domain = grid_or_mesh(u, mesh, dx, dy, bc, be=get_backend(backend))
    eps = check.scalar(eps, "eps", strict=True)
    check_stability = check.flag(check_stability, "check_stability")
    if not 1.0 / (eps * eps) < float(np.finfo(field.dtype).max) if eps * eps > 0 else True:
        raise ValueError(
            f"eps={eps:g} is too small for {field.dtype}: the reaction term (u³ − u + b)/eps² "
            f"overflows; allowed: eps > {1 / math.sqrt(float(np.finfo(field.dtype).max)):.3g}"
        )
    dt = check.scalar(dt, "dt", strict=True)
    n = check.steps(steps)
    b_ = param_value(b, "b", field)
    expect_out(out, u, field.dtype)
    if method not in AllenCahn.methods:
        raise ValueError(f"method must be one of {AllenCahn.methods}, got {method!r}")
    stepper = AllenCahn().stepper(
        domain, {"eps": eps, "b": b_}, dt=dt, backend=get_backend(backend), dtype=field.dtype,
        check_stability=check_stability, method=method,
    )
    stepper.set_state({"u": field})
    stepper.advance(n)
    res = check_finite(stepper.get_state()["u"], "allen_cahn", stepping=True,
                       check_stability=check_stability)
    return give_host(res.reshape(given_shape(u)), u, out)
