import numpy as np
import open3d as o3d
import pytest

from simulate.colliders import MeshCollider
from simulate.collisions import ContactParams, collide
from simulate.forces import ForceSet, Gravity
from simulate.particles import advance_local

G = 9.81


@pytest.fixture(scope="module")
def floor():
    box = o3d.geometry.TriangleMesh.create_box(4, 4, 1)
    box.translate((-2, -2, -1))  # top face at z = 0
    return MeshCollider(box)


def _run(col, x, v, h, steps, params, inside=None, forces=None):
    fs = forces or ForceSet([Gravity()])
    for _ in range(steps):
        x0, v0 = x.copy(), v.copy()
        advance_local(fs, 0, x, v, 1.0, h, method="rk4")
        x, v, st = collide(col, x0, v0, x, v, h, params, inside=inside)
        yield x, v, st


@pytest.mark.parametrize("e", [0.5, 0.8])
def test_bouncing_ball_apex_heights(floor, e):
    h0 = 1.0
    x0, v0 = np.array([[0.1, 0.2, h0]]), np.zeros((1, 3))
    apex, bounces = [], 0
    for x, v, st in _run(floor, x0, v0, 1 / 97, 3000, ContactParams(restitution=e,
                                                                   rest_speed=1e-9)):
        bounces += st.impacts
        if bounces > len(apex) and v[0, 2] > 0:
            apex.append(x[0, 2] + v[0, 2] ** 2 / (2 * G))  # exact in free flight
        if len(apex) == 5:
            break
    n = np.arange(1, 6)
    np.testing.assert_allclose(apex, e ** (2 * n) * h0, rtol=1e-6)


def test_several_bounces_within_one_step(floor):
    # a fast, low bounce: 0.2 m/s up from 1 mm gives several impacts in a 0.2 s step
    x, v = np.array([[0, 0, 1e-3]]), np.array([[0.0, 0.0, 0.5]])
    x0, v0 = x.copy(), v.copy()
    h = 0.2
    advance_local(ForceSet([Gravity()]), 0, x, v, 1.0, h)
    x1, v1, st = collide(floor, x0, v0, x, v, h, ContactParams(restitution=0.5,
                                                                 rest_speed=1e-6))
    assert st.impacts >= 3
    assert x1[0, 2] >= 0
    # energy never grows
    assert 0.5 * v1[0, 2] ** 2 + G * x1[0, 2] <= 0.5 * 0.25 + G * 1e-3


def test_resting_contact_and_friction(floor):
    # sliding along the floor: friction mu g decelerates it and it stops and stays
    x0, v0 = np.array([[0, 0, 1e-9]]), np.array([[1.0, 0, 0]])
    params = ContactParams(restitution=0.3, friction=0.5, rest_speed=0.05)
    *_, (x, v, _) = _run(floor, x0, v0, 0.01, 60, params)
    assert np.abs(v).max() < 1e-9
    # stopping distance v^2 / (2 mu g), to within a step's travel
    assert x[0, 0] == pytest.approx(1.0 / (2 * 0.5 * G), abs=0.011)
    assert 0 <= x[0, 2] < 1e-4  # resting contacts keep a float32-resolvable gap


@pytest.mark.parametrize("shape", ["sphere", "torus", "box"])
def test_no_escape_from_closed_mesh(shape):
    mesh = {"sphere": lambda: o3d.geometry.TriangleMesh.create_sphere(1.0, 12),
            "torus": lambda: o3d.geometry.TriangleMesh.create_torus(1.0, 0.4, 24, 12),
            "box": lambda: o3d.geometry.TriangleMesh.create_box(1, 1, 1)}[shape]()
    col = MeshCollider(mesh)
    rng = np.random.default_rng(1)
    p = rng.uniform(*col.bounds, (20000, 3))
    p = p[col.inside(p) & (np.abs(col.signed_distance(p)) > 0.02)][:1000]
    v = rng.normal(size=p.shape)
    v *= 40 / np.linalg.norm(v, axis=1, keepdims=True)  # 0.4 m per step: several bounces
    inside = np.ones(len(p), bool)
    worst, impacts = -np.inf, 0
    for x, _v, st in _run(col, p, v, 0.01, 100, ContactParams(restitution=0.9, friction=0.1),
                         inside=inside):
        impacts += st.impacts
        worst = max(worst, col.signed_distance(x).max())
    assert len(p) == 1000 and impacts > 10_000
    assert worst <= 1e-6  # 1000 particles x 100 steps = 10^5 particle-steps, none outside


def test_params_validation():
    with pytest.raises(ValueError, match="restitution"):
        ContactParams(restitution=1.5)
    with pytest.raises(ValueError, match="max_bounces"):
        ContactParams(max_bounces=0)
