import numpy as np
import pytest

from acquire.camera import Camera
from acquire.render.splats import composite_splats, render_splats


def test_over_blending_is_porter_duff_and_depth_sorted():
    bg = np.full((9, 9, 3), 0.2)
    px = np.array([[4.0, 4.0], [4.0, 4.0]])
    red, green = [1.0, 0, 0], [0, 1.0, 0]
    # Given in near-to-far order: the far (green) one must still be drawn first.
    img = composite_splats(px, np.array([1.0, 2.0]), np.array([red, green]),
                           np.array([2.0, 2.0]), np.array([0.5, 0.5]), bg)
    under = 0.5 * np.array(green) + 0.5 * 0.2
    expect = 0.5 * np.array(red) + 0.5 * under
    np.testing.assert_allclose(img[4, 4], expect, atol=1e-12)
    # Off-centre the weight falls as a Gaussian with sigma = radius / 2.
    one = composite_splats(px[:1], np.ones(1), np.ones((1, 3)), np.array([2.0]), np.ones(1),
                           np.zeros((9, 9, 3)))
    assert one[4, 5, 0] == pytest.approx(np.exp(-1 / 2))


def test_background_depth_occludes():
    bg = np.zeros((5, 5, 3))
    depth = np.full((5, 5), np.inf)
    depth[:, :2] = 0.5  # a wall in front of the left columns
    img = composite_splats(np.array([[2.0, 2.0]]), np.ones(1), np.ones((1, 3)),
                           np.array([4.0]), np.ones(1), bg, background_depth=depth)
    assert img[2, :2].max() == 0 and img[2, 2:].min() > 0.5


def test_render_splats_projects_world_size():
    cam = Camera.look_at([0, -2, 0], [0, 0, 0], width=41, height=41, fov_deg=60)
    img = render_splats(np.zeros((1, 3)), cam, sizes=0.1, alphas=1.0)
    assert img[20, 20].min() == pytest.approx(1.0)
    # radius fx * r / z pixels: sigma = half of it.
    sigma = 0.5 * cam.fx * 0.1 / 2.0
    assert img[20, 23, 0] == pytest.approx(np.exp(-9 / (2 * sigma**2)), rel=1e-9)
    assert render_splats(np.zeros((0, 3)), cam).max() == 0
