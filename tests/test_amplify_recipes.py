"""scanamp.amplify: recipe validation, the runner's outputs, seeds, and the CLI."""

import json

import numpy as np
import open3d as o3d
import pytest

from core.io.image import read_image
from core.io.mesh import read_mesh, write_mesh
from core.meshes import make_mesh, mesh_arrays
from core.validate import InputError
from scanamp.amplify import KINDS, load_recipe, recipe_names, run
from scanamp.cli import main

SHIPPED = {"displace", "terrain", "forest", "vines", "hypertexture", "snow", "drape", "flock",
           "city"}


@pytest.fixture(scope="module")
def small_mesh(tmp_path_factory):
    """A closed lumpy blob standing on z = 0 (a small scan stand-in, 162 vertices)."""
    ball = o3d.geometry.TriangleMesh.create_icosahedron(0.5)
    ball = ball.subdivide_loop(2)
    v, f = mesh_arrays(ball)
    v = v / np.linalg.norm(v, axis=1, keepdims=True) * 0.5
    v *= 1.0 + 0.15 * np.sin(3 * v[:, [0]]) * np.cos(4 * v[:, [1]])
    v[:, 2] -= v[:, 2].min()
    path = tmp_path_factory.mktemp("mesh") / "blob.ply"
    write_mesh(path, make_mesh(v, f))
    return path


def test_every_shipped_recipe_loads():
    assert SHIPPED <= set(recipe_names())
    for name in recipe_names():
        rec = load_recipe(name)
        assert rec.steps and all(s.kind in KINDS for s in rec.steps)


def test_run_writes_mesh_renders_and_report(small_mesh, tmp_path):
    recipe = {"step": [{"kind": "displace", "edge": 0.5, "amplitude": 0.2},
                       {"kind": "scatter", "density": 40.0, "slope_max_deg": 40.0,
                        "variants": 2, "height": 0.15},
                       {"kind": "sweep", "count": 3, "length": 0.5, "step": 0.02}],
              "render": {"width": 64, "height": 48}}
    out = run(small_mesh, recipe, tmp_path / "out", seed=3)
    rep = json.loads((out / "report.json").read_text())
    assert [s["kind"] for s in rep["steps"]] == ["displace", "scatter", "sweep"]
    assert rep["seed"] == 3 and rep["input"]["triangles"] == 320
    assert rep["steps"][0]["after"]["triangles"] > rep["steps"][0]["before"]["triangles"]
    assert rep["steps"][1]["plants"] > 0
    final = read_mesh(out / "mesh.ply")
    assert len(final.triangles) == rep["output"]["triangles"]
    parts = sum(len(read_mesh(out / f"{n}.ply").triangles) for n in ("surface", "bark",
                                                                      "leaf", "vines"))
    assert parts == len(final.triangles)
    # every vertex labelled and coloured: the parts' labels count their vertices exactly
    from core.io.mesh import read_labeled_mesh
    from scanamp.amplify.labels import LABELS

    lm = read_labeled_mesh(out / "mesh.ply")
    assert lm["names"] == LABELS
    ids = {name: k for k, name in LABELS.items()}
    assert rep["steps"][1]["parts"] == ["bark", "leaf"]
    for part, label in (("bark", "bark"), ("leaf", "leaf"), ("vines", "vine")):
        n = len(read_mesh(out / f"{part}.ply").vertices)
        assert int((lm["labels"] == ids[label]).sum()) == n
    assert int(np.isin(lm["labels"], [ids["ground"], ids["object"]]).sum()) == \
        len(read_mesh(out / "surface.ply").vertices)
    leaf_rgb = lm["colors"][lm["labels"] == ids["leaf"]]
    assert np.all(leaf_rgb == np.round(np.array([0.35, 0.5, 0.2]) * 255))
    bark_rgb = lm["colors"][lm["labels"] == ids["bark"]]
    assert np.all(bark_rgb == np.round(np.array([0.42, 0.3, 0.2]) * 255))
    assert len(read_mesh(out / "mesh.gltf").triangles) == len(final.triangles)
    before, after = read_image(out / "before.png"), read_image(out / "after.png")
    assert before.shape == after.shape == (48, 64, 3) and np.any(before != after)
    assert not any(p.name.startswith(".") for p in tmp_path.iterdir())   # atomic


def test_same_seed_same_bytes(small_mesh, tmp_path):
    recipe = {"step": [{"kind": "displace", "edge": 0.6, "noise": "ridged"},
                       {"kind": "scatter", "density": 30.0, "variants": 2, "height": 0.1}],
              "render": {"width": 32, "height": 24}}
    a = run(small_mesh, recipe, tmp_path / "a", seed=7)
    b = run(small_mesh, recipe, tmp_path / "b", seed=7)
    c = run(small_mesh, recipe, tmp_path / "c", seed=8)
    for name in ("mesh.ply", "surface.ply", "bark.ply", "leaf.ply", "after.png"):
        assert (a / name).read_bytes() == (b / name).read_bytes()
    assert (a / "mesh.ply").read_bytes() != (c / "mesh.ply").read_bytes()


def _write(tmp_path, text):
    p = tmp_path / "r.toml"
    p.write_text(text)
    return p


@pytest.mark.parametrize("text, field, words", [
    ('[[step]]\nkind = "explode"\n', "step[0].kind", "displace, refine-terrain, scatter"),
    ('[[step]]\nkind = "displace"\namplitude = 12.0\n', "step[0].amplitude", "[0, 10]"),
    ('[[step]]\nkind = "displace"\n[[step]]\nkind = "animate"\nrecipe = "snow"\n',
     "step[1].simulation", "missing"),
    ('[[step]]\nkind = "displace"\nnoise = "worley"\n', "step[0].noise", "fbm, turbulence"),
    ('[[step]]\nkind = "displace"\namplitud = 1.0\n', "step[0].amplitud", "unknown field"),
    ('[[step]]\nkind = "refine-terrain"\ncontrol_size = 30\n', "step[0].control_size",
     "2**k + 1"),
    ('[[step]]\nkind = "animate"\nsimulation = "cloth"\nrecipe = "snow"\n',
     "step[0].recipe", "particles recipe, not cloth"),
    ('[[step]]\nkind = "scatter"\naltitude_range = [0.2]\n', "step[0].altitude_range",
     "list of 2"),
    ('description = "no steps"\n', "step", "missing"),
])
def test_bad_recipes_name_file_and_field(tmp_path, text, field, words):
    p = _write(tmp_path, text)
    with pytest.raises(InputError) as exc:
        load_recipe(p)
    msg = str(exc.value)
    assert str(p) in msg and f"{field}:" in msg and words in msg


def test_cli_bad_recipe_exits_2_with_one_error_line(small_mesh, tmp_path, capsys):
    p = _write(tmp_path, '[[step]]\nkind = "displace"\noctaves = 40\n')
    rc = main(["amplify", str(small_mesh), "--recipe", str(p), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1
    assert err[0].startswith("error:") and str(p) in err[0] and "step[0].octaves" in err[0]
    assert not (tmp_path / "o").exists()
    rc = main(["amplify", str(small_mesh), "--recipe", "nosuch", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and err[-1].startswith("error:") and "displace" in err[-1]
    rc = main(["amplify", str(tmp_path / "missing.ply"), "--recipe", "displace", "--out",
               str(tmp_path / "o")])
    assert rc == 2


def test_cli_end_to_end_with_hypertexture_and_animation(small_mesh, tmp_path):
    p = _write(tmp_path, """
description = "test"
[render]
width = 48
height = 36
[[step]]
kind = "hypertexture"
amplitude = 0.01
resolution = 24
[[step]]
kind = "animate"
simulation = "boids"
recipe = "torus"
n = 12
frames = 4
render = false
""")
    rc = main(["-q", "amplify", str(small_mesh), "--recipe", str(p), "--out",
               str(tmp_path / "o"), "--seed", "2"])
    assert rc == 0
    rep = json.loads((tmp_path / "o" / "report.json").read_text())
    assert [s["kind"] for s in rep["steps"]] == ["hypertexture", "animate"]
    anim = rep["steps"][1]
    assert anim["animation"] == "animation" and anim["result"]["n"] == 12
    boids = json.loads((tmp_path / "o" / "animation" / "report.json").read_text())
    assert boids["steps"] == 4 and boids["mesh"]["closed"]
    assert (tmp_path / "o" / "mesh.ply").is_file()


@pytest.mark.parametrize("seed", [0, 1])
def test_plants_stand_along_the_meshes_own_up(tmp_path, seed):
    """A gently rolling ground in its own frame (up is a random direction): the plants
    stand on it along that up, found from the mesh, and the report says so."""
    from scipy.spatial.transform import Rotation

    from procgen.terrain import heightfield_to_mesh

    x = np.linspace(0, 2 * np.pi, 21)
    hf = 0.02 * np.sin(x)[:, None] * np.cos(x)[None, :]
    v, f = mesh_arrays(heightfield_to_mesh(hf, spacing=0.05))   # 1 m x 1 m
    R = Rotation.random(random_state=seed).as_matrix()
    up = R @ [0.0, 0.0, 1.0]
    path = tmp_path / "ground.ply"
    write_mesh(path, make_mesh(v @ R.T, f))
    recipe = {"step": [{"kind": "scatter", "density": 30.0, "height": 0.1, "variants": 2,
                        "slope_max_deg": 40.0}], "render": {"width": 32, "height": 24}}
    out = run(path, recipe, tmp_path / "out", seed=0)
    rep = json.loads((out / "report.json").read_text())
    assert rep["up"]["source"] == "mesh"
    assert np.degrees(np.arccos(np.clip(np.dot(rep["up"]["up"], up), -1, 1))) < 5.0
    pv = np.vstack([mesh_arrays(read_mesh(out / f"{n}.ply"))[0] for n in ("bark", "leaf")])
    h = pv @ up                                  # heights along the true up
    ground_top = float((v @ R.T @ up).max())
    height = 0.1 * np.sqrt(2.0)                  # 0.1 of the 1.41 m diagonal
    assert h.min() > float((v @ R.T @ up).min()) - 0.01   # nothing grows into the ground
    assert h.max() > ground_top + 0.5 * height            # they stand up, not sideways
    # --up given: used as is
    out2 = run(path, recipe, tmp_path / "out2", seed=0, up=tuple(up))
    assert json.loads((out2 / "report.json").read_text())["up"]["source"] == "given"


def test_variants_scene_and_turntable(small_mesh, tmp_path):
    """--variants: one result per seed and a contact sheet; each result is a scene the
    capture commands accept (one object per label, its meshes standing on z = 0) and,
    asked for, a turntable animation with the frames asked."""
    import imageio.v2 as iio

    from data_synth.scenes import build_scene
    from scanamp.amplify import run_variants

    recipe = {"step": [{"kind": "displace", "edge": 0.0, "amplitude": 0.3},
                       {"kind": "scatter", "density": 40.0, "slope_max_deg": 60.0,
                        "variants": 2, "height": 0.15}],
              "render": {"width": 64, "height": 48}}
    out = run_variants(small_mesh, recipe, tmp_path / "v", seeds=[3, 4], turntable=6)
    a, b = (out / "seed_3" / "mesh.ply").read_bytes(), (out / "seed_4" / "mesh.ply").read_bytes()
    assert a != b
    sheet = read_image(out / "contact_sheet.png")
    assert sheet.shape[1] == 4 * 320 and sheet.std() > 1
    reader = iio.get_reader(out / "seed_3" / "turntable.mp4", format="FFMPEG")
    assert sum(1 for _ in reader) == 6
    scene = build_scene(str(out / "seed_3" / "scene.toml"))
    names = [o.name for o in scene.render_scene.objects]
    assert "bark" in names and set(names) <= {"ground", "object", "bark", "leaf"}
    v, f = mesh_arrays(scene.gt_mesh())
    assert abs(v[:, 2].min()) < 1e-9
    assert len(f) == len(read_mesh(out / "seed_3" / "mesh.ply").triangles)


def test_an_open_scan_collides_as_its_closed_shell(tmp_path, caplog):
    """A reconstruction is open (a ground sheet with a mound): the cloth step builds a
    closed shell to collide with instead of warning that inside/outside is unreliable,
    and the draped cloth rests on the shell, above the surface and never below it."""
    import logging

    from procgen.terrain import heightfield_to_mesh

    x = np.linspace(-1, 1, 25)
    hf = 0.3 * np.exp(-(x[:, None] ** 2 + x[None, :] ** 2) / 0.2)
    path = tmp_path / "mound.ply"
    write_mesh(path, heightfield_to_mesh(hf, spacing=2.0 / 24))   # 2 m x 2 m, open
    recipe = {"step": [{"kind": "animate", "simulation": "cloth", "recipe": "drape",
                        "frames": 6, "size": 0.5, "render": False, "collider_resolution": 64}],
              "render": {"width": 32, "height": 24}}
    with caplog.at_level(logging.WARNING):
        out = run(path, recipe, tmp_path / "out", seed=0)
    assert "not closed" not in caplog.text
    rep = json.loads((out / "report.json").read_text())["steps"][0]
    assert rep["collider"]["closed_input"] is False
    half = rep["collider"]["shell_half_width"]
    assert 0 < half < 0.1 * np.sqrt(8.0)
    cloth, _ = mesh_arrays(read_mesh(out / "cloth.ply"))
    v, f = mesh_arrays(read_mesh(path))

    # over the mound the cloth never sinks into the surface: it rests on the shell
    h = _height_over(v, f, cloth)
    h = h[np.isfinite(h)]
    assert len(h) > 0.25 * len(cloth)            # the cloth is larger than the mound
    assert h.min() == pytest.approx(half, rel=0.25)


def _height_over(v, f, points):
    """Height of ``points`` over the surface ``(v, f)`` along +z (ray cast down)."""
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(v.astype(np.float32)),
                        o3d.core.Tensor(f.astype(np.uint32)))
    top = float(v[:, 2].max()) + 10.0
    rays = np.zeros((len(points), 6), np.float32)
    rays[:, :2], rays[:, 2], rays[:, 5] = points[:, :2], top, -1.0
    t = scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()
    return points[:, 2] - (top - t)


def test_city_recipe_lays_labelled_roads_buildings_and_roofs(tmp_path):
    """The shipped city recipe on a scan's ground with an object on it: roads, buildings
    and roofs each carry their label, and the object keeps its place and label."""
    from core.io.mesh import read_labeled_mesh
    from core.meshes import merge_meshes
    from procgen.terrain import heightfield_to_mesh
    from scanamp.amplify.labels import LABELS

    x = np.linspace(0, 1, 41)
    ground = heightfield_to_mesh(0.01 * np.sin(5 * x)[:, None] * np.ones(41), spacing=0.025)
    rock = o3d.geometry.TriangleMesh.create_sphere(0.12, resolution=12)
    rock.translate((0.7, 0.7, 0.05))
    path = tmp_path / "scan.ply"
    write_mesh(path, merge_meshes([ground, rock]))
    out = run(path, "city", tmp_path / "out", seed=1)
    rep = json.loads((out / "report.json").read_text())["steps"][-1]
    assert rep["parts"] == ["road", "building", "roof"] and rep["buildings_laid"] > 0
    lm = read_labeled_mesh(out / "mesh.ply")
    ids = {name: k for k, name in LABELS.items()}
    for part in ("road", "building", "roof"):
        n = len(read_mesh(out / f"{part}.ply").vertices)
        assert n > 0 and int((lm["labels"] == ids[part]).sum()) == n
    assert (lm["labels"] == ids["object"]).sum() > 0          # the rock is still there


def test_forest_of_weber_penn_species(tmp_path):
    """The scatter step with species: Weber & Penn trees of the named species, each standing
    on the ground at about the height asked, bark and leaves as parts; an unknown species
    names the recipe field."""
    from procgen.terrain import heightfield_to_mesh

    v, f = mesh_arrays(heightfield_to_mesh(np.zeros((11, 11)), spacing=0.1))   # 1 m x 1 m
    path = tmp_path / "ground.ply"
    write_mesh(path, make_mesh(v, f))
    recipe = {"step": [{"kind": "scatter", "density": 8.0, "height": 0.2, "height_jitter": 0.0,
                        "variants": 2, "species": "quaking_aspen, scots_pine"}],
              "render": {"width": 32, "height": 24}}
    out = run(path, recipe, tmp_path / "out", seed=0)
    rep = json.loads((out / "report.json").read_text())
    res = rep["steps"][0]
    assert res["species"] == ["quaking_aspen", "scots_pine"] and res["plants"] >= 3
    bark = mesh_arrays(read_mesh(out / "bark.ply"))
    leaf = mesh_arrays(read_mesh(out / "leaf.ply"))
    assert len(leaf[1]) > 1000 and len(bark[1]) > 1000
    top = max(bark[0][:, 2].max(), leaf[0][:, 2].max())
    height = 0.2 * np.sqrt(2.0)                  # 0.2 of the 1.41 m diagonal
    assert top == pytest.approx(height * 0.98, rel=0.05)   # (bases sunk 2 % into the ground)
    assert bark[0][:, 2].min() > -0.03 * height
    bad = dict(recipe, step=[dict(recipe["step"][0], species="quaking_aspen, baobab")])
    with pytest.raises(InputError, match="baobab") as e:
        load_recipe(bad)
    assert "species" in str(e.value)
