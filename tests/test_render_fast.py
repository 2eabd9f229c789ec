"""The renderer's compiled paths agree with its general ones: camera rays, the fBm and
constant albedo, and the direct light of point and directional lights (with shadows)
against the same lights through the light protocol."""

import numpy as np
import open3d as o3d
import pytest

from acquire.camera import Camera
from acquire.render.lights import DirectionalLight, PointLight
from acquire.render.materials import Material
from acquire.render.renderer import albedo, camera_rays, cast, render
from acquire.render.scene import RenderScene, SceneObject


class _Protocol:
    """A light seen only through the light protocol (the renderer's general path)."""

    def __init__(self, light):
        self.light = light

    def irradiance(self, points, normals):
        return self.light.irradiance(points, normals)

    def shadow_rays(self, points):
        return self.light.shadow_rays(points)


@pytest.fixture(scope="module")
def scene():
    ball = o3d.geometry.TriangleMesh.create_sphere(0.08, 30)
    ball.translate([0.02, 0.0, 0.08])
    floor = o3d.geometry.TriangleMesh.create_box(0.8, 0.8, 0.01)
    floor.translate([-0.4, -0.4, -0.01])
    crate = o3d.geometry.TriangleMesh.create_box(0.1, 0.1, 0.12)
    crate.translate([-0.2, 0.05, 0.0])
    T = np.eye(4)
    T[:3, 3] = [0.01, -0.02, 0.0]
    objs = [SceneObject("ball", ball, Material("solid", [0.8, 0.6, 0.4], scale=30.0, seed=7)),
            SceneObject("floor", floor, Material("solid", [0.5, 0.7, 0.6], contrast=0.5)),
            SceneObject("crate", crate, Material("constant", [0.3, 0.4, 0.9]),
                        world_from_object=T)]
    lights = [PointLight([0.3, -0.4, 0.6], 0.8, color=[1.0, 0.9, 0.8]),
              DirectionalLight([-0.3, 0.4, -0.9], 0.4)]
    return RenderScene(objs, lights, 0.05, background=np.array([0.1, 0.2, 0.3]))


@pytest.fixture(scope="module")
def camera():
    return Camera.look_at([0.45, -0.6, 0.4], [0, 0, 0.05], width=96, height=72, fov_deg=55)


@pytest.mark.parametrize("s", [1, 2, 3])
def test_camera_rays_are_the_pixel_grid_rays(camera, s):
    o, d = camera_rays(camera, s)
    o_ref, d_ref = camera.rays(camera.pixel_grid(supersample=s))
    assert np.array_equal(o, o_ref)
    assert np.allclose(d, d_ref, rtol=0, atol=1e-14)


def test_distorted_camera_takes_the_general_path():
    cam = Camera.look_at([0.4, -0.5, 0.3], [0, 0, 0], width=40, height=30, fov_deg=50,
                         dist=np.array([-0.2, 0.05, 0.0, 0.0, 0.0]))
    o, d = camera_rays(cam, 2)
    o_ref, d_ref = cam.rays(cam.pixel_grid(supersample=2))
    assert np.array_equal(d, d_ref) and np.array_equal(o, o_ref)


def test_albedo_matches_each_material(scene, camera):
    hits = cast(scene, *camera_rays(camera, 1))
    alb = albedo(scene, hits)
    assert np.all(alb[~hits.hit] == 0)
    for i, obj in enumerate(scene.objects):
        sel = np.flatnonzero(hits.obj == i)
        assert sel.size > 50
        Tinv = np.linalg.inv(obj.world_from_object)
        ref = obj.material.albedo_at(hits.points[sel] @ Tinv[:3, :3].T + Tinv[:3, 3])
        assert np.allclose(alb[sel], ref, rtol=0, atol=1e-12)
    # the texture varies (a constant answer would pass the crate alone)
    assert np.ptp(alb[hits.obj == 0, 0]) > 0.2


def test_direct_light_matches_the_light_protocol(scene, camera):
    fast = render(scene, camera, supersample=2)
    general = render(scene, camera, supersample=2,
                     lights=[_Protocol(light) for light in scene.lights])
    assert np.allclose(fast.radiance, general.radiance, rtol=0, atol=1e-6)
    # the scene has shadows and both lights matter
    lit_by_one = render(scene, camera, supersample=2, lights=scene.lights[:1])
    assert np.abs(fast.radiance - lit_by_one.radiance).max() > 0.05
    one = render(scene, camera, supersample=1)
    assert (~one.mask).sum() > 100
    assert np.all(one.radiance[~one.mask] == np.float32([0.1, 0.2, 0.3]))


@pytest.mark.parametrize("n", [0, 1, 2047, 2048, 2049, 100_003])
def test_scattered_blocks_visit_every_row_once(n):
    from acquire.render._kernels import BLOCK, block_rows, n_blocks

    m = n_blocks(n)
    seen = np.zeros(n, np.int64)
    starts = []
    for k in range(m):
        lo, hi = block_rows(k, n)
        seen[lo:hi] += 1
        starts.append(lo)
    assert np.all(seen == 1)
    if m > 2:   # neighbouring blocks of the loop are far apart in the rows
        assert abs(starts[1] - starts[0]) > BLOCK


def test_centre_rays_from_the_sub_rays_are_the_cast_centre_rays(scene, camera, monkeypatch):
    import acquire.render.renderer as R

    ball = o3d.geometry.TriangleMesh.create_sphere(0.06, 12)   # coarse: faces differ
    ball.translate([-0.15, -0.15, 0.06])
    sphere = SceneObject("sphere", ball, Material("constant", [0.9, 0.9, 0.9]),
                         analytic={"type": "sphere", "center": (-0.15, -0.15, 0.06),
                                   "radius": 0.06})
    sc = RenderScene([*scene.objects, sphere], scene.lights, 0.05)
    hits = cast(sc, *camera_rays(camera, 2))
    cast_rows = []
    embree = R._embree_hits
    monkeypatch.setattr(R, "_embree_hits", lambda s, o, d: cast_rows.append(len(o))
                        or embree(s, o, d))
    derived = R.centre_hits(sc, camera, hits, 2)
    n_cast = sum(cast_rows)
    ref = cast(sc, *camera_rays(camera, 1))
    for f in ("hit", "t", "points", "normals", "obj"):
        assert np.array_equal(getattr(derived, f), getattr(ref, f)), f
    meshes = ref.obj != 3     # on the analytic sphere the triangle is a neighbour's
    assert np.array_equal(derived.tri[meshes], ref.tri[meshes])
    assert (ref.obj == 3).sum() > 100
    # only the pixels on an edge (between objects or triangles) were cast
    assert 0 < n_cast < 0.3 * camera.width * camera.height
