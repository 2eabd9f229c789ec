"""``scanamp grow``: stats JSON, mesh output, exit 2 with file/line/column on bad grammars."""

import json

import pytest

from scanamp.cli import main


def test_stats_json(capsys):
    assert main(["grow", "abop_1_24a", "--stats"]) == 0
    stats = json.loads(capsys.readouterr().out)
    assert stats["length"] == 7811
    assert stats["counts"]["F"] == 3125
    assert stats["segments"] == 3125


def test_writes_mesh_and_seeds(tmp_path, capsys):
    """The mesh is the library's derivation drawn, the seed is honoured: the same seed
    gives the same bytes, another seed another plant (the grammar is stochastic)."""
    import numpy as np

    from core.io.mesh import read_mesh
    from procgen.lsystem import derive, interpret, load_grammar

    def grow(seed):
        out = tmp_path / f"bush{seed}.ply"
        assert main(["grow", "stochastic_bush", "--out", str(out), "-n", "3", "--seed",
                     str(seed), "--stats"]) == 0
        return out, json.loads(capsys.readouterr().out)

    a, stats = grow(4)
    again = tmp_path / "again.ply"
    assert main(["grow", "stochastic_bush", "--out", str(again), "-n", "3", "--seed", "4"]) == 0
    assert again.read_bytes() == a.read_bytes()
    b, other = grow(5)
    assert b.read_bytes() != a.read_bytes() and other != stats
    # the mesh spans the turtle's segments of the same derivation
    g = load_grammar("stochastic_bush")
    segs = interpret(derive(g, 3, rng=np.random.default_rng(4)), g).polylines()
    pts = np.vstack(segs)
    v = np.asarray(read_mesh(a).vertices)
    assert len(v) > 0 and len(read_mesh(a).triangles) > 0
    span = np.ptp(pts, axis=0).max()
    np.testing.assert_allclose(v.min(0), pts.min(0), atol=0.1 * span)
    np.testing.assert_allclose(v.max(0), pts.max(0), atol=0.1 * span)


@pytest.mark.parametrize("text, words", [
    ("axiom: F\nF -> F(1 +)\n", "line 2, column 11"),
    ("axiom: F\nF -> FQ\n", "unknown symbol 'Q'"),
    ("axiom: F\nF -(0.5)-> FF\nF -(0.4)-> F\n", "sum to 0.9"),
    ("axiom: A(1)\nA(x) -> A(1 / (x - 1))\n", "division by zero"),
    ("axiom: F\nF -> FFFFFFFFFF\n", "would produce"),
])
def test_bad_grammars_exit_2(tmp_path, capsys, text, words):
    path = tmp_path / "bad.lsys"
    path.write_text(text)
    assert main(["grow", str(path), "--stats", "-n", "30"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and words in err and "Traceback" not in err


def test_missing_grammar_lists_examples(capsys):
    assert main(["grow", "no_such_plant", "--stats"]) == 2
    assert "abop_1_24a" in capsys.readouterr().err


def test_lines_write_polylines(tmp_path, capsys):
    import open3d as o3d

    assert main(["grow", "dragon", "--lines", str(tmp_path / "d.ply"),
                 "--lines", str(tmp_path / "d.obj")]) == 0  # the last --lines wins
    text = (tmp_path / "d.obj").read_text().splitlines()
    assert sum(t.startswith("v ") for t in text) == 1025   # one polyline of 1024 segments
    assert sum(t.startswith("l ") for t in text) == 1
    assert main(["grow", "koch_snowflake", "--lines", str(tmp_path / "k.ply")]) == 0
    ls = o3d.io.read_line_set(str(tmp_path / "k.ply"))
    assert len(ls.lines) == 3 * 4 ** 4
    assert main(["grow", "dragon", "--lines", str(tmp_path / "d.svg")]) == 2
    assert "--lines" in capsys.readouterr().err


def test_gltf_output_is_readable_by_vtk(tmp_path):
    import pyvista as pv

    out = tmp_path / "plant.gltf"
    assert main(["grow", "abop_1_24a", "-n", "2", "--out", str(out)]) == 0
    from procgen.lsystem import derive, interpret, load_grammar, to_mesh

    g = load_grammar("abop_1_24a")
    want = to_mesh(interpret(derive(g, 2), g), sides=8)
    assert pv.read(out).combine().n_cells == len(want.triangles)  # VTK reads every triangle
