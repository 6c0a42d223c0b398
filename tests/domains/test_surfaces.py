"""Rough surfaces (seed 002 §2, §5): random waves, heat filters, roughen, periodic graph
meshes and the disc mesh."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sl
import scipy.sparse as sp

from rdgpu.domains.graph_surface import GraphSurface
from rdgpu.domains.mesh.surface_mesh import DegenerateMeshError, SurfaceMesh
from rdgpu.domains.surfaces import graph_mesh, heat_filtered, random_waves, roughen, vertex_normals

# ------------------------------------------------------------------------ random waves


def power(h: np.ndarray) -> np.ndarray:
    """|FFT|² with the axes' integer frequencies: returns (P, ky, kx) (ky rows, kx columns)."""
    P = np.abs(np.fft.fft2(h)) ** 2
    ky = np.fft.fftfreq(h.shape[0], 1.0 / h.shape[0])
    kx = np.fft.fftfreq(h.shape[1], 1.0 / h.shape[1])
    KX, KY = np.meshgrid(np.abs(kx), np.abs(ky), indexing="xy")
    return P, KY, KX


def test_random_waves_reproducible_and_seeded() -> None:
    a = random_waves((24, 32), 0.2, 4, seed=7)
    b = random_waves((24, 32), 0.2, 4, seed=7)
    c = random_waves((24, 32), 0.2, 4, seed=8)
    assert a.dtype == np.float64 and a.shape == (24, 32)
    np.testing.assert_array_equal(a, b)
    assert np.abs(a - c).max() > 0.05


@pytest.mark.parametrize("amplitude", [0.05, 0.1, 1.5])
def test_random_waves_amplitude_exact(amplitude: float) -> None:
    h = random_waves((20, 28), amplitude, (3, 2), seed=1, dx=0.3)
    assert np.abs(h).max() == pytest.approx(amplitude, rel=1e-15)


def test_random_waves_zero_amplitude() -> None:
    h = random_waves((16, 16), 0.0, 3)
    assert h.shape == (16, 16) and not h.any()


@pytest.mark.parametrize("M, N", [(2, 6), (5, 1), (0, 3), (7, 7)])
def test_random_waves_band_limited(M: int, N: int) -> None:
    """Periodic on the grid and band limited: no energy above (M, N), M along x (columns),
    N along y (rows); energy up to the cut-off on both axes."""
    h = random_waves((32, 36), 1.0, (M, N), seed=3, dx=0.5, dy=0.25)
    P, ky, kx = power(h)
    total = P.sum()
    assert P[(kx > M) | (ky > N)].sum() < 1e-24 * total
    assert P[kx == M].sum() > 1e-6 * total and P[ky == N].sum() > 1e-6 * total
    assert P[0, 0] < 1e-24 * total  # a_00 = 0: zero mean


def test_random_waves_matches_eq6_at_cell_centres() -> None:
    """The fast evaluation equals eq. 6 summed term by term with the documented draws."""
    M, N, beta, ny, nx, dx, dy = 2, 3, 1.5, 10, 12, 0.7, 0.4
    rng = np.random.default_rng(5)
    xi = rng.standard_normal((2 * N + 1, 2 * M + 1))
    phi = rng.uniform(-np.pi / 2, np.pi / 2, (2 * N + 1, 2 * M + 1))
    x = (np.arange(nx) + 0.5) * dx
    y = (np.arange(ny) + 0.5) * dy
    X, Y = np.meshgrid(x, y, indexing="xy")
    ref = np.zeros((ny, nx))
    for n in range(-N, N + 1):
        for m in range(-M, M + 1):
            if m == 0 and n == 0:
                continue
            a = xi[n + N, m + M] * (m * m + n * n) ** (-beta / 2)
            ref += a * np.cos(
                2 * np.pi * (m * X / (nx * dx) + n * Y / (ny * dy)) + phi[n + N, m + M]
            )
    ref *= 0.3 / np.abs(ref).max()
    h = random_waves((ny, nx), 0.3, (M, N), seed=5, attenuation=beta, dx=dx, dy=dy)
    np.testing.assert_allclose(h, ref, rtol=0, atol=1e-13)


def test_attenuation_lowers_high_frequency_energy() -> None:
    def high_fraction(beta: float) -> float:
        P, ky, kx = power(random_waves((48, 48), 1.0, 10, seed=2, attenuation=beta))
        return float(P[np.hypot(kx, ky) > 5].sum() / P.sum())

    f0, f1, f2 = high_fraction(0.0), high_fraction(1.0), high_fraction(2.0)
    assert f0 > f1 > f2
    assert f2 < 0.5 * f0


# ------------------------------------------------------------------------ heat filtered


def test_heat_filtered_reproducible_amplitude_mean() -> None:
    a = heat_filtered((20, 24), 0.1, 10, seed=4)
    b = heat_filtered((20, 24), 0.1, 10, seed=4)
    c = heat_filtered((20, 24), 0.1, 10, seed=5)
    np.testing.assert_array_equal(a, b)
    assert np.abs(a - c).max() > 0.01
    assert np.abs(a).max() == pytest.approx(0.1, rel=1e-15)
    assert abs(a.mean()) < 1e-15
    assert not heat_filtered((8, 8), 0.0, 3).any()


@pytest.mark.parametrize("tensor, tau", [((1.0, 1.0), None), ((0.01, 1.0), 0.3), ((5.0, 1.0), 2.0)])
def test_heat_filtered_equals_fourier_filter(
    tensor: tuple[float, float], tau: float | None
) -> None:
    """The periodic 5-point filter is diagonal in Fourier space: k implicit steps divide
    mode (p, q) by (1 + τ(fx·4 sin²(πp/nx)/dx² + fy·4 sin²(πq/ny)/dy²))^k."""
    ny, nx, dx, dy, steps = 12, 18, 0.5, 0.8, 7
    h = heat_filtered((ny, nx), 0.2, steps, seed=9, tensor=tensor, tau=tau, dx=dx, dy=dy)
    x0 = np.random.default_rng(9).uniform(0.0, 1.0, (ny, nx))
    t = dx * dy if tau is None else tau
    lam = (tensor[0] * 4 * np.sin(np.pi * np.arange(nx) / nx) ** 2 / dx**2)[None, :] + (
        tensor[1] * 4 * np.sin(np.pi * np.arange(ny) / ny) ** 2 / dy**2
    )[:, None]
    ref = np.fft.ifft2(np.fft.fft2(x0) / (1 + t * lam) ** steps).real
    ref -= ref.mean()
    ref *= 0.2 / np.abs(ref).max()
    np.testing.assert_allclose(h, ref, rtol=0, atol=1e-12)


def test_heat_filtered_anisotropy() -> None:
    """A weak x filter (fx ≪ fy) leaves the surface rougher along x than along y."""
    h = heat_filtered((40, 40), 1.0, 15, seed=0, tensor=(0.01, 1.0))
    gx = np.abs(np.diff(h, axis=1)).mean()
    gy = np.abs(np.diff(h, axis=0)).mean()
    assert gx > 3 * gy


# ------------------------------------------------------------------------ roughen


@pytest.mark.parametrize(
    "make",
    [
        lambda: SurfaceMesh.icosphere(2),
        lambda: SurfaceMesh.disc(1.0, 6),
        lambda: graph_mesh(random_waves((12, 10), 0.2, 2), dx=0.4),
    ],
    ids=["icosphere", "disc", "periodic-graph"],
)
def test_roughen_moves_along_normals(make) -> None:
    mesh = make()
    V0 = np.array(mesh.vertices)
    rough = mesh.roughen(amplitude=0.03, filter_steps=5, seed=2)
    assert isinstance(rough, SurfaceMesh) and rough is not mesh
    np.testing.assert_array_equal(mesh.vertices, V0)  # the input is unchanged
    np.testing.assert_array_equal(rough.faces, mesh.faces)
    assert rough.n_faces == mesh.n_faces and rough.is_closed == mesh.is_closed
    assert rough.period == mesh.period
    d = rough.vertices - mesh.vertices
    n = vertex_normals(mesh)
    s = np.einsum("ij,ij->i", d, n)
    np.testing.assert_allclose(d, s[:, None] * n, atol=1e-15)  # along the normals only
    assert np.abs(s).max() == pytest.approx(0.03, rel=1e-12)  # ≤ amplitude, attained
    assert abs(np.dot(mesh.areas, s)) < 1e-14 * mesh.total_area  # area-weighted mean 0
    np.testing.assert_array_equal(roughen(mesh, 0.03, 5, seed=2).vertices, rough.vertices)
    assert np.abs(mesh.roughen(0.03, 5, seed=3).vertices - rough.vertices).max() > 1e-3


def test_roughen_is_the_mesh_heat_filter() -> None:
    """The normal displacement is k steps of (A − τW) x_{k+1} = A x_k on uniform values."""
    mesh = SurfaceMesh.uv_sphere(6, 10)
    steps, tau = 4, 0.05
    rough = mesh.roughen(0.1, steps, seed=11, tau=tau)
    x = np.random.default_rng(11).uniform(0.0, 1.0, mesh.n_vertices)
    A, W = np.diag(mesh.areas), mesh.weights.toarray()
    for _ in range(steps):
        x = np.linalg.solve(A - tau * W, A @ x)
    x -= np.dot(mesh.areas, x) / mesh.areas.sum()
    x *= 0.1 / np.abs(x).max()
    s = np.einsum("ij,ij->i", rough.vertices - mesh.vertices, vertex_normals(mesh))
    np.testing.assert_allclose(s, x, atol=1e-13)


def test_roughen_smooths_more_with_more_steps() -> None:
    mesh = SurfaceMesh.icosphere(3)

    def dirichlet_energy(m: SurfaceMesh) -> float:
        s = np.einsum("ij,ij->i", m.vertices - mesh.vertices, vertex_normals(mesh))
        return float(-s @ (mesh.weights @ s))

    e = [dirichlet_energy(mesh.roughen(0.05, k, seed=1)) for k in (0, 3, 15)]
    assert e[0] > 3 * e[1] > 9 * e[2]


def test_vertex_normals_sphere_and_disc() -> None:
    sphere = SurfaceMesh.icosphere(2)
    n = vertex_normals(sphere)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-15)
    assert np.einsum("ij,ij->i", n, sphere.vertices).min() > 0.99  # outward, near radial
    np.testing.assert_allclose(vertex_normals(SurfaceMesh.disc(1.0, 3)), [[0, 0, 1]] * 37)


# ------------------------------------------------------------------------ periodic graph mesh


@pytest.mark.parametrize("nx, ny, dx, dy", [(5, 4, 1.0, 1.0), (7, 9, 0.3, 0.7)])
def test_flat_periodic_plane_is_the_5_point_laplacian(
    nx: int, ny: int, dx: float, dy: float
) -> None:
    mesh = graph_mesh(np.zeros((ny, nx)), dx=dx, dy=dy)
    assert mesh.is_closed and mesh.boundary_edges.shape == (0, 2)
    assert mesh.period == (nx * dx, ny * dy)
    assert repr(mesh).endswith(f"closed, period=({nx * dx:g}, {ny * dy:g}))")
    assert mesh.total_area == pytest.approx(nx * dx * ny * dy, rel=1e-14)
    np.testing.assert_allclose(mesh.areas, dx * dy, rtol=1e-14)
    d2 = lambda n, h: sp.diags([1.0, -2.0, 1.0], [-1, 0, 1], (n, n)).tolil()  # noqa: E731
    Dx, Dy = d2(nx, dx), d2(ny, dy)
    Dx[0, -1] = Dx[-1, 0] = 1
    Dy[0, -1] = Dy[-1, 0] = 1
    five = sp.kron(sp.identity(ny), Dx) / dx**2 + sp.kron(Dy, sp.identity(nx)) / dy**2
    np.testing.assert_allclose(mesh.laplacian.toarray(), five.toarray(), atol=1e-12)


def test_periodic_mesh_closed_and_conservative() -> None:
    h = random_waves((16, 20), 0.4, (3, 2), seed=6, dx=0.25)
    mesh = graph_mesh(h, dx=0.25)
    assert mesh.is_closed and mesh.boundary_edges.size == 0
    assert mesh.n_vertices == 320 and mesh.n_faces == 640 and mesh.n_edges == 960
    u = np.random.default_rng(0).standard_normal(mesh.n_vertices)
    Lu = mesh.laplacian @ u
    assert abs(np.dot(mesh.areas, Lu)) < 1e-12 * np.abs(mesh.areas * Lu).sum()
    np.testing.assert_allclose(mesh.laplacian @ np.ones(mesh.n_vertices), 0.0, atol=1e-10)
    assert mesh.mean_edge_length < 0.5  # minimum images: no edge crosses the domain


def test_rough_periodic_area_converges_to_metric_area() -> None:
    """The triangulated area and Σ √g dx dy (GraphSurface) agree to O(h²) as the grid of
    the same surface is refined."""
    L, errors = 2.0, []
    for n in (16, 32, 64):
        h = random_waves((n, n), 0.3, 2, seed=4, dx=L / n)
        mesh_area = graph_mesh(h, dx=L / n).total_area
        metric_area = float(GraphSurface((n, n), dx=L / n, height=h).area_weights.sum())
        assert mesh_area > L * L  # rough: more area than the flat square
        errors.append(abs(mesh_area - metric_area) / metric_area)
    assert errors[0] < 0.02
    assert errors[1] < 0.4 * errors[0] and errors[2] < 0.4 * errors[1]


def test_periodic_mesh_export_unwraps_seams(tmp_path: Path) -> None:
    nx, ny, dx = 6, 5, 0.5
    mesh = graph_mesh(random_waves((ny, nx), 0.1, 2, seed=1), dx=dx)
    V, F, src = mesh.unwrapped()
    assert len(V) == nx * ny + nx + ny + 1  # a seam column, a seam row and a corner
    np.testing.assert_array_equal(V[: mesh.n_vertices], mesh.vertices)
    np.testing.assert_array_equal(V[:, 2], mesh.vertices[src, 2])
    np.testing.assert_allclose(
        (V[:, :2] - mesh.vertices[src, :2]) % [nx * dx, ny * dx], 0.0, atol=1e-12
    )
    span = [np.ptp(V[F][:, :, a], axis=1).max() for a in (0, 1)]
    assert span[0] <= dx + 1e-12 and span[1] <= dx + 1e-12  # no triangle spans the domain
    flat = SurfaceMesh(V, F)  # an ordinary open mesh with the same triangles
    assert flat.total_area == pytest.approx(mesh.total_area, rel=1e-13)
    assert len(flat.boundary_edges) == 2 * (nx + ny)

    pytest.importorskip("trimesh")
    assert len(mesh.to_trimesh().vertices) == len(V)
    mesh.save(tmp_path / "m.obj")
    back = SurfaceMesh.load(tmp_path / "m.obj")
    np.testing.assert_allclose(back.vertices, V, atol=1e-15)
    f = np.arange(mesh.n_vertices, dtype=np.float64)
    mesh.save(tmp_path / "m.ply", fields={"f": f})
    pytest.importorskip("pyvista")
    pd = mesh.to_pyvista({"f": f})
    np.testing.assert_array_equal(np.asarray(pd.point_data["f"]), f[src])


def test_non_periodic_export_unchanged() -> None:
    mesh = SurfaceMesh.disc(1.0, 2)
    V, F, src = mesh.unwrapped()
    np.testing.assert_array_equal(V, mesh.vertices)
    np.testing.assert_array_equal(F, mesh.faces)
    np.testing.assert_array_equal(src, np.arange(mesh.n_vertices))
    assert mesh.period is None


# ------------------------------------------------------------------------ disc


def test_disc_counts_area_boundary() -> None:
    errors = []
    for rings in (2, 4, 8, 16):
        d = SurfaceMesh.disc(1.5, rings)
        assert d.n_vertices == 1 + 3 * rings * (rings + 1) and d.n_faces == 6 * rings**2
        assert len(d.boundary_edges) == 6 * rings and not d.is_closed
        assert np.abs(d.vertices[:, 2]).max() == 0.0
        r = np.hypot(d.vertices[:, 0], d.vertices[:, 1])
        np.testing.assert_allclose(r[d.boundary_vertices], 1.5, rtol=1e-14)
        errors.append(np.pi * 1.5**2 - d.total_area)
        assert d.total_area == pytest.approx(d.areas.sum(), rel=1e-13)
    assert errors[-1] > 0 and all(e1 < 0.3 * e0 for e0, e1 in zip(errors, errors[1:], strict=False))
    assert errors[-1] < 3e-3 * np.pi * 1.5**2


def test_disc_near_equilateral() -> None:
    d = SurfaceMesh.disc(1.0, 10)
    V, F = d.vertices, d.faces
    lengths = np.stack(
        [np.linalg.norm(V[F[:, k]] - V[F[:, (k + 1) % 3]], axis=1) for k in range(3)]
    )
    assert (lengths.max(axis=0) / lengths.min(axis=0)).max() < 1.6
    cross = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    assert (cross[:, 2] > 0).all()  # counter-clockwise


def test_disc_neumann_eigenvalue_converges() -> None:
    """λ₁ = (j'_{1,1}/r)² (double) for the Neumann Laplacian on a disc of radius r."""
    r, errors = 2.0, []
    exact = (1.8411837813406593 / r) ** 2
    for rings in (3, 6, 12):
        d = SurfaceMesh.disc(r, rings)
        lam = sl.eigh(-d.weights.toarray(), np.diag(d.areas), eigvals_only=True)
        assert abs(lam[0]) < 1e-10
        assert lam[2] - lam[1] < 1e-8 * lam[1]  # the cos θ / sin θ pair
        errors.append(abs(lam[1] - exact) / exact)
    assert errors[1] < 0.5 * errors[0] and errors[2] < 0.5 * errors[1]
    assert errors[-1] < 5e-3


# ------------------------------------------------------------------------ errors


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: random_waves((8, 8), -0.1), "amplitude"),
        (lambda: random_waves((8, 8), 0.1, 0), "not both 0"),
        (lambda: random_waves((8, 8), 0.1, (1, -1)), "max_frequency"),
        (lambda: random_waves((8, 8), 0.1, (1.5, 2)), "max_frequency"),
        (lambda: random_waves((8, 8), 0.1, (4, 1)), "2M < nx"),
        (lambda: random_waves((16, 8), 0.1, (1, 8)), "2N < ny"),
        (lambda: random_waves((8,), 0.1, 1), "shape"),
        (lambda: random_waves((8, 8), 0.1, 1, dx=0.0), "dx and dy"),
        (lambda: random_waves((8, 8), 0.1, 1, attenuation=-1), "attenuation"),
        (lambda: heat_filtered((8, 8), 0.1, -1), "filter_steps"),
        (lambda: heat_filtered((8, 8), 0.1, 2.5), "filter_steps"),
        (lambda: heat_filtered((8, 8), 0.1, 2, tensor=(1.0, -1.0)), "tensor"),
        (lambda: heat_filtered((8, 8), 0.1, 2, tensor=1.0), "tensor"),
        (lambda: heat_filtered((8, 8), 0.1, 2, tau=0.0), "tau"),
        (lambda: heat_filtered((2, 8)), "shape"),
        (lambda: SurfaceMesh.icosphere(1).roughen(amplitude=np.nan), "amplitude"),
        (lambda: SurfaceMesh.icosphere(1).roughen(0.1, 3, tau=-1.0), "tau"),
        (lambda: graph_mesh(np.zeros(9)), "2-D"),
        (lambda: graph_mesh(np.zeros((2, 5))), "shape"),
        (lambda: graph_mesh(np.full((4, 4), np.nan)), "finite"),
        (lambda: SurfaceMesh.disc(rings=0), "rings"),
        (lambda: SurfaceMesh.disc(radius=-1.0), "radius"),
        (lambda: SurfaceMesh(np.eye(3), [[0, 1, 2]], period=(1.0, 0.0)), "period"),
        (lambda: SurfaceMesh(np.eye(3), [[0, 1, 2]], period="ab"), "period"),
    ],
)
def test_errors(call, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        call()


def test_roughen_needs_a_mesh() -> None:
    with pytest.raises(TypeError, match="SurfaceMesh"):
        roughen(np.zeros((3, 3)))  # type: ignore[arg-type]


def test_periodic_face_too_wide_is_rejected() -> None:
    V = np.array([[0.1, 0.1, 0.0], [0.6, 0.1, 0.0], [0.1, 0.3, 0.0]])
    SurfaceMesh(V, [[0, 1, 2]], period=(2.0, 2.0))  # narrow: fine
    wide = np.array([[0.0, 0.0, 0.0], [0.5, 0.1, 0.0], [1.0, 0.3, 0.0]])
    SurfaceMesh(wide, [[0, 1, 2]])  # fine without a period
    with pytest.raises(DegenerateMeshError, match="half a period"):
        SurfaceMesh(wide, [[0, 1, 2]], period=(1.5, 2.0))  # its three edges wrap apart


# ------------------------------------------------------------------------ periodic meshes elsewhere


def test_periodic_mesh_simulation_data_file_keeps_period(tmp_path: Path) -> None:
    """A run on a periodic mesh saved to .npz loads back on the same periodic mesh (the
    wrapped triangles would otherwise span the domain)."""
    from rdgpu.io.output import load_npz, save_npz
    from rdgpu.simulation.driver import Simulation

    mesh = graph_mesh(random_waves((10, 12), 0.3, 2), dx=0.5)
    result = Simulation("gray-scott", mesh, None, dt=0.05, backend="numpy", seed=0).run(3)
    back = load_npz(save_npz(tmp_path / "run.npz", result)).domain
    assert back.period == mesh.period
    np.testing.assert_array_equal(back.laplacian.toarray(), mesh.laplacian.toarray())


def test_periodic_mesh_is_rendered_unwrapped(monkeypatch: pytest.MonkeyPatch) -> None:
    from rdgpu.io import output, rendering

    seen: dict[str, np.ndarray] = {}

    def fake_render(arrays: dict[str, np.ndarray], options: dict) -> np.ndarray:
        seen.update(arrays)
        return np.zeros((len(arrays["frames"]), 2, 2, 3), dtype=np.uint8)

    monkeypatch.setattr(rendering, "render_offscreen", fake_render)
    mesh = graph_mesh(np.zeros((4, 5)), dx=1.0)
    field = np.arange(mesh.n_vertices, dtype=np.float64)
    output.render_mesh(mesh, field)
    V, F, src = mesh.unwrapped()
    np.testing.assert_array_equal(seen["vertices"], V)
    np.testing.assert_array_equal(seen["faces"], F)
    np.testing.assert_array_equal(seen["frames"][0], field[src])
