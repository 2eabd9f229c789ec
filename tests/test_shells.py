"""Seashells: the five shape classes by measurable properties; closed meshes."""

import numpy as np
import pytest

from procgen.shells import SHAPES, CortieParams, cortie_points, cortie_shell, helicospiral_shell
from procgen.sweeps import edge_manifold_report, mesh_volume


def _extent(v):
    e = v.max(0) - v.min(0)
    return e[2] / max(e[0], e[1])


@pytest.mark.parametrize("name", sorted(SHAPES))
def test_shapes_are_closed_oriented_surfaces(name):
    v, f = cortie_shell(name, n_theta=120, n_s=16)
    rep = edge_manifold_report(f)
    assert rep["boundary"] == rep["nonmanifold"] == rep["inconsistent"] == 0
    assert mesh_volume(v, f) > 0


def test_shape_classes():
    ext = {name: _extent(cortie_shell(name, n_theta=200, n_s=16)[0]) for name in SHAPES}
    assert ext["turbinate"] > 1.5          # a tall spire
    assert ext["discoid"] < 0.5            # flat
    # discoid: beta = 90 puts the coiling centre line in one plane
    th = np.linspace(0, 20, 50)
    centre = cortie_points(CortieParams(beta=90, a=1e-9, b=1e-9), th, np.zeros(1))[:, 0]
    assert np.ptp(centre[:, 2]) < 1e-6
    # patelliform: most of the surface belongs to the last half turn (rapid expansion)
    p = SHAPES["patelliform"]
    assert np.exp(np.pi / np.tan(np.radians(p.alpha))) > 8
    # tubular: successive whorls do not touch (centre lines farther apart than the two
    # tube radii, which grow with the whorl)
    t = SHAPES["tubular"]
    growth = np.exp(2 * np.pi / np.tan(np.radians(t.alpha)))
    thin = CortieParams(**{**t.__dict__, "a": 1e-9, "b": 1e-9})
    c = cortie_points(thin, np.array([0.0, 2 * np.pi]), np.zeros(1))[:, 0]
    assert np.linalg.norm(c[1] - c[0]) > t.a * (1 + growth)
    # spherical: the aperture is large against the distance to the axis
    s = SHAPES["spherical"]
    assert max(s.a, s.b) > 0.4 * s.A


def test_growth_is_exponential():
    p = CortieParams()
    pts = cortie_points(p, np.array([0.0, 2 * np.pi]), np.array([0.0]))[:, 0]
    ratio = np.linalg.norm(pts[1, :2]) / np.linalg.norm(pts[0, :2])
    assert ratio == pytest.approx(np.exp(2 * np.pi / np.tan(np.radians(p.alpha))), rel=1e-9)


def test_chirality_mirrors():
    a = cortie_points(CortieParams(D=1), np.linspace(0, 6, 10), np.linspace(0, 3, 4))
    b = cortie_points(CortieParams(D=-1), np.linspace(0, 6, 10), np.linspace(0, 3, 4))
    np.testing.assert_allclose(a[..., 0], -b[..., 0])
    np.testing.assert_allclose(a[..., 1:], b[..., 1:])


def test_helicospiral_shell():
    v, f = helicospiral_shell(turns=4, expansion=2, spire=1.5, n_path=200, n_profile=16)
    rep = edge_manifold_report(f)
    assert rep["boundary"] == rep["nonmanifold"] == rep["inconsistent"] == 0
    flat, _ = helicospiral_shell(turns=4, expansion=2, spire=0.0, n_path=200, n_profile=16)
    assert np.ptp(flat[:, 2]) < np.ptp(v[:, 2])
    with pytest.raises(ValueError, match="expansion"):
        helicospiral_shell(expansion=0.5)
    with pytest.raises(ValueError, match="params"):
        cortie_shell("conical")
