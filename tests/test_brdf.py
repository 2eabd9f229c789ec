"""Reflectance models (issue 17): normalised, reciprocal, energy-conserving (furnace tests),
a closed-form albedo, and a glossy render whose highlight sits at the mirror point."""

import numpy as np
import pytest

from acquire.render.brdf import dielectric_f0, ggx, ggx_d, lambert, smith_g
from acquire.render.materials import Material


def _dirs(theta_deg, phi=0.0):
    t = np.radians(theta_deg)
    return np.array([[np.sin(t) * np.cos(phi), np.sin(t) * np.sin(phi), np.cos(t)]])


def _albedo_is(wo_deg: float, roughness: float, f0=1.0, n=400_000, seed=0):
    """Directional albedo of the GGX specular lobe by importance sampling its normals:
    ``E = mean(F G (wo.h) / ((n.wo)(n.h)))`` (the estimator of Walter et al. 2007)."""
    rng = np.random.default_rng(seed)
    a = roughness ** 2
    u1, u2 = rng.random(n), rng.random(n)
    ch = np.sqrt((1 - u2) / (1 + (a * a - 1) * u2))
    sh, ph = np.sqrt(1 - ch * ch), 2 * np.pi * u1
    h = np.stack([sh * np.cos(ph), sh * np.sin(ph), ch], 1)
    wo = np.repeat(_dirs(wo_deg), n, 0)
    oh = np.einsum("ij,ij->i", wo, h)
    wi = 2 * oh[:, None] * h - wo
    ok = wi[:, 2] > 0
    F = f0 + (1 - f0) * (1 - oh) ** 5
    w = np.where(ok, F * smith_g(wi[:, 2], wo[:, 2], a) * oh / (wo[:, 2] * ch), 0.0)
    return w.mean(), w.std() / np.sqrt(n)


@pytest.mark.parametrize("alpha", [0.01, 0.1, 0.5, 1.0])
def test_ggx_distribution_is_normalised(alpha):
    # int D(h) (n.h) dw_h = 2 pi int D(cos t) cos t sin t dt, by a fine quadrature in t
    t = np.linspace(0, np.pi / 2, 2_000_001)
    val = ggx_d(np.cos(t), alpha) * np.cos(t) * np.sin(t)
    assert 2 * np.pi * np.trapezoid(val, t) == pytest.approx(1.0, abs=1e-3)


def test_furnace_closed_form_at_roughness_one():
    """alpha = 1 makes D = 1/pi and G = 2 cos/(1 + cos) at normal view: the albedo of a
    perfect reflector is 1 - ln 2 exactly (derived in acquire/brdf's test)."""
    e, se = _albedo_is(0.0, 1.0)
    assert e == pytest.approx(1.0 - np.log(2.0), abs=4 * se + 1e-3)


@pytest.mark.parametrize("roughness", [0.05, 0.3, 0.7, 1.0])
@pytest.mark.parametrize("view", [0.0, 45.0, 75.0])
def test_a_perfect_conductor_never_reflects_more_than_it_receives(roughness, view):
    e, se = _albedo_is(view, roughness)
    assert e <= 1.0 + 4 * se
    if roughness <= 0.05 and view < 60:
        assert e > 0.97       # a smooth mirror loses almost nothing


def test_dielectric_and_lambert_furnaces_and_reciprocity():
    rng = np.random.default_rng(1)
    n = 400_000
    z = rng.random(n)                       # uniform hemisphere (pdf 1 / 2 pi)
    r, ph = np.sqrt(1 - z * z), 2 * np.pi * rng.random(n)
    wi = np.stack([r * np.cos(ph), r * np.sin(ph), z], 1)
    nrm = np.tile([0.0, 0.0, 1.0], (n, 1))
    for view in (0.0, 60.0):
        wo = np.repeat(_dirs(view), n, 0)
        lam = lambert(wi, wo, nrm, [0.8, 0.5, 0.2])
        e = (lam * wi[:, 2:3]).mean(0) * 2 * np.pi
        np.testing.assert_allclose(e, [0.8, 0.5, 0.2], rtol=0.01)
        coat = ggx(wi, wo, nrm, roughness=0.6, f0=dielectric_f0(1.5), diffuse=[1, 1, 1])
        assert (coat[:, 0] * wi[:, 2]).mean() * 2 * np.pi <= 1.0
    # reciprocity f(wi, wo) = f(wo, wi), all models
    a = rng.normal(size=(500, 3)) * [1, 1, 0.3] + [0, 0, 1]
    b = rng.normal(size=(500, 3)) * [1, 1, 0.3] + [0, 0, 1]
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    nn = np.tile([0.0, 0.0, 1.0], (500, 1))
    for kw in ({"f0": 0.9}, {"f0": 0.04, "diffuse": [0.5, 0.5, 0.5]}):
        np.testing.assert_allclose(ggx(a, b, nn, roughness=0.4, **kw),
                                   ggx(b, a, nn, roughness=0.4, **kw), rtol=1e-12)


def test_a_glossy_plane_shows_its_highlight_at_the_mirror_point():
    """A polished metal floor, a point light and a camera: the brightest pixel is where
    the light's mirror image is seen (half-vector = normal); the same floor matte is
    brightest under the light instead."""
    from acquire.camera import Camera
    from acquire.render.lights import PointLight
    from acquire.render.renderer import render
    from acquire.render.scene import RenderScene, SceneObject
    from core.meshes import make_mesh

    floor = make_mesh(np.array([[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0.0]]),
                      np.array([[0, 1, 2], [0, 2, 3]]))
    light = PointLight(position=np.array([0.5, 0.0, 1.0]), intensity=1.0)
    cam = Camera.look_at([-1.0, 0.0, 1.0], [0.0, 0.0, 0.0], width=96, height=72, fov_deg=70)
    # mirror point: on the floor where light and camera make equal angles: x = -0.25
    want = cam.project(np.array([[-0.25, 0.0, 0.0]]))[0][0]
    for brdf, expect in (("conductor", want), ("lambert", None)):
        mat = Material(albedo=np.array([0.9, 0.9, 0.9]), brdf=brdf, roughness=0.15)
        scene = RenderScene([SceneObject("floor", floor, material=mat)], lights=[light],
                            ambient=0.0)
        img = render(scene, cam, supersample=1).radiance[..., 0]
        y, x = np.unravel_index(np.argmax(img), img.shape)
        if expect is not None:
            assert abs(x - expect[0]) <= 2 and abs(y - expect[1]) <= 2
        else:   # matte: brightest under the light (x = 0.5), far from the mirror point
            under = cam.project(np.array([[0.5, 0.0, 0.0]]))[0][0]
            assert abs(y - under[1]) <= 2 and abs(y - want[1]) > 10
