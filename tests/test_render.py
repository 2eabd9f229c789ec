"""The renderer against closed forms, the sensor model, targets and determinism."""

import numpy as np
import open3d as o3d
import pytest

from acquire.camera import Camera
from acquire.render.lights import DirectionalLight, PointLight
from acquire.render.materials import Material
from acquire.render.renderer import render
from acquire.render.scene import RenderScene, SceneObject
from acquire.sensor import Sensor
from acquire.targets import ChArUcoTarget, ChessboardTarget

R_SPHERE = 0.1


@pytest.fixture(scope="module")
def sphere_plane():
    sph = o3d.geometry.TriangleMesh.create_sphere(R_SPHERE, 40)
    plane = o3d.geometry.TriangleMesh.create_box(1, 1, 0.01)
    plane.translate([-0.5, -0.5, -0.01 - R_SPHERE])  # top face at z = -R
    objs = [SceneObject("sphere", sph, Material("solid", [0.8, 0.6, 0.4]), object_id=1,
                        analytic={"type": "sphere", "center": [0, 0, 0], "radius": R_SPHERE}),
            SceneObject("plane", plane, Material(), object_id=2,
                        analytic={"type": "plane", "point": [0, 0, -R_SPHERE],
                                  "normal": [0, 0, 1]})]
    scene = RenderScene(objs, [PointLight([0.3, -0.3, 0.5], 0.5)], 0.1)
    dist = np.array([-0.1, 0.02, 0.001, -0.001, 0.0])
    cam = Camera.look_at([0.05, -0.6, 0.25], [0, 0, -0.02], width=160, height=120,
                         fov_deg=50, dist=dist)
    return scene, cam, render(scene, cam, supersample=2)


def _closed_form_depth(cam, depth_mask, r):
    """z-depth of the analytic sphere / plane along each pixel's ray."""
    H, W = depth_mask.shape
    o, d = cam.rays(cam.pixel_grid())
    oc = o
    A = np.einsum("ij,ij->i", d, d)
    B = 2 * np.einsum("ij,ij->i", oc, d)
    C = np.einsum("ij,ij->i", oc, oc) - r * r
    disc = B * B - 4 * A * C
    with np.errstate(invalid="ignore"):
        t_s = (-B - np.sqrt(disc)) / (2 * A)
    t_p = (-r - o[:, 2]) / d[:, 2]
    t_p = np.where((t_p > 0) & (np.abs(o[:, 0] + t_p * d[:, 0]) < 0.5)
                   & (np.abs(o[:, 1] + t_p * d[:, 1]) < 0.5), t_p, np.inf)
    t = np.where(disc > 0, np.minimum(t_s, t_p), t_p)
    return t.reshape(H, W)


def test_depth_matches_closed_form(sphere_plane):
    scene, cam, r = sphere_plane
    ref = _closed_form_depth(cam, r.mask, R_SPHERE)
    # interior pixels only: silhouette pixels of the faceted sphere may differ in which
    # surface the ray meets first
    inside = r.mask & np.isfinite(ref)
    near_edge = np.abs(r.depth - ref) > 1e-3
    assert near_edge[inside].mean() < 0.02
    good = inside & ~near_edge
    assert good.sum() > 0.5 * r.mask.size
    assert np.max(np.abs(r.depth[good] - ref[good])) < 1e-6


def test_normals_ids_and_shadow(sphere_plane):
    scene, cam, r = sphere_plane
    ids = set(np.unique(r.object_id).tolist())
    assert ids == {-1, 1, 2}
    n = r.normals[r.object_id == 1]
    p = r.points[r.object_id == 1]
    cos = np.einsum("ij,ij->i", n, p / np.linalg.norm(p, axis=1, keepdims=True))
    assert np.all(cos > 0.999)
    # Every plane pixel against the closed form: shadowed where the segment to the light
    # meets the sphere (ambient only), else albedo * (ambient + I cos / d^2).
    sel = (r.object_id == 2) & (r.depth > 0)
    sel[:1] = sel[-1:] = False
    sel[:, :1] = sel[:, -1:] = False
    p = r.points[sel].astype(np.float64)
    L = np.array([0.3, -0.3, 0.5])
    d = L - p
    dist2 = np.einsum("ij,ij->i", d, d)
    tc = np.clip(-np.einsum("ij,ij->i", p, d) / dist2, 0, 1)
    closest = p + tc[:, None] * d
    shadow = np.linalg.norm(closest, axis=1) < R_SPHERE
    lit = 0.7 * (0.1 + 0.5 * (d[:, 2] / np.sqrt(dist2)) / dist2)
    expect = np.where(shadow, 0.07, lit)
    err = np.abs(r.radiance[sel][:, 0] - expect)
    # supersampled pixels straddling the shadow edge are mixtures: allow a few
    assert shadow.sum() > 50
    assert np.mean(err < 2e-3) > 0.97


def test_lambert_point_light_closed_form():
    plane = o3d.geometry.TriangleMesh.create_box(2, 2, 0.01)
    plane.translate([-1, -1, -0.01])
    scene = RenderScene([SceneObject("p", plane, Material(albedo=[0.5, 0.5, 0.5]))],
                        [PointLight([0, 0, 1.0], 2.0)], ambient=0.0)
    cam = Camera.look_at([0, 0, 0.5], [0, 0, 0], up=(0, 1, 0), width=41, height=41,
                         fov_deg=60)
    rad = render(scene, cam, supersample=1).radiance
    # centre pixel: E = I cos / r^2 = 2 * 1 / 1, radiance = albedo * E = 1.0
    assert rad[20, 20, 0] == pytest.approx(1.0, rel=1e-5)


def test_render_is_deterministic_and_sensor_seeded(sphere_plane):
    scene, cam, r = sphere_plane
    r2 = render(scene, cam, supersample=2)
    assert r.radiance.tobytes() == r2.radiance.tobytes()
    s = Sensor(read_noise=3.0, blur_sigma=0.7, vignetting=0.3)
    a = s.apply(r.radiance, np.random.default_rng(7))
    b = s.apply(r.radiance, np.random.default_rng(7))
    c = s.apply(r.radiance, np.random.default_rng(8))
    assert a.tobytes() == b.tobytes() and a.tobytes() != c.tobytes()
    assert a.dtype == np.uint8


def test_sensor_noise_statistics():
    s = Sensor(full_well=10000.0, read_noise=5.0, bit_depth=16)
    rad = np.full((200, 200), 0.25)
    dn = s.apply(rad, np.random.default_rng(0)).astype(float)
    e = dn / 65535 * 10000
    assert e.mean() == pytest.approx(2500, rel=0.01)
    # variance = shot (mean electrons) + read^2 (+ quantization, negligible at 16 bits)
    assert e.var() == pytest.approx(2500 + 25, rel=0.05)
    sat = Sensor.ideal().apply(np.full((4, 4), 3.0), np.random.default_rng(0))
    assert np.all(sat == 255)
    with pytest.raises(ValueError, match="bit_depth"):
        Sensor(bit_depth=12)


@pytest.mark.parametrize("target", [ChArUcoTarget(), ChessboardTarget()])
def test_targets_detected_at_projected_corners(target):
    w, h = target.size_m()
    scene = RenderScene([target.scene_object("board", np.eye(4))],
                        [DirectionalLight([0.1, 0.1, 1], 0.8)], 0.2)
    cam = Camera.look_at([w / 2 + 0.04, h / 2 - 0.03, -0.25], [w / 2, h / 2, 0], up=(0, -1, 0),
                         width=480, height=360, fov_deg=50)
    img = Sensor.ideal().apply(render(scene, cam, supersample=3).radiance,
                               np.random.default_rng(0))
    ids, corners = target.detect(img)
    assert len(ids) >= 0.8 * len(target.corner_points())
    px, _ = cam.project(target.corner_points()[ids])
    err = np.linalg.norm(px - corners, axis=1)
    assert np.sqrt(np.mean(err ** 2)) < 0.1  # sub-pixel: the renderer is faithful
