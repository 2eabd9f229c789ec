import json

import numpy as np
import pytest

from core.io.mesh import read_mesh
from core.meshes import is_closed
from data_synth.scenes import build_scene, scene_names
from scanamp.cli import main


def test_builtin_scenes():
    assert {"primitives", "object"} <= set(scene_names())
    b = build_scene("object")
    ext = np.ptp(np.asarray(b.object_mesh("object").vertices), axis=0)
    assert 0.12 < ext.max() < 0.19  # about 15 cm across
    assert is_closed(b.object_mesh("object"))
    assert np.asarray(b.object_mesh("object").vertices)[:, 2].min() == pytest.approx(0, abs=1e-9)


def test_columns_scene_has_thin_columns_on_steps():
    """The multi-view stereo detail scene: six columns 14 mm across and 10 cm high stand
    on the top of three steps and carry a lintel."""
    b = build_scene("columns")
    assert "columns" in scene_names()
    tops = []
    for i in range(1, 7):
        col = b.object_mesh(f"column{i}")
        ext = np.ptp(np.asarray(col.vertices), axis=0)
        assert ext[0] == pytest.approx(0.014, abs=5e-4) and ext[2] == pytest.approx(0.1)
        tops.append(np.asarray(col.vertices)[:, 2].min())
    step3 = np.asarray(b.object_mesh("step3").vertices)
    np.testing.assert_allclose(tops, step3[:, 2].max(), atol=1e-9)  # on the top step
    lintel = np.asarray(b.object_mesh("lintel").vertices)
    assert lintel[:, 2].min() == pytest.approx(0.145, abs=1e-9)  # on the columns' tops


def test_scene_folder_rebuilds_bit_for_bit(tmp_path):
    assert main(["scene", "primitives", "--out", str(tmp_path / "a"), "--seed", "3"]) == 0
    assert main(["scene", str(tmp_path / "a" / "scene.toml"), "--out", str(tmp_path / "b")]) == 0
    for f in ("mesh.ply", "objects/ball.ply", "materials.json", "scene.toml"):
        assert (tmp_path / "a" / f).read_bytes() == (tmp_path / "b" / f).read_bytes(), f
    assert len(read_mesh(tmp_path / "a" / "mesh.ply").triangles) > 1000
    assert json.loads((tmp_path / "a" / "materials.json").read_text())["ball"]["kind"] == "solid"


def test_seed_changes_procedural_shapes():
    a = np.asarray(build_scene("object", seed=1).object_mesh("object").vertices)
    b = np.asarray(build_scene("object", seed=2).object_mesh("object").vertices)
    assert not np.allclose(a, b)


def test_render_cli_and_gt(tmp_path):
    """The ground-truth depth is the scene's: every hit pixel, unprojected with the render's
    camera, lands on the scene's surface; the normals face the camera."""
    import open3d as o3d

    from acquire.camera import Camera
    from scanamp.cli.render import default_view

    out = tmp_path / "v.png"
    assert main(["render", "primitives", "--out", str(out), "--size", "96x72", "--gt",
                 "--supersample", "1"]) == 0
    depth = np.load(tmp_path / "v.gt" / "depth.npy")
    mask = np.load(tmp_path / "v.gt" / "mask.npy")
    normals = np.load(tmp_path / "v.gt" / "normals.npy")
    assert depth.shape == (72, 96) and depth.dtype == np.float32
    assert np.all(depth[mask] > 0) and np.all(depth[~mask] == 0) and 0.05 < mask.mean() < 1
    bundle = build_scene("primitives")
    eye, target = default_view(bundle.bounds())
    cam = Camera.look_at(eye, target, width=96, height=72, fov_deg=50.0)  # render's defaults
    v, u = np.nonzero(mask)
    pts = cam.unproject(np.stack([u, v], 1).astype(float), depth[v, u].astype(float))
    gt = bundle.gt_mesh()
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(gt))
    dist = scene.compute_distance(o3d.core.Tensor(pts.astype(np.float32))).numpy()
    diag = np.linalg.norm(np.ptp(np.asarray(gt.vertices), axis=0))
    assert np.percentile(dist, 99) < 1e-3 * diag  # on the surface (float32 depth)
    to_eye = eye - pts
    facing = np.einsum("ij,ij->i", normals[v, u], to_eye)
    assert (facing > 0).mean() > 0.99


@pytest.mark.parametrize("spec, field", [
    ("[[objects]]\nshape = 'sphere'\n", "objects[0].radius: missing"),
    ("[[objects]]\nshape = 'cone'\n", "objects[0].shape: expected one of"),
    ("[[objects]]\nshape = 'sphere'\nradius = 'big'\n", "objects[0].radius: expected a number"),
    ("[[objects]]\nshape = 'sphere'\nradius = -1.0\n", "objects[0]: radius"),
    ("[[lights]]\ntype = 'spot'\n[[objects]]\nshape='sphere'\nradius=1.0\n", "lights[0].type"),
    ("objects = [", "malformed TOML"),
])
def test_bad_specs_exit_2_with_one_line(tmp_path, capsys, spec, field):
    p = tmp_path / "bad.toml"
    p.write_text(spec)
    assert main(["scene", str(p), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "bad.toml" in err[0]
    assert field in err[0]
    assert not (tmp_path / "out").exists()


def test_unknown_scene_name(tmp_path, capsys):
    assert main(["scene", "nope", "--out", str(tmp_path / "o")]) == 2
    assert "unknown scene" in capsys.readouterr().err
