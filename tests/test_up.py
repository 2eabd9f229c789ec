"""Up of a reconstruction in its own frame (issue 19): within 5 degrees on rotated scenes
whose up is known, from the mesh alone and from the cameras beside it."""

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from acquire.camera import look_at_cam_from_world
from core.meshes import mesh_arrays
from data_synth.scenes import build_scene
from reconstruct.surface.up import estimate_up, find_camera_model, up_from_cameras, up_from_mesh


def _angle(a, b) -> float:
    return float(np.degrees(np.arccos(np.clip(np.dot(a, b), -1.0, 1.0))))


@pytest.fixture(scope="module")
def scenes():
    return {name: mesh_arrays(build_scene(name).gt_mesh()) for name in ("demo", "primitives")}


@pytest.mark.parametrize("name", ["demo", "primitives"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_up_from_the_mesh_under_a_random_rotation(scenes, name, seed):
    v, f = scenes[name]
    R = Rotation.random(random_state=seed).as_matrix()
    est = up_from_mesh(v @ R.T, f)
    assert est.source == "mesh"
    assert _angle(est.up, R @ [0.0, 0.0, 1.0]) < 5.0
    # the sign too: flipping every face must not turn it upside down when the heights say
    flipped = up_from_mesh(v @ R.T, f[:, ::-1])
    assert _angle(flipped.up, R @ [0.0, 0.0, 1.0]) < 5.0 or "normals agree" in flipped.detail


def _ring(R: np.ndarray, rng, n=12, roll_deg=4.0):
    """world_from_cam of upright cameras on a ring around the origin (z up), each rolled
    a little, then the whole rig rotated by R into a reconstruction's own frame."""
    out = []
    for k in range(n):
        ang = 2 * np.pi * k / n
        eye = np.array([3 * np.cos(ang), 3 * np.sin(ang), 1.5])
        T = np.linalg.inv(look_at_cam_from_world(eye, [0.0, 0.0, 0.3]))
        roll = Rotation.from_rotvec(T[:3, 2] * np.radians(rng.normal(0, roll_deg))).as_matrix()
        T[:3, :3] = roll @ T[:3, :3]
        W = np.eye(4)
        W[:3, :3] = R
        out.append(W @ T)
    return out


def test_up_from_cameras_beside_the_mesh(tmp_path):
    from acquire.camera import Camera
    from acquire.sfm.nerfstudio import write_transforms

    rng = np.random.default_rng(0)
    R = Rotation.random(random_state=5).as_matrix()
    poses = _ring(R, rng)
    est = up_from_cameras(poses)
    assert _angle(est.up, R @ [0.0, 0.0, 1.0]) < 5.0 and est.support > 0.9
    # the same through a transforms.json found beside a mesh
    cams = [Camera(64, 48, 50.0, 50.0, 31.5, 23.5, np.zeros(5), np.linalg.inv(T))
            for T in poses]
    rec = tmp_path / "rec"
    rec.mkdir()
    write_transforms(rec / "transforms.json", cams, [f"images/{i}.png" for i in range(12)])
    mesh_path = rec / "mesh.ply"
    found = find_camera_model(mesh_path)
    assert found == rec / "transforms.json"
    v = np.random.default_rng(1).normal(size=(30, 3))  # a mesh whose own up is meaningless
    f = np.array([[0, 1, 2], [3, 4, 5], [6, 7, 8]])
    got = estimate_up(v, f, cameras=found)
    assert got.source == "cameras" and _angle(got.up, R @ [0.0, 0.0, 1.0]) < 5.0
    assert estimate_up(v, f, up=(0, 0, 2), cameras=found).to_dict()["up"] == [0.0, 0.0, 1.0]
    json.dumps(got.to_dict())


def test_bad_up_names_itself():
    with pytest.raises(ValueError, match="up"):
        estimate_up(np.zeros((3, 3)), np.array([[0, 1, 2]]), up=(0, 0, 0))


def test_ground_and_objects_of_the_demo_scene():
    """The morphological ground filter against the scene's own parts: the terrain is
    ground, the tree, shell and object stand on it (only their feet count as ground)."""
    from reconstruct.surface.ground import ground_mask

    bundle = build_scene("demo")
    terrain = np.concatenate([np.full(len(o.mesh.vertices), o.name == "terrain")
                              for o in bundle.render_scene.objects])
    v, f = mesh_arrays(bundle.gt_mesh())
    g = ground_mask(v, f)
    assert g[terrain].mean() > 0.95 and g[~terrain].mean() < 0.06
    # in its own frame and scale: rotate back to up with the estimate, scale 100x
    R = Rotation.random(random_state=3).as_matrix()
    from core.frames import rotation_between

    est = up_from_mesh(100 * v @ R.T, f)
    g2 = ground_mask(100 * v @ R.T @ rotation_between(est.up, [0, 0, 1]).T, f)
    assert np.mean(g2 == g) > 0.97
