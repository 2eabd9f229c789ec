"""``scanamp procgen terrain|fractal|hypertexture`` in-process: outputs and exit codes."""

import numpy as np
import pytest

from core.image_io import read_image
from core.mesh_io import read_mesh
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


@pytest.mark.parametrize("kind", ["koch", "sierpinski", "fern", "mandelbrot", "julia"])
def test_fractal_images(tmp_path, kind):
    out = tmp_path / f"{kind}.png"
    rc = main(["-q", "procgen", "fractal", kind, "--width", "120", "--height", "90",
               "--level", "3", "--points", "20000", "--max-iter", "64", "--out", str(out)])
    assert rc == 0
    img = read_image(out)
    assert img.shape == (90, 120, 3) and len(np.unique(img.reshape(-1, 3), axis=0)) > 2


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
