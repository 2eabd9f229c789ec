"""LiDAR worlds and their reconstruction: forest scenes keep their truth, the ground filter,
DTM/CHM rasters, tree detection and lidaRtRee's matching, on closed-form cases."""

from __future__ import annotations

import numpy as np
import pytest

from acquire.lidar.labels import part_code
from core.io.las import LasWriter, read_las
from core.io.raster import Raster, read_raster, write_raster
from core.io.trees import read_tree_table, write_tree_table
from core.validate import InputError
from scanamp.cli import main

E0, N0 = 512_000.0, 5_403_000.0  # projected coordinates (UTM-like), kept everywhere
EPSG = "EPSG:25832"

INVENTORY = """x,y,height,dbh,crown_radius,species
{x1},{y1},24.5,0.35,3.0,PIAB
{x2},{y2},18.0,,,Fagus sylvatica
{x3},{y3},21.0,,2.5,Pinus sylvestris
{x4},{y4},16.0,,,Tilia cordata
{x5},{y5},15.5,,,FASY
"""
TREES_XY = [(12.0, 12.0), (28.0, 14.0), (14.0, 29.0), (29.0, 30.0), (29.3, 30.2)]


def _inventory_text():
    kw = {}
    for i, (x, y) in enumerate(TREES_XY, 1):
        kw[f"x{i}"], kw[f"y{i}"] = E0 + x, N0 + y
    return INVENTORY.format(**kw)


@pytest.fixture(scope="session")
def forest(tmp_path_factory):
    """A five-tree plot (two coppice stems 0.36 m apart) at UTM coordinates, built by the
    CLI; returns (scene folder, rebuilt bundle)."""
    from data_synth.scenes import load_scene

    d = tmp_path_factory.mktemp("forest")
    inv = d / "inv.csv"
    inv.write_text(_inventory_text())
    out = d / "scene"
    assert main(["-q", "scene", "forest", "--inventory", str(inv), "--out", str(out),
                 "--forest.understory", "0", "--forest.variants", "1", "--forest.margin", "6",
                 "--forest.relief", "1.5", "--forest.crs", EPSG]) == 0
    return out, load_scene(out)


def test_forest_truth_matches_its_geometry(forest):
    out, b = forest
    truth = read_tree_table(out / "trees.csv")
    want = np.array([[E0 + x, N0 + y] for x, y in TREES_XY])
    np.testing.assert_allclose(np.column_stack([truth["x"], truth["y"]]), want, atol=5e-4)
    np.testing.assert_allclose(truth["height"], [24.5, 18.0, 21.0, 16.0, 15.5])
    assert list(truth["species"]) == ["PIAB", "FASY", "PISY", "GENB", "FASY"]
    assert b.origin.tolist() == [E0 + 10, N0 + 10, 0.0]  # local geometry about the origin
    # (the trees' south-west corner, rounded down to 10 m)
    objs = {o.name: o for o in b.render_scene.objects}
    for k in range(5):
        wood, leaf = objs[f"tree{k + 1:05d}.wood"], objs[f"tree{k + 1:05d}.leaf"]
        v = np.vstack([wood.world_arrays()[0], leaf.world_arrays()[0]])
        assert np.abs(v[:, :2] - (want[k] - b.origin[:2])).max() < 12  # local, near the stem
        top = v[:, 2].max() + b.origin[2]
        assert top == pytest.approx(truth["z_ground"][k] + truth["height"][k], abs=1e-3)  # mm CSV
        assert set(np.unique(wood.part_labels)) == {part_code("trunk"), part_code("branch")}
        assert set(np.unique(leaf.part_labels)) == {part_code("leaf")}
        assert wood.object_id == leaf.object_id == k + 1
    assert set(np.unique(objs["ground"].part_labels)) == {part_code("ground")}
    # the DTM truth is the ground mesh: its grid, in the inventory's coordinates and CRS
    dtm = read_raster(out / "dtm.tif")
    gv = objs["ground"].world_arrays()[0]
    assert dtm.values.size == len(gv)
    np.testing.assert_allclose(np.sort(dtm.values.ravel()), np.sort(gv[:, 2]), atol=1e-4)
    assert dtm.x0 == pytest.approx(gv[:, 0].min() + b.origin[0], abs=1e-6)
    assert dtm.y0 == pytest.approx(gv[:, 1].min() + b.origin[1], abs=1e-6)
    from rasterio.crs import CRS

    assert CRS.from_wkt(dtm.crs_wkt) == CRS.from_user_input(EPSG)


def test_forest_rebuilds_bit_for_bit(forest):
    from data_synth.scenes import load_scene

    out, b = forest
    again = load_scene(out)
    for o1, o2 in zip(b.render_scene.objects, again.render_scene.objects, strict=True):
        np.testing.assert_array_equal(np.asarray(o1.mesh.vertices), np.asarray(o2.mesh.vertices))


@pytest.mark.parametrize("text, field", [
    ("x,y\n1,2\n", "height"),
    ("x,y,height\n1,2,nan\n", "height"),
    ("x,y,height\n1,2,-3\n", "height"),
    ("x,y,height\n1,2,abc\n", "height"),
    ("x,y,height\n1,2,20\n3,4,18\n1,2,20\n", "x, y, height"),
])
def test_bad_inventory_exits_2_with_one_line(tmp_path, capsys, text, field):
    inv = tmp_path / "inv.csv"
    inv.write_text(text)
    out = tmp_path / "scene"
    assert main(["scene", "forest", "--inventory", str(inv), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {inv}: {field}: "), err
    assert not out.exists()


def test_coppice_stems_decimetres_apart_are_two_trees(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("x,y,height\n5.0,5.0,20\n5.3,5.0,20\n5.0,5.0,19.5\n")
    assert len(read_tree_table(p)["x"]) == 3


def _terrain(x, y):
    return 300 + 0.08 * x - 0.05 * y + 1.5 * np.sin(x / 9.0) * np.cos(y / 11.0)


def _synthetic_survey(rng, n=40_000, size=60.0):
    """Points on a known terrain, with two box buildings and canopy points above it."""
    xy = rng.uniform(0, size, (n, 2))
    z = _terrain(xy[:, 0], xy[:, 1])
    kind = np.zeros(n, int)  # 0 ground, 1 box roof, 2 canopy
    for x0, y0, w, h in ((15, 15, 8, 6), (40, 35, 10, 9)):
        inb = (np.abs(xy[:, 0] - x0) < w / 2) & (np.abs(xy[:, 1] - y0) < w / 2)
        kind[inb] = 1
        z[inb] += h
    canopy = (kind == 0) & (rng.random(n) < 0.35)
    kind[canopy] = 2
    z[canopy] += rng.uniform(1.5, 20, canopy.sum())
    return np.column_stack([xy, z]), kind


def test_csf_finds_the_ground_of_a_known_terrain():
    from reconstruct.lidar import GroundOptions, classify_ground, dtm_errors, dtm_from_ground

    rng = np.random.default_rng(3)
    pts, kind = _synthetic_survey(rng)
    g = classify_ground(pts, options=GroundOptions(rigidness=2, cloth_resolution=0.5))
    inner = np.all((pts[:, :2] > 5) & (pts[:, :2] < 55), axis=1)
    # the cloth's edges are less sure; inside, every ground point and nothing else
    err = np.mean(g[inner] != (kind[inner] == 0))
    assert err < 0.005, err
    dtm = dtm_from_ground(pts[g], bounds=(5, 5, 55, 55), res=1.0)
    xs, ys = dtm.centres()
    truth = Raster(_terrain(xs[None, :], ys[:, None]), x0=xs[0], y0=ys[0], res=1.0)
    assert dtm_errors(dtm, truth)["rmse"] < 0.05


def test_dtm_chm_values_and_crs_round_trip(tmp_path):
    from rasterio.crs import CRS

    from reconstruct.lidar import canopy_height, dtm_from_ground

    # a plane of ground and one point per cell 7 m above it
    xs = np.arange(0.25, 20, 0.5)
    X, Y = np.meshgrid(xs, xs)
    ground = np.column_stack([X.ravel() + E0, Y.ravel() + N0, 200 + 0.1 * X.ravel()])
    wkt = CRS.from_user_input(EPSG).to_wkt()
    dtm = dtm_from_ground(ground, bounds=(E0, N0, E0 + 20, N0 + 20), res=1.0, crs_wkt=wkt)
    cx, cy = dtm.centres()
    np.testing.assert_allclose(dtm.values, np.broadcast_to(200 + 0.1 * (cx - E0), dtm.values.shape),
                               atol=1e-6)
    canopy = ground + [0.0, 0.0, 7.0]
    chm = canopy_height(np.vstack([ground, canopy]), dtm)
    # (the outer half cell samples the DTM's edge, not its extrapolation)
    np.testing.assert_allclose(chm.values[1:-1, 1:-1], 7.0, atol=1e-6)
    for name, r in (("dtm.tif", dtm), ("chm.tif", chm)):
        back = read_raster(write_raster(tmp_path / name, r))
        np.testing.assert_allclose(back.values, r.values, atol=1e-4)  # float32 on disk
        assert (back.x0, back.y0, back.res) == (r.x0, r.y0, r.res)
        assert CRS.from_wkt(back.crs_wkt) == CRS.from_user_input(EPSG)


def test_tree_detection_finds_every_gaussian_crown():
    from reconstruct.lidar import detect_trees, tree_scores

    rng = np.random.default_rng(5)
    res = 0.5
    xs = np.arange(0, 80, res)
    X, Y = np.meshgrid(xs, xs)
    # 30 crowns on a jittered grid (no two closer than 8 m), heights 10-35 m
    gx, gy = np.meshgrid(np.arange(8, 75, 13.0), np.arange(8, 75, 13.0))
    pos = np.column_stack([gx.ravel(), gy.ravel()])[:30] + rng.uniform(-2, 2, (30, 2))
    h = rng.uniform(10, 35, 30)
    width = 1.2 + 0.08 * h
    z = np.zeros_like(X)
    for (x, y), hh, w in zip(pos, h, width, strict=True):
        z = np.maximum(z, hh * np.exp(-((X - x) ** 2 + (Y - y) ** 2) / (2 * w * w)))
    t = detect_trees(Raster(z, x0=0.0, y0=0.0, res=res))
    assert len(t["x"]) == 30
    s = tree_scores(np.column_stack([pos, h]), np.column_stack([t["x"], t["y"], t["height"]]))
    assert s["f"] == 1.0 and s["position_rmse"] < res
    # a crown's top is its highest grid sample: at most half a cell's diagonal off its peak
    pairs = np.argsort(-h)
    drop = h[pairs] * (1 - np.exp(-(res * res / 2) / (2 * width[pairs] ** 2)))
    assert np.all((t["height"] <= h[pairs] + 1e-9) & (t["height"] >= h[pairs] - drop - 1e-9))
    # each crown is its own watershed region, all of them about the size of their bump
    assert np.all(t["crown_area"] > np.pi * width[np.argsort(-h)] ** 2)


def test_matching_rule_on_hand_made_cases():
    from reconstruct.lidar import match_trees, tree_scores

    ref = np.array([[0.0, 0.0, 20.0]])
    limit = 2.1 + 0.14 * 20  # 4.9 m in 3-D
    inside = np.array([[limit - 0.01, 0.0, 20.0]])
    outside = np.array([[limit + 0.01, 0.0, 20.0]])
    assert len(match_trees(ref, inside)) == 1 and len(match_trees(ref, outside)) == 0
    # the height difference counts (3-D distance): 3 m across and 4 m lower is 5 m away
    assert len(match_trees(ref, np.array([[3.0, 0.0, 16.0]]))) == 0
    assert len(match_trees(ref, np.array([[3.0, 0.0, 17.0]]))) == 1
    # one to one: of two detections near one reference tree, the closer is matched
    two = np.array([[1.5, 0.0, 20.0], [0.5, 0.0, 20.0]])
    assert match_trees(ref, two).tolist() == [[0, 1]]
    s = tree_scores(ref, two)
    assert (s["matched"], s["commission"], s["f"]) == (1, 0.5, pytest.approx(2 / 3))
    # two references, one detection between them: it goes to the one it is relatively
    # closer to (distance / limit), here the farther but taller one
    refs = np.array([[0.0, 0.0, 10.0], [4.4, 0.0, 12.0]])  # limits 3.5 m and 3.78 m
    det = np.array([[2.1, 0.0, 11.0]])  # 2.326 m (index 0.6646) and 2.508 m (0.6635)
    assert match_trees(refs, det).tolist() == [[1, 0]]
    # nothing found: every tree omitted, F = 0 (not an error)
    none = tree_scores(refs, np.empty((0, 3)))
    assert (none["matched"], none["omission"], none["f"]) == (0, 1.0, 0.0)


def _write_survey(path, pts, cls, *, wkt=None):
    n = len(pts)
    with LasWriter(path, origin=pts.min(axis=0), crs_wkt=wkt) as w:
        w.write({"x": pts[:, 0], "y": pts[:, 1], "z": pts[:, 2], "classification": cls,
                 "return_number": np.ones(n, np.uint8), "number_of_returns": np.ones(n, np.uint8)})


def test_reconstruct_lidar_keeps_large_coordinates_and_crs(tmp_path):
    from rasterio.crs import CRS

    rng = np.random.default_rng(7)
    # ground points everywhere, three cone crowns at projected coordinates
    xy = rng.uniform(0, 50, (30_000, 2))
    z = 410 + 0.05 * xy[:, 0]
    trees = np.array([[12.0, 15.0, 22.0], [35.0, 12.0, 17.0], [25.0, 38.0, 28.0]])
    cls = np.full(len(xy), 2, np.uint8)
    for k, (x, y, h) in enumerate(trees):
        d = np.hypot(xy[:, 0] - x, xy[:, 1] - y)
        on = (d < 0.25 * h) & (rng.random(len(xy)) < 0.8)
        z[on] += h * (1 - d[on] / (0.25 * h))
        cls[on] = 5
        trees[k, 2] = np.max(z[on] - 410 - 0.05 * xy[on, 0])  # its highest point
    pts = np.column_stack([xy[:, 0] + E0, xy[:, 1] + N0, z])
    wkt = CRS.from_user_input(EPSG).to_wkt()
    src = tmp_path / "survey.laz"
    _write_survey(src, pts, cls, wkt=wkt)
    out = tmp_path / "recon"
    assert main(["-q", "reconstruct", "lidar", str(src), "--out", str(out)]) == 0
    t = read_tree_table(out / "trees.csv")
    want = trees + [E0, N0, 0.0]
    got = np.column_stack([t["x"], t["y"], t["height"]])
    assert len(got) == 3
    got = got[np.argsort(got[:, 0])]
    want = want[np.argsort(want[:, 0])]
    assert np.abs(got[:, :2] - want[:, :2]).max() < 0.75
    assert np.abs(got[:, 2] - want[:, 2]).max() < 0.05
    dtm = read_raster(out / "dtm.tif")
    assert CRS.from_wkt(dtm.crs_wkt) == CRS.from_user_input(EPSG)
    xs, ys = dtm.centres()
    assert E0 <= xs[0] < E0 + 1 and N0 <= ys[0] < N0 + 1
    np.testing.assert_allclose(dtm.values, np.broadcast_to(410 + 0.05 * (xs - E0),
                                                           dtm.values.shape), atol=0.02)
    back, info = read_las(out / "classified.laz")
    np.testing.assert_allclose(back["x"], pts[:, 0], atol=1e-3)
    np.testing.assert_array_equal(back["classification"], cls)  # the file's ground was kept


def test_reconstruct_lidar_bad_files_exit_2(tmp_path, capsys):
    empty = tmp_path / "empty.laz"
    with LasWriter(empty):
        pass
    noground = tmp_path / "noground.laz"
    _write_survey(noground, np.array([[0.0, 0, 0], [1, 1, 1]]), np.array([1, 1], np.uint8))
    noise = tmp_path / "noise.laz"
    _write_survey(noise, np.random.default_rng(0).uniform(0, 9, (50, 3)),
                  np.full(50, 7, np.uint8))
    for src, field in ((empty, "points"), (noground, "classification"),
                       (noise, "classification")):
        out = tmp_path / f"out_{src.stem}"
        assert main(["reconstruct", "lidar", str(src), "--out", str(out)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(f"error: {src}: {field}: "), err
        assert not out.exists()


def test_evaluate_lidar_result_against_truth(tmp_path, capsys):
    import json

    truth, recon = tmp_path / "truth", tmp_path / "recon"
    truth.mkdir()
    recon.mkdir()
    write_tree_table(truth / "trees.csv", {"x": [E0 + 5, E0 + 15, E0 + 25],
                                           "y": [N0 + 5, N0 + 5, N0 + 5],
                                           "height": [20.0, 25.0, 30.0]})
    write_tree_table(recon / "trees.csv", {"x": [E0 + 5.5, E0 + 15], "y": [N0 + 5, N0 + 5],
                                           "height": [19.0, 26.0]})
    z = np.full((10, 40), 100.0)
    write_raster(truth / "dtm.tif", Raster(z, x0=E0 + 0.5, y0=N0 + 0.5, res=1.0))
    write_raster(recon / "dtm.tif", Raster(z + 0.2, x0=E0 + 0.5, y0=N0 + 0.5, res=1.0))
    out = tmp_path / "scores.json"
    assert main(["evaluate", str(recon), "--reference", str(truth), "--json", str(out)]) == 0
    s = json.loads(out.read_text())
    assert s["trees"]["matched"] == 2 and s["trees"]["f"] == pytest.approx(0.8)
    assert s["trees"]["height_bias"] == pytest.approx(0.0)
    assert s["trees"]["height_rmse"] == pytest.approx(1.0)
    assert s["dtm"]["rmse"] == pytest.approx(0.2, abs=1e-5)
    assert "F 0.800" in capsys.readouterr().out


def test_raster_sample_and_tree_table_errors(tmp_path):
    r = Raster(np.array([[0.0, 1.0], [2.0, 3.0]]), x0=10.0, y0=20.0, res=2.0)
    assert r.sample(np.array([11.0]), np.array([21.0]))[0] == pytest.approx(1.5)
    assert np.isnan(r.sample(np.array([9.0]), np.array([21.0]))[0])
    p = tmp_path / "t.csv"
    p.write_text("x,y,height\n1,2\n")
    with pytest.raises(InputError, match="row 2: expected 3 values"):
        read_tree_table(p)


def test_an_inventory_crown_offset_moves_that_crown_only(tmp_path):
    from data_synth.forest import ForestConfig, build_forest

    cfg = ForestConfig(relief=0.0, margin=2.0, understory=0.0, variants=1)
    base = "x,y,height,crown_radius,species{h}\n10,10,12,2.0,FASY{a}\n20,10,12,2.0,FASY{b}\n"
    leaves = []
    for name, text in (("plain", base.format(h="", a="", b="")),
                       ("offset", base.format(h=",crown_dx,crown_dy", a=",0.8,0", b=",,"))):
        inv = tmp_path / f"{name}.csv"
        inv.write_text(text)
        objs = {o.name: o for o in build_forest(cfg, inventory=inv, seed=3).render_scene.objects}
        leaves.append([objs[f"tree{k:05d}.leaf"].world_arrays()[0] for k in (1, 2)])
        # each object keeps only the vertices its own triangles use
        for o in objs.values():
            assert len(np.unique(np.asarray(o.mesh.triangles))) == len(o.mesh.vertices)
    (a1, a2), (b1, b2) = leaves
    shift = b1[:, :2].mean(0) - a1[:, :2].mean(0)
    assert shift[0] > 0.15 and abs(shift[1]) < 0.3 * shift[0]   # towards +x
    assert b1[:, 0].max() - 10 > a1[:, 0].max() - 10 + 0.3       # reaching further there
    np.testing.assert_array_equal(a2, b2)                         # an empty offset: none


def test_unlisted_trees_grow_in_the_gaps_and_leave_the_listed_alone(tmp_path):
    from data_synth.forest import ForestConfig, build_forest

    inv = tmp_path / "inv.csv"
    inv.write_text("x,y,height,crown_radius,crown_dx,crown_dy,species\n"
                   "10,10,14,4.0,1.0,0,PIAB\n30,12,12,3.0,,,PIAB\n20,30,16,5.0,0,-1.5,FASY\n")
    plain = build_forest(ForestConfig(relief=0.0, margin=2.0, understory=400.0, variants=1),
                         inventory=inv, seed=4)
    cfg = ForestConfig(relief=0.0, margin=2.0, understory=400.0, variants=1, unlisted=300.0,
                       unlisted_height=6.0, unlisted_height_sd=2.0)
    b = build_forest(cfg, inventory=inv, seed=4)
    t = b.trees
    new = t["listed"] == 0
    m = int(new.sum())
    assert m >= 5 and t["listed"][:3].tolist() == [1, 1, 1]
    assert t["tree_id"].tolist() == list(range(1, 4 + m))
    assert np.all(t["height"][new] >= 2.0) and set(t["species"][new]) <= {"PIAB", "FASY"}
    # each unlisted stem stands where no listed crown (centre = stem + offset) reaches
    centre = np.array([[11.0, 10.0], [30.0, 12.0], [20.0, 28.5]])
    d = np.hypot(t["x"][new, None] - centre[:, 0], t["y"][new, None] - centre[:, 1])
    assert np.all(d >= np.array([4.0, 3.0, 5.0]))
    # the listed trees and the shrubs are the same triangles as without them
    objs = {o.name: o for o in b.render_scene.objects}
    for o in plain.render_scene.objects:
        np.testing.assert_array_equal(np.asarray(o.mesh.vertices),
                                      np.asarray(objs[o.name].mesh.vertices))
    ids = {o.object_id for o in b.render_scene.objects if o.name.startswith("tree")}
    assert ids == set(range(1, 4 + m))
    assert objs["understory"].object_id == 4 + m
