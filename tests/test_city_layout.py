"""procgen.amplify.city_layout: a city laid on a ground, following its relief."""

import numpy as np
import open3d as o3d
import pytest

from core.meshes import mesh_arrays
from procgen.amplify.city_layout import lay_city
from procgen.terrain import heightfield_to_mesh


def _ground():
    """1 m x 1 m: a gentle rolling plain on the left half, a 45-degree slope on the right."""
    x = np.linspace(0.0, 1.0, 81)
    X, Y = np.meshgrid(x, x)                  # X along the columns: mesh x
    hf = 0.02 * np.sin(4 * X) * np.cos(3 * Y) + np.where(X > 0.6, X - 0.6, 0.0)
    return mesh_arrays(heightfield_to_mesh(hf, spacing=1.0 / 80))


def _box(lo, hi):
    b = o3d.geometry.TriangleMesh.create_box(*(np.subtract(hi, lo)))
    b.translate(lo)
    return mesh_arrays(b)


def _height_below(v, f, xy):
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(v.astype(np.float32)),
                        o3d.core.Tensor(f.astype(np.uint32)))
    rays = np.zeros((len(xy), 6), np.float32)
    rays[:, :2], rays[:, 2], rays[:, 5] = xy, 10.0, -1.0
    return 10.0 - scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy().astype(float)


@pytest.fixture(scope="module")
def laid():
    v, f = _ground()
    ov, of = _box((0.3, 0.3, -0.05), (0.45, 0.45, 0.2))       # an object on the plain
    return v, f, ov, of, lay_city(v, f, rng=np.random.default_rng(3), object_v=ov,
                                  object_f=of, max_slope_deg=20.0)


def test_roads_follow_the_relief(laid):
    v, f, _, _, lay = laid
    rv, _ = mesh_arrays(lay.roads)
    below = _height_below(v, f, rv[:, :2])
    np.testing.assert_allclose(rv[:, 2] - below, lay.lift, atol=1e-5)
    assert np.ptp(rv[:, 2]) > 0.05               # they climb and dip, not a flat sheet
    assert 0 < lay.roads_kept <= len(lay.city.edges)


def test_buildings_stand_on_the_ground_off_objects_and_slopes(laid):
    v, f, ov, of, lay = laid
    assert lay.buildings_kept > 5
    wv, _ = mesh_arrays(lay.walls)
    rv, _ = mesh_arrays(lay.roofs)
    pts = np.vstack([wv, rv])
    # nothing on the object's footprint, nothing on the 45-degree slope (x > 0.6)
    on_box = np.all((pts[:, :2] > 0.3) & (pts[:, :2] < 0.45), axis=1)
    assert not on_box.any()
    assert pts[:, 0].max() < 0.62
    # each kept building's base is the lowest ground under its footprint
    kept = np.flatnonzero(np.isfinite(lay.base))
    from procgen.amplify.city_layout import _footprint

    for i in kept[:10]:
        fp, fr = lay.city.footprints[i], lay.city.lot_frames[i]
        xy = lay.origin + lay.scale * _footprint(fp, fr[0])
        assert lay.base[i] == pytest.approx(_height_below(v, f, xy).min(), abs=1e-5)
    # roofs face up
    from core.meshes import face_normals

    rv, rf = mesh_arrays(lay.roofs)
    assert np.all(face_normals(rv, rf)[:, 2] > 0.9)


@pytest.mark.parametrize("scale", [0.01, 100.0])
def test_the_same_city_at_any_scale(laid, scale):
    v, f, ov, of, lay = laid
    other = lay_city(v * scale, f, rng=np.random.default_rng(3), object_v=ov * scale,
                     object_f=of, max_slope_deg=20.0)
    assert other.buildings_kept == lay.buildings_kept
    assert other.roads_kept == lay.roads_kept
    a, _ = mesh_arrays(lay.walls)
    b, _ = mesh_arrays(other.walls)
    np.testing.assert_allclose(b / scale, a, atol=1e-6 * np.sqrt(3))


def test_a_ground_without_faces_is_refused():
    with pytest.raises(ValueError, match="ground_f"):
        lay_city(np.zeros((3, 3)), np.empty((0, 3), int), rng=np.random.default_rng(0))
