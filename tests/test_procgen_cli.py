"""``scanamp procgen terrain|fractal|hypertexture`` in-process: outputs and exit codes."""

import subprocess
import sys

import numpy as np
import pytest

from core.io.image import read_image
from core.io.mesh import read_mesh
from scanamp.cli import main


def test_terrain_with_water_and_preview(tmp_path):
    out = tmp_path / "t.ply"
    rc = main(["-q", "procgen", "terrain", "--size", "33", "--water", "0.0", "--seed", "2",
               "--out", str(out)])
    assert rc == 0
    assert len(read_mesh(out).vertices) == 33 * 33
    assert (tmp_path / "t.water.ply").is_file()
    img = read_image(tmp_path / "t.preview.png")
    assert img.ndim == 3 and img.std() > 1  # something was drawn


def test_terrain_same_seed_same_bytes(tmp_path):
    # PLY: OBJ output names its .mtl after the temporary file (mesh_io, reported to the lead)
    a, b = tmp_path / "a.ply", tmp_path / "b.ply"
    for p in (a, b):
        assert main(["-q", "procgen", "terrain", "--size", "17", "--method", "fbm",
                     "--seed", "5", "--no-preview", "--out", str(p)]) == 0
    assert a.read_bytes() == b.read_bytes()


def _shoelace(p):
    x, y = p[:, 0], p[:, 1]
    return 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


@pytest.mark.parametrize("kind", ["koch", "sierpinski", "fern", "mandelbrot", "julia"])
def test_fractal_images(tmp_path, kind):
    """Each image shows its fractal: the areas it covers match the geometry (closed forms
    where they exist), the escape-time sets their known area or symmetry."""
    from matplotlib.path import Path
    from scipy.ndimage import binary_erosion
    from scipy.spatial import ConvexHull

    from procgen import fractals as F
    from scanamp.cli.procgen_fractal import _fit

    w, h, level = 120, 90, 3
    out = tmp_path / f"{kind}.png"
    rc = main(["-q", "procgen", "fractal", kind, "--width", str(w), "--height", str(h),
               "--level", str(level), "--points", "20000", "--max-iter", "64",
               "--out", str(out)])
    assert rc == 0
    img = read_image(out).astype(int)
    assert img.shape == (h, w, 3)
    inked = (765 - img.sum(axis=2)) > 30  # clearly not white (faint anti-aliasing aside)
    if kind in ("koch", "sierpinski"):  # drawn where the library's polygons are
        if kind == "koch":
            polys = [_fit(F.koch_snowflake(level), w, h)]
        else:
            polys = list(_fit(F.sierpinski_triangle(level).reshape(-1, 2), w, h)
                         .reshape(-1, 3, 2))
            outer = ConvexHull(np.vstack(polys)).volume
            assert len(polys) == 3 ** level  # (3/4)^L of the outer triangle remains
            assert sum(_shoelace(t) for t in polys) == pytest.approx(0.75 ** level * outer)
        yy, xx = np.mgrid[0:h, 0:w]
        centres = np.stack([xx.ravel(), yy.ravel()], 1).astype(float)
        truth = np.zeros(h * w, bool)
        for poly in polys:
            truth |= Path(poly).contains_points(centres)
        truth = truth.reshape(h, w)
        # away from the edges (3 px: anti-aliasing, the outline) the image is exact
        assert inked[binary_erosion(truth, iterations=3)].all()
        assert not inked[binary_erosion(~truth, iterations=3)].any()
        assert truth.sum() > 0.05 * w * h
    elif kind == "fern":  # Barnsley's fern spans x in [-2.18, 2.66], y in [0, 9.99]
        rows, cols = np.nonzero(inked)
        aspect = (np.ptp(rows) + 1) / (np.ptp(cols) + 1)
        assert aspect == pytest.approx(9.99 / 4.84, rel=0.1)
    else:
        inside = (img == 0).all(axis=2)  # the sets are drawn black
        if kind == "mandelbrot":  # 120 px over a width of 3: area 1.506 (+ boundary pixels)
            assert inside.sum() * (3.0 / w) ** 2 == pytest.approx(1.55, abs=0.1)
        else:  # a filled Julia set is symmetric under z -> -z
            assert inside.sum() > 50
            assert (inside == inside[::-1, ::-1]).mean() > 0.99


def test_hypertexture_sphere_and_mesh(tmp_path):
    out = tmp_path / "h.ply"
    assert main(["-q", "procgen", "hypertexture", "sphere", "--resolution", "24",
                 "--no-preview", "--out", str(out)]) == 0
    r = np.linalg.norm(np.asarray(read_mesh(out).vertices), axis=1)
    assert 0.95 < r.min() and r.max() < 1.5
    out2 = tmp_path / "h2.ply"
    assert main(["-q", "procgen", "hypertexture", "mesh", "--mesh", str(out), "--resolution",
                 "24", "--amplitude", "0.05", "--no-preview", "--out", str(out2)]) == 0
    assert out2.is_file()


@pytest.mark.parametrize("argv,needle", [
    (["procgen", "terrain", "--size", "100"], "--size"),
    (["procgen", "terrain", "--hurst", "1.5"], "hurst"),
    (["procgen", "fractal", "mandelbrot"], "--out"),  # wrong suffix, see below
    (["procgen", "hypertexture", "mesh"], "--mesh"),
    (["procgen", "hypertexture", "sweep", "--polyline", "0,0"], "--polyline"),
])
def test_bad_input_exits_2(tmp_path, capsys, argv, needle):
    out = tmp_path / ("x.txt" if "fractal" in argv else "x.ply")
    assert main([*argv, "--no-preview" if "fractal" not in argv else "--seed=0",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and needle in err
    assert not out.exists()


def test_empty_input_mesh_exits_2(tmp_path, capsys):
    empty = tmp_path / "empty.ply"
    empty.write_text("ply\nformat ascii 1.0\nelement vertex 0\nelement face 0\n"
                     "property list uchar int vertex_indices\nend_header\n")
    rc = main(["procgen", "hypertexture", "mesh", "--mesh", str(empty), "--out",
               str(tmp_path / "o.ply")])
    assert rc == 2
    assert "empty.ply" in capsys.readouterr().err


def _labelled(path):
    from core.io.mesh import read_labeled_mesh

    m = read_labeled_mesh(path)
    return m, {m["names"][int(k)] for k in np.unique(m["labels"])}


def test_city_cli_writes_roads_buildings_and_gis_files(tmp_path):
    import json

    from procgen.city import check_cityjson

    out = tmp_path / "city" / "c.ply"
    out.parent.mkdir()
    assert main(["-q", "procgen", "city", "--size", "600", "--max-segments", "60",
                 "--pattern", "grid", "--out", str(out)]) == 0
    m, names = _labelled(out)
    assert names == {"road", "building", "roof", "window", "ground"}
    # roads lie flat just above the ground, buildings rise from it
    road = m["vertices"][m["labels"] == 6]
    assert np.allclose(road[:, 2], 0.05)
    assert m["vertices"][m["labels"] == 8][:, 2].max() > 6.0
    assert read_image(out.with_name("c.preview.png")).std() > 1
    roads = json.loads(out.with_name("c.roads.geojson").read_text())
    assert roads["type"] == "FeatureCollection" and len(roads["features"]) > 10
    buildings = json.loads(out.with_name("c.buildings.geojson").read_text())
    assert all(f["properties"]["floors"] >= 1 for f in buildings["features"])
    doc = json.loads(out.with_name("c.city.json").read_text())
    assert check_cityjson(doc) == [] and len(doc["CityObjects"]) == len(buildings["features"])
    # cjio (the CityJSON tool) reads it as a 2.0 file with every building, and finds no
    # orphan or duplicate vertex to remove; in its own process, since importing cjio
    # replaces the json module's float encoder for the whole process
    pytest.importorskip("cjio")
    check = ("import sys; from cjio.cityjson import CityJSON; "
             "cm = CityJSON(file=open(sys.argv[1])); "
             "print(cm.get_version(), cm.is_transform(), cm.number_city_objects_level1(), "
             "cm.remove_orphan_vertices(), cm.remove_duplicate_vertices())")
    r = subprocess.run([sys.executable, "-c", check, str(out.with_name("c.city.json"))],
                       capture_output=True, text=True, check=True)
    assert r.stdout.split() == ["2.0", "True", str(len(buildings["features"])), "0", "0"]


def test_city_cli_bad_rule_file_and_map_exit_2_writing_nothing(tmp_path, capsys):
    rules = tmp_path / "rules.toml"
    rules.write_text('[rules]\nLot = { op = "extrude", then = "M" }\nM = { op = "explode" }\n')
    out = tmp_path / "a" / "c.ply"
    assert main(["-q", "procgen", "city", "--size", "400", "--rules", str(rules),
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "rules.toml" in err and "rules.M.op" in err and "explode" in err
    assert len(err.strip().splitlines()) == 1 and not out.parent.exists()
    pop = tmp_path / "pop.npy"
    np.save(pop, np.ones((16, 24)))
    assert main(["-q", "procgen", "city", "--size", "400", "--population", str(pop),
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "pop.npy" in err and "population" in err and "(16, 24)" in err
    assert not out.parent.exists()


def test_plant_cli_bark_and_leaves_same_seed_same_bytes(tmp_path):
    a, b = tmp_path / "a" / "p.ply", tmp_path / "b" / "p.ply"
    for p in (a, b):
        p.parent.mkdir()
        assert main(["-q", "procgen", "plant", "--seed", "4", "--no-preview",
                     "--out", str(p)]) == 0
    assert a.read_bytes() == b.read_bytes()
    m, names = _labelled(a)
    assert names == {"bark", "leaf"}
    c = tmp_path / "c" / "p.ply"
    c.parent.mkdir()
    assert main(["-q", "procgen", "plant", "--seed", "5", "--no-preview", "--out", str(c)]) == 0
    assert c.read_bytes() != a.read_bytes()


@pytest.mark.parametrize("shape", ["turbinate", "helicospiral"])
def test_shell_cli_scaled_to_size(tmp_path, shape):
    out = tmp_path / "s.ply"
    assert main(["-q", "procgen", "shell", "--shape", shape, "--size", "0.2", "--n-theta",
                 "120", "--n-s", "16", "--no-preview", "--out", str(out)]) == 0
    v = read_mesh(out).vertices
    assert np.ptp(np.asarray(v), axis=0).max() == pytest.approx(0.2)


def test_sweep_cli_closed_tube_of_the_profile_radius(tmp_path):
    from core.meshes import is_closed, mesh_arrays

    out = tmp_path / "w.ply"
    assert main(["-q", "procgen", "sweep", "--profile", "circle", "--path", "circle",
                 "--twist", "0", "--radius", "0.05", "--size", "2", "--no-preview",
                 "--out", str(out)]) == 0
    v, f = mesh_arrays(read_mesh(out))
    assert is_closed(f)
    # a torus: every vertex 0.1 m from the 1 m circle (profile radius 0.05 x size 2)
    ring = np.hypot(v[:, 0], v[:, 1]) - 1.0
    assert np.allclose(np.hypot(ring, v[:, 2]), 0.1, atol=1e-9)
    assert main(["-q", "procgen", "sweep", "--path", "circle", "--taper", "0.5",
                 "--out", str(tmp_path / "x.ply")]) == 2


def test_terrain_eroded_with_rivers_materials_and_a_dem(tmp_path):
    """Stream power carves the fractal; the ground is coloured by material, the water
    follows the flow, and the DEM reads back in metres with its CRS."""
    from core.io.raster import read_raster
    from procgen.terrain.metrics import pit_share

    out, dem = tmp_path / "t.ply", tmp_path / "t.tif"
    assert main(["-q", "procgen", "terrain", "--size", "65", "--extent", "3000",
                 "--height", "100", "--erosion", "stream-power", "--rivers", "--dem",
                 str(dem), "--crs", "EPSG:32632", "--no-preview", "--out", str(out)]) == 0
    r = read_raster(dem)
    assert r.values.shape == (65, 65) and r.res == pytest.approx(3000 / 64)
    assert "32632" in r.crs_wkt and r.x0 == pytest.approx(-1500.0)
    assert pit_share(r.values) <= 0.002        # eroded: drains (fractal noise: ~4 %)
    mesh = read_mesh(out)
    np.testing.assert_allclose(np.asarray(mesh.vertices)[:, 2], r.values.ravel(), atol=1e-3)
    assert mesh.has_vertex_colors() and (tmp_path / "t.water.ply").is_file()
    # the DEM as the start of another run: its CRS is kept
    again = tmp_path / "u.ply"
    assert main(["-q", "procgen", "terrain", "--from-dem", str(dem), "--erosion", "thermal",
                 "--no-preview", "--out", str(again)]) == 0
    assert len(read_mesh(again).vertices) == 65 * 65


@pytest.mark.parametrize("extra,needle", [
    (["--erosion", "stream-power", "--rates.erodibility=-1e-3"], "erodibility"),
    (["--erosion", "hydraulic", "--rates.rain=-0.1"], "rain"),
    (["--dem", "{tmp}/d.tif", "--crs", "EPSG:4326"], "--crs"),
    (["--from-dem", "{tmp}/nocrs.tif"], "crs"),
])
def test_terrain_bad_rates_and_crs_exit_2(tmp_path, capsys, extra, needle):
    from core.io.raster import Raster, write_raster

    write_raster(tmp_path / "nocrs.tif", Raster(np.zeros((5, 5)), x0=0.0, y0=0.0, res=1.0))
    out = tmp_path / "x.ply"
    argv = [a.replace("{tmp}", str(tmp_path)) for a in extra]
    assert main(["procgen", "terrain", "--size", "17", "--no-preview", *argv,
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and needle in err and err.count("\n") == 1
    assert not out.exists() and not (tmp_path / "d.tif").exists()
