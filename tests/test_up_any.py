"""Up on any reconstruction, without trusting the winding: the project's scenes (whole, and
as a capture from above sees them: no undersides) and facades (whole, and as a street-level
capture sees them), each with its winding as written and reversed, under random
rotations: within 10 degrees on every one. The winding is then turned so the ground faces
up, and the forest recipe plants on such a mesh."""

import logging

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from core.meshes import mesh_arrays
from data_synth.facades import facade_mesh
from data_synth.fixtures import ring_of_eyes, seen_triangles
from data_synth.scenes import build_scene
from reconstruct.surface.up import orient_winding, up_from_mesh

Z = np.array([0.0, 0.0, 1.0])


def _angle(a, b) -> float:
    return float(np.degrees(np.arccos(np.clip(np.dot(a, b), -1.0, 1.0))))


def _facade(seed):
    rng = np.random.default_rng(seed)
    return facade_mesh(rng, width=rng.uniform(12, 30), height=rng.uniform(9, 15),
                       ground_depth=rng.uniform(3, 6), floors=int(rng.integers(3, 5)),
                       bays=int(rng.integers(4, 8)), rotate=False)


def _cases():
    out = {}
    for name in ("columns", "demo", "object", "primitives"):
        v, f = mesh_arrays(build_scene(name).gt_mesh())
        out[name] = (v, f, Z)
        out[f"{name}, seen from above"] = (v, seen_triangles(v, f, ring_of_eyes(v), rays=90), Z)
    for seed in range(3):
        v, f, up = _facade(seed)
        out[f"facade {seed}"] = (v, f, up)
        # a street-level capture: cameras across the street, at head height and a little
        # above, looking at the facade (the wall faces -y, its foot at y = 0)
        lo, hi = v.min(0), v.max(0)
        xs = np.linspace(lo[0], hi[0], 6)
        eyes = np.concatenate([np.stack([xs, np.full(6, lo[1] - 8.0), np.full(6, z)], 1)
                               for z in (1.7, 6.0)])
        out[f"facade {seed}, from the street"] = (
            v, seen_triangles(v, f, eyes, target=0.5 * (lo + hi), fov_deg=90, rays=80), up)
    return out


CASES = _cases()


@pytest.mark.parametrize("name", list(CASES))
def test_up_within_10_degrees_whatever_the_winding(name):
    v, f, up = CASES[name]
    for seed in (0, 1):
        R = Rotation.random(random_state=seed).as_matrix()
        for tris in (f, f[:, ::-1]):
            est = up_from_mesh(v @ R.T, tris)
            assert _angle(est.up, R @ up) < 10.0, (name, seed, est.detail)
            d = est.decision
            assert 0 < d["confidence"] <= 1 and d["confidence"] == d["margin"]


def test_orient_winding_turns_the_ground_up():
    v, f, up = CASES["demo, seen from above"]
    g, flipped = orient_winding(v, f[:, ::-1], up)
    assert flipped and np.array_equal(g, f)
    g, flipped = orient_winding(v, f, up)
    assert not flipped and np.array_equal(g, f)
    # a closed object: its underside faces down (outward), its top up: kept as it is
    import open3d as o3d

    ball = o3d.geometry.TriangleMesh.create_sphere(0.5, 12)
    bv, bf = mesh_arrays(ball)
    assert not orient_winding(bv, bf, Z)[1] and orient_winding(bv, bf[:, ::-1], Z)[1]


def test_a_close_call_logs_the_flag(caplog):
    # a 20 x 10 wall on a 20 x 10 strip of ground and nothing else: an L that reads
    # either way
    v = np.array([[0, 0, 0], [20, 0, 0], [20, 0, 10], [0, 0, 10],
                  [0, -10, 0], [20, -10, 0]], float)
    f = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 1], [4, 1, 0]])
    with caplog.at_level(logging.WARNING, logger="reconstruct.surface.up"):
        est = up_from_mesh(v, f)
    assert est.close and "--up" in caplog.text and "low confidence" in caplog.text
    assert est.decision["runner_up"]["angle_deg"] > 45
    # cameras in front of the wall and above the ground settle it
    eyes = np.array([[x, -8.0, z] for x in (2.0, 10.0, 18.0) for z in (1.7, 4.0)])
    for R in (np.eye(3), Rotation.random(random_state=4).as_matrix()):
        got = up_from_mesh(v @ R.T, f, centres=eyes @ R.T)
        assert _angle(got.up, R @ Z) < 1e-6 or _angle(got.up, R @ [0, -1.0, 0]) < 1e-6
        assert got.decision["runner_up"] is not None


def test_the_forest_recipe_plants_on_a_reversed_rotated_mesh(tmp_path):
    import tomllib

    from core.io.mesh import write_mesh
    from core.meshes import make_mesh
    from scanamp.amplify import run
    from scanamp.amplify.recipe import RECIPE_DIR

    v, f, _ = CASES["columns, seen from above"]
    R = Rotation.random(random_state=7).as_matrix()
    path = tmp_path / "rec.ply"
    write_mesh(path, make_mesh(v @ R.T, f[:, ::-1]))
    recipe = tomllib.loads((RECIPE_DIR / "forest.toml").read_text())
    recipe["render"] = {"width": 64, "height": 48}
    recipe["step"] = [s for s in recipe["step"] if s["kind"] == "scatter"]  # no remesh
    recipe["step"][0].update(variants=1, steps=3, max_plants=12)
    out = run(path, recipe, tmp_path / "out", seed=1)
    import json

    rep = json.loads((out / "report.json").read_text())
    assert _angle(np.array(rep["up"]["up"]), R @ Z) < 10.0
    assert rep["winding_reversed"] is True
    assert rep["steps"][0]["plants"] >= 6
