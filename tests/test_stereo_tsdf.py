"""TSDF fusion: analytic sphere depth maps from several cameras fuse to the sphere."""

import numpy as np
import pytest

from acquire.camera import Camera
from reconstruct.surface.tsdf import fuse_depth_maps


def _sphere_depth(cam: Camera, radius: float) -> np.ndarray:
    """Z-depth of a sphere of ``radius`` at the origin (closed form ray intersection)."""
    px = cam.pixel_grid()
    o, d = cam.rays(px)  # t = z-depth
    b = np.einsum("ij,ij->i", o, d)
    a = np.einsum("ij,ij->i", d, d)
    c = np.einsum("ij,ij->i", o, o) - radius**2
    disc = b * b - a * c
    t = np.where(disc > 0, (-b - np.sqrt(np.maximum(disc, 0))) / a, 0.0)
    return t.reshape(cam.height, cam.width).astype(np.float32)


@pytest.mark.parametrize("dist", [None, (0.05, -0.01, 0.0, 0.0, 0.0)])
def test_fused_sphere_lies_on_radius(dist):
    r = 0.1
    cams = []
    for ang in np.radians([0, 90, 180, 270]):
        eye = 0.5 * np.array([np.cos(ang), np.sin(ang), 0.3])
        cams.append(Camera.look_at(eye, [0, 0, 0], width=160, height=120, fov_deg=40, dist=dist))
    cams.append(Camera.look_at([0, 0.01, 0.5], [0, 0, 0], width=160, height=120, fov_deg=40,
                               dist=dist))
    cams.append(Camera.look_at([0, 0.01, -0.5], [0, 0, 0], width=160, height=120, fov_deg=40,
                               dist=dist))
    depths = [_sphere_depth(c, r) for c in cams]
    mesh = fuse_depth_maps(depths, cams, voxel_size=0.004, depth_max=2.0)
    v = np.asarray(mesh.vertices)
    assert len(v) > 1000
    rad = np.linalg.norm(v, axis=1)
    # marching cubes on a 4 mm grid: vertices within half a voxel of the true surface
    assert np.percentile(np.abs(rad - r), 95) < 0.002
    # coverage: vertex directions span the whole sphere
    dirs = v / rad[:, None]
    assert dirs[:, 2].min() < -0.9 and dirs[:, 2].max() > 0.9


def test_shape_mismatch_names_argument():
    cam = Camera.look_at([0, -1, 0], [0, 0, 0], width=32, height=24)
    with pytest.raises(ValueError, match=r"depths\[0\]"):
        fuse_depth_maps([np.ones((10, 10))], [cam], voxel_size=0.01)


def test_empty_depth_gives_empty_mesh():
    cam = Camera.look_at([0, -1, 0], [0, 0, 0], width=32, height=24)
    mesh = fuse_depth_maps([np.zeros((24, 32))], [cam], voxel_size=0.01)
    assert len(mesh.vertices) == 0


def test_same_depth_maps_give_the_same_bytes():
    """Open3D's block hash map extracts in a different order on every run; the mesh must
    not (same seed, same bytes): two fusions of the same maps are byte-identical, and the
    order is the geometric one."""
    cams = [Camera.look_at(0.4 * np.array([np.cos(a), np.sin(a), 0.4]), [0, 0, 0],
                           width=120, height=90, fov_deg=40)
            for a in np.linspace(0, 2 * np.pi, 5, endpoint=False)]
    depths = [_sphere_depth(c, 0.1) for c in cams]
    meshes = [fuse_depth_maps(depths, cams, voxel_size=0.005, depth_max=2.0) for _ in range(3)]
    first = (np.asarray(meshes[0].vertices).tobytes(), np.asarray(meshes[0].triangles).tobytes())
    for m in meshes[1:]:
        assert (np.asarray(m.vertices).tobytes(), np.asarray(m.triangles).tobytes()) == first
    v = np.asarray(meshes[0].vertices)
    assert np.all(np.diff(v[:, 0]) >= 0)
