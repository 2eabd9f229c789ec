"""Implicit surfaces and hypertexture: exact shapes without noise, bounded amplification."""

import numpy as np
import pytest

from core.meshes import make_mesh
from procgen.implicit import (
    architexture,
    fractal_egg,
    hypertexture,
    isosurface,
    mesh_sdf,
    sphere_sdf,
    sweep_sdf,
)


@pytest.fixture(scope="module")
def sphere_mesh():
    import open3d as o3d

    return o3d.geometry.TriangleMesh.create_sphere(radius=1.0, resolution=30)


def test_no_noise_gives_the_shape_back():
    mesh = hypertexture(sphere_sdf(radius=1.0), bounds=((-1.5,) * 3, (1.5,) * 3),
                        resolution=32, amplitude=0.0)
    v = np.asarray(mesh.vertices)
    step = 3.0 / 31
    assert np.abs(np.linalg.norm(v, axis=1) - 1.0).max() < step / 4
    assert mesh.is_watertight()
    assert mesh.get_volume() == pytest.approx(4 / 3 * np.pi, rel=0.02)
    n = np.asarray(mesh.vertex_normals)
    assert np.all(np.einsum("ij,ij->i", n, v) > 0)  # outwards


def test_noise_displaces_within_the_amplitude():
    amp = 0.1
    mesh = hypertexture(sphere_sdf(radius=1.0), resolution=48, amplitude=amp, noise="fbm",
                        seed=3)
    r = np.linalg.norm(np.asarray(mesh.vertices), axis=1)
    # fBm of 5 octaves with gain 0.5 is bounded by about 2 in magnitude; one voxel of slack
    assert r.min() > 1.0 - 2 * amp - 0.05 and r.max() < 1.0 + 2 * amp + 0.05
    assert r.std() > 0.01  # actually bumpy
    t = hypertexture(sphere_sdf(radius=1.0), resolution=48, amplitude=amp, seed=3)
    rt = np.linalg.norm(np.asarray(t.vertices), axis=1)
    assert rt.min() > 1.0 - 0.05  # turbulence >= 0 only grows the shape


def test_bias_and_gain_change_the_surface():
    a = hypertexture(sphere_sdf(), resolution=24, amplitude=0.1, seed=1)
    b = hypertexture(sphere_sdf(), resolution=24, amplitude=0.1, seed=1, bias=0.7, gain=0.3)
    ra = np.linalg.norm(np.asarray(a.vertices), axis=1).mean()
    rb = np.linalg.norm(np.asarray(b.vertices), axis=1).mean()
    assert rb > ra  # bias > 0.5 raises the density: the surface moves out


def test_mesh_signed_distance_and_amplification(sphere_mesh):
    sdf = mesh_sdf(sphere_mesh)
    d = sdf(np.array([[0.0, 0, 0], [2.0, 0, 0], [0, 0, 0.5]]))
    np.testing.assert_allclose(d, [-1.0, 1.0, -0.5], atol=0.01)
    out = hypertexture(sphere_mesh, resolution=32, amplitude=0.05, seed=2)
    r = np.linalg.norm(np.asarray(out.vertices), axis=1)
    assert 0.95 < r.min() and r.max() < 1.2


def test_sweep_distance_closed_form():
    sdf = sweep_sdf(np.array([[0.0, 0, 0], [2.0, 0, 0], [2.0, 2.0, 0]]), 0.25)
    p = np.array([[1.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [3.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    np.testing.assert_allclose(sdf(p), [0.75, 0.75, 0.75, -0.25])
    mesh = architexture(np.array([[0.0, 0, 0], [1.0, 0, 0]]), 0.2, amplitude=0.0,
                        resolution=40)
    lo, hi = mesh.get_min_bound(), mesh.get_max_bound()
    np.testing.assert_allclose(lo, [-0.2, -0.2, -0.2], atol=0.03)
    np.testing.assert_allclose(hi, [1.2, 0.2, 0.2], atol=0.03)


def test_fractal_egg_is_taller_than_wide():
    egg = fractal_egg(resolution=32, amplitude=0.0)
    lo, hi = egg.get_min_bound(), egg.get_max_bound()
    assert hi[2] == pytest.approx(1.4, abs=0.05) and lo[2] == pytest.approx(-1.0, abs=0.05)
    assert hi[0] == pytest.approx(1.0, abs=0.05)


def test_isosurface_empty_when_not_crossed():
    assert len(isosurface(np.zeros((4, 4, 4)), 0.5).triangles) == 0


def test_bad_input():
    empty = make_mesh(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64))
    with pytest.raises(ValueError, match="mesh"):
        hypertexture(empty)
    with pytest.raises(ValueError, match="resolution"):
        hypertexture(sphere_sdf(), resolution=4)
    with pytest.raises(ValueError, match="noise"):
        hypertexture(sphere_sdf(), noise="worley")
    with pytest.raises(ValueError, match="bias"):
        hypertexture(sphere_sdf(), bias=1.0)
    with pytest.raises(ValueError, match="bounds"):
        hypertexture(lambda p: np.linalg.norm(p, axis=1) - 1)
    with pytest.raises(ValueError, match="shape"):
        hypertexture(42)
