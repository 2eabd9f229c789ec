"""Terrain meshes: exact geometry of planes, UVs, water by threshold, generators."""

import numpy as np
import pytest

from core.meshes import surface_area
from procgen.terrain import fractal_terrain, heightfield_to_mesh, tileable_terrain, water_mesh


def test_tilted_plane_geometry_normals_and_uvs():
    rows, cols, dx, dy = 5, 7, 0.5, 0.25
    jj, ii = np.meshgrid(np.arange(cols), np.arange(rows))
    z = 0.3 * jj * dx  # slope 0.3 along x
    mesh = heightfield_to_mesh(z, spacing=(dx, dy), origin=(1.0, 2.0, 3.0))
    v = np.asarray(mesh.vertices)
    f = np.asarray(mesh.triangles)
    assert len(v) == rows * cols and len(f) == 2 * (rows - 1) * (cols - 1)
    np.testing.assert_allclose(v[cols + 2], [1.0 + 2 * dx, 2.0 + dy, 3.0 + 0.3 * 2 * dx])
    width, depth = (cols - 1) * dx, (rows - 1) * dy
    assert surface_area(v, f).sum() == pytest.approx(width * depth * np.hypot(1, 0.3))
    n = np.asarray(mesh.vertex_normals)
    np.testing.assert_allclose(n, np.tile([-0.3, 0, 1] / np.hypot(1, 0.3), (len(v), 1)),
                               atol=1e-12)
    uv = np.asarray(mesh.triangle_uvs)
    assert uv.shape == (3 * len(f), 2) and uv.min() == 0.0 and uv.max() == 1.0
    # the UV of each corner is its grid position
    corner = f.ravel()
    np.testing.assert_allclose(uv[:, 0], (corner % cols) / (cols - 1))
    np.testing.assert_allclose(uv[:, 1], (corner // cols) / (rows - 1))


def test_water_mesh_by_threshold():
    z = np.zeros((4, 4))
    z[:, 2:] = 5.0  # a cliff: only the first column of cells has its lowest corner under 1
    w = water_mesh(z, 1.0, spacing=2.0)
    v = np.asarray(w.vertices)
    assert np.all(v[:, 2] == 1.0)
    assert len(w.triangles) == 2 * 3 * 2  # 3 rows x 2 columns of wet cells
    assert surface_area(v, np.asarray(w.triangles)).sum() == pytest.approx(3 * 2 * 4.0)
    assert np.allclose(np.asarray(w.vertex_normals), [0, 0, 1])
    dry = water_mesh(z, -1.0)
    assert len(dry.triangles) == 0


def test_fractal_terrain_methods():
    for method in ("diamond_square", "fbm", "ridged"):
        z = fractal_terrain(65, rng=np.random.default_rng(0), method=method, height=2.0)
        assert z.shape == (65, 65)
        assert z.std() == pytest.approx(2.0) and abs(z.mean()) < 1e-9
        again = fractal_terrain(65, rng=np.random.default_rng(0), method=method, height=2.0)
        assert z.tobytes() == again.tobytes()


def test_tileable_terrain_is_seamless():
    z = tileable_terrain(65, rng=np.random.default_rng(1), frequency=4, octaves=4)
    assert np.array_equal(z[:, 0], z[:, -1]) and np.array_equal(z[0], z[-1])
    tiled = np.hstack([z, z[:, 1:]])  # two tiles sharing the seam column
    steps = np.abs(np.diff(tiled, axis=1))
    seam = steps[:, 63:65].max()
    assert seam <= steps.max()  # no cliff at the seam


def test_bad_input():
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="size"):
        fractal_terrain(100, rng=rng)
    with pytest.raises(ValueError, match="hurst"):
        fractal_terrain(33, rng=rng, hurst=1.2)
    with pytest.raises(ValueError, match="method"):
        fractal_terrain(33, rng=rng, method="voronoi")
    with pytest.raises(ValueError, match="heights"):
        heightfield_to_mesh(np.array([[0.0, np.inf], [0.0, 0.0]]))
    with pytest.raises(ValueError, match="spacing"):
        heightfield_to_mesh(np.zeros((3, 3)), spacing=0.0)
