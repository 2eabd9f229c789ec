"""Up of an object with no ground, from how it would rest: the quasi-static probabilities
of a box's and a cone's faces against their closed forms (the solid angle each face
subtends from the centre of mass, every face being stable), and up within 10 degrees on
objects resting on a known face (a cone on its base, a figure on a plinth and an animal
on four feet, scanned: no surface where they touch the floor) under random rotations and
either winding."""

import numpy as np
import open3d as o3d
import pytest
from scipy.spatial.transform import Rotation

from core.meshes import mesh_arrays
from reconstruct.surface.up import rest_poses, up_from_mesh

Z = np.array([0.0, 0.0, 1.0])


def _angle(a, b) -> float:
    return float(np.degrees(np.arccos(np.clip(np.dot(a, b), -1.0, 1.0))))


def _rectangle_solid_angle(a, b, d) -> float:
    """Solid angle of an a x b rectangle seen from distance d above its centre."""
    return 4.0 * np.arcsin(a * b / np.sqrt((a * a + 4 * d * d) * (b * b + 4 * d * d)))


def _merge(parts):
    vs, fs, n = [], [], 0
    for v, f in parts:
        vs.append(v)
        fs.append(f + n)
        n += len(v)
    return np.vstack(vs), np.vstack(fs)


def _part(mesh, shift=(0.0, 0.0, 0.0), drop_below: float | None = None):
    """A primitive's arrays moved by ``shift``; with ``drop_below``, its faces lying on
    that height removed (a scan does not see what stands on the floor)."""
    v, f = mesh_arrays(mesh)
    v = v + np.asarray(shift)
    if drop_below is not None:
        f = f[~np.all(v[f][:, :, 2] <= drop_below + 1e-9, axis=1)]
    return v, f


def _figure_on_plinth():
    return _merge([
        _part(o3d.geometry.TriangleMesh.create_box(1.2, 1.2, 0.4), (-0.6, -0.6, 0.0), 0.0),
        _part(o3d.geometry.TriangleMesh.create_cylinder(0.25, 1.4, 24, 4), (0, 0, 1.1)),
        _part(o3d.geometry.TriangleMesh.create_sphere(0.22, 16), (0, 0, 2.0)),
        _part(o3d.geometry.TriangleMesh.create_cylinder(0.08, 0.9, 12, 2)
              .rotate(Rotation.from_euler("y", 90, degrees=True).as_matrix(), (0, 0, 0)),
              (0, 0, 1.5))])


def _animal():
    body = o3d.geometry.TriangleMesh.create_sphere(1.0, 24)
    body.scale(1.0, (0, 0, 0))
    v, f = mesh_arrays(body)
    v = v * [1.2, 0.45, 0.4] + [0, 0, 1.0]  # an ellipsoid body
    legs = [_part(o3d.geometry.TriangleMesh.create_cylinder(0.1, 0.8, 12, 2),
                  (x, y, 0.4), 0.0) for x in (-0.8, 0.8) for y in (-0.25, 0.25)]
    head = _part(o3d.geometry.TriangleMesh.create_sphere(0.3, 16), (1.3, 0, 1.35))
    return _merge([(v, f), *legs, head])


def test_the_quasi_static_probabilities_of_a_box_are_its_faces_solid_angles():
    a, b, c = 4.0, 2.0, 1.0
    v, f = mesh_arrays(o3d.geometry.TriangleMesh.create_box(a, b, c))
    R = Rotation.random(random_state=7).as_matrix()
    poses = rest_poses((v - [a / 2, b / 2, c / 2]) @ R.T, f)
    assert len(poses) == 6
    assert sum(p.probability for p in poses) == pytest.approx(1.0, abs=1e-9)
    want = {0: _rectangle_solid_angle(b, c, a / 2), 1: _rectangle_solid_angle(a, c, b / 2),
            2: _rectangle_solid_angle(a, b, c / 2)}
    for p in poses:
        local = R.T @ p.up
        axis = int(np.argmax(np.abs(local)))
        assert abs(local[axis]) > 1 - 1e-9  # a face's normal
        assert p.probability == pytest.approx(want[axis] / (4 * np.pi), abs=0.012)


def test_a_cone_rests_on_its_base_with_the_probability_of_its_solid_angle():
    r, h = 1.0, 2.0
    v, f = mesh_arrays(o3d.geometry.TriangleMesh.create_cone(r, h, 64, 2))  # base at z = 0
    poses = rest_poses(v, f)
    base = [p for p in poses if _angle(p.up, Z) < 1e-6]
    assert len(base) == 1
    # the centre of mass of a solid cone is h/4 above its base
    half = np.arctan(r / (h / 4))
    assert base[0].probability == pytest.approx((1 - np.cos(half)) / 2, abs=0.015)
    assert poses[0] is base[0]  # the likeliest
    # on its side it touches along a line: a small basin, one of many
    assert all(p.probability < 0.1 for p in poses[1:])


@pytest.mark.parametrize("name", ["cone", "figure on a plinth", "animal on four feet"])
def test_up_of_an_object_with_no_ground_from_how_it_rests(name):
    if name == "cone":
        v, f = mesh_arrays(o3d.geometry.TriangleMesh.create_cone(0.6, 1.5, 48, 2))
    else:
        v, f = _figure_on_plinth() if name == "figure on a plinth" else _animal()
    for seed in range(2):
        R = Rotation.random(random_state=seed).as_matrix()
        for tris in (f, f[:, ::-1]):
            est = up_from_mesh(v @ R.T, tris)
            assert _angle(est.up, R @ Z) < 10.0, (name, seed, est.detail)


def test_a_sheet_has_no_resting_pose():
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    assert rest_poses(v, np.array([[0, 1, 2], [0, 2, 3]])) == []
