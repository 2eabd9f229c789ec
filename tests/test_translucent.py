"""Thin translucent sheets (issue 17): a leaf lit from behind shows the light it lets
through, ``transmission * albedo * E``; lit from the front it reflects the rest; the two
add up to the albedo (energy conserved); the bounce carries light through the sheet."""

import numpy as np
import pytest

from acquire.camera import Camera
from acquire.render.lights import DirectionalLight
from acquire.render.materials import Material
from acquire.render.renderer import render
from acquire.render.scene import RenderScene, SceneObject
from core.meshes import make_mesh

ALBEDO = np.array([0.35, 0.8, 0.25])


def _sheet(t, light_dir):
    sheet = make_mesh(np.array([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1.0]]),
                      np.array([[0, 1, 2], [0, 2, 3]]))
    mat = Material(albedo=ALBEDO, brdf="translucent", transmission=t)
    scene = RenderScene([SceneObject("leaf", sheet, material=mat)],
                        lights=[DirectionalLight(np.asarray(light_dir, float), intensity=1.0)],
                        ambient=0.0)
    cam = Camera.look_at([0.0, -2.0, 0.0], [0.0, 0.0, 0.0], width=32, height=24, fov_deg=30)
    return render(scene, cam, supersample=1).radiance[12, 16]


@pytest.mark.parametrize("t", [0.0, 0.3, 0.7, 1.0])
def test_a_leaf_lets_through_its_transmission_and_reflects_the_rest(t):
    behind = _sheet(t, [0.0, -1.0, 0.0])      # the light travels toward the camera
    front = _sheet(t, [0.0, 1.0, 0.0])        # from the camera's side
    np.testing.assert_allclose(behind, t * ALBEDO, rtol=1e-6)
    np.testing.assert_allclose(front, (1 - t) * ALBEDO, rtol=1e-6)
    np.testing.assert_allclose(behind + front, ALBEDO, rtol=1e-6)   # nothing made or lost
    oblique = _sheet(t, [0.0, -np.cos(np.radians(60)), -np.sin(np.radians(60))])
    np.testing.assert_allclose(oblique, t * ALBEDO * 0.5, rtol=1e-6)   # cos 60


def test_the_bounce_carries_light_through_a_sheet():
    """A canopy over a white floor, the sun above, the camera under the canopy looking
    up: it sees the sun's light the canopy lets through (none when opaque) plus, with
    the bounce, the floor's light reflected by the canopy's underside."""
    canopy = make_mesh(np.array([[-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1.0]]),
                       np.array([[0, 1, 2], [0, 2, 3]]))
    floor = make_mesh(np.array([[-3, -3, 0], [3, -3, 0], [3, 3, 0], [-3, 3, 0.0]]),
                      np.array([[0, 1, 2], [0, 2, 3]]))
    sun = DirectionalLight(np.array([0.0, 0.0, -1.0]), intensity=1.0)
    cam = Camera.look_at([0.0, 0.0, 0.3], [0.0, 0.0, 1.0], up=(0, 1, 0), width=16,
                         height=12, fov_deg=30)
    out = {}
    for t in (0.0, 0.6):
        mats = [Material(albedo=ALBEDO, brdf="translucent", transmission=t),
                Material(albedo=np.full(3, 0.9))]
        scene = RenderScene([SceneObject("canopy", canopy, material=mats[0]),
                             SceneObject("floor", floor, material=mats[1], object_id=1)],
                            lights=[sun], ambient=0.0)
        direct = render(scene, cam, supersample=1).radiance.mean(axis=(0, 1))
        both = render(scene, cam, supersample=4, bounces=1, seed=0).radiance.mean(axis=(0, 1))
        out[t] = (direct, both)
    np.testing.assert_allclose(out[0.6][0], 0.6 * ALBEDO, rtol=1e-5)   # the sun, through
    assert np.all(out[0.0][0] == 0)                  # opaque from below: only the bounce
    assert np.all(out[0.0][1] > 0)                   # the floor lights its underside
    assert np.all(out[0.6][1] > out[0.6][0])


@pytest.mark.parametrize("t", [0.2, 0.6])
def test_a_laser_behind_a_sheet_shows_its_stripe_through_it(t):
    """The laser plate's sheet mirrored to the far side of a thin translucent plate meets
    it on the same line: the camera sees the stripe in the same place, with the light
    let through, ``t / (1 - t)`` of the stripe the sheet reflects from the front."""
    from acquire.laser.sheet import LaserRenderer, LaserSheet
    from data_synth.plates import laser_plate

    lp = laser_plate(Material(albedo=ALBEDO, brdf="translucent", transmission=t))
    m = np.array([1.0, 1.0, -1.0])
    behind = LaserSheet(lp.laser.origin * m, lp.laser.normal * m, lp.laser.direction * m,
                        lp.laser.fan_angle, lp.laser.thickness, lp.laser.power,
                        lp.laser.color)
    r = LaserRenderer(lp.scene, lp.camera)
    front = r.frame(lp.camera.cam_from_world, lp.laser).radiance.astype(float)
    back = r.frame(lp.camera.cam_from_world, behind).radiance.astype(float)
    row = len(front) // 2
    assert front[row].max() > 0
    assert np.argmax(back[row]) == np.argmax(front[row])
    assert back[row].max() / front[row].max() == pytest.approx(t / (1 - t), rel=1e-3)
