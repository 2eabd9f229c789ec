"""Outputs never destroy (issue 15): the four refusals, --overwrite, file outputs, and the
messages that name final paths; ``scanamp --version``."""

import json

import pytest

from core.files import MANIFEST
from scanamp.cli import main


def _scene(tmp_path, name="sc", *extra):
    return main(["scene", "primitives", "--out", str(tmp_path / name), *extra])


def test_refusals_leave_everything_as_it_was(tmp_path, capsys):
    (tmp_path / "notes.txt").write_text("mine")
    (tmp_path / "mydir").mkdir()
    (tmp_path / "mydir" / "a.txt").write_text("also mine")
    assert _scene(tmp_path, "notes.txt") == 2
    assert "notes.txt: exists and is not a folder" in capsys.readouterr().err
    assert _scene(tmp_path, "mydir") == 2
    assert "mydir: is a folder scanamp did not write" in capsys.readouterr().err
    assert (tmp_path / "notes.txt").read_text() == "mine"
    assert (tmp_path / "mydir" / "a.txt").read_text() == "also mine"
    assert sorted(p.name for p in (tmp_path / "mydir").iterdir()) == ["a.txt"]


def test_own_folder_needs_overwrite_and_input_is_never_the_output(tmp_path, capsys):
    assert _scene(tmp_path) == 0
    sc = tmp_path / "sc"
    manifest = json.loads((sc / MANIFEST).read_text())
    assert manifest["command"] == "scene" and manifest["format"] == "scanamp.output/1"
    before = {p.name: p.read_bytes() for p in sc.iterdir() if p.is_file()}
    assert _scene(tmp_path) == 2
    assert "pass --overwrite" in capsys.readouterr().err
    assert _scene(tmp_path, "sc", "--overwrite") == 0
    assert {p.name: p.read_bytes() for p in sc.iterdir() if p.is_file()} == before  # same bytes
    for out, what in ((sc, "is the input"), (sc / "cap", "is inside the input"),
                      (tmp_path, "contains the input")):
        code = main(["capture", "sfm", str(sc), "--out", str(out), "--overwrite"])
        err = capsys.readouterr().err
        assert code == 2 and what in err and err.count("\n") == 1, err
    assert {p.name: p.read_bytes() for p in sc.iterdir() if p.is_file()} == before
    # a folder of another command is never replaced, even with --overwrite
    assert main(["render", str(sc), "--out", str(tmp_path / "v.png"), "--size", "32x24",
                 "--supersample", "1"]) == 0
    capsys.readouterr()
    assert main(["simulate", "boids", "torus", "--n", "8", "--steps", "2", "--size", "32x24",
                 "--out", str(sc), "--overwrite"]) == 2
    assert "holds the output of 'scanamp scene'" in capsys.readouterr().err


def test_single_file_outputs_need_overwrite(tmp_path, capsys):
    assert _scene(tmp_path) == 0
    png = tmp_path / "v.png"
    png.write_bytes(b"my picture")
    args = ["render", str(tmp_path / "sc"), "--out", str(png), "--size", "32x24",
            "--supersample", "1"]
    assert main(args) == 2
    assert "v.png: exists; pass --overwrite" in capsys.readouterr().err
    assert png.read_bytes() == b"my picture"
    assert main([*args, "--overwrite"]) == 0
    assert png.read_bytes()[:4] == b"\x89PNG"


def test_messages_name_the_final_path_not_the_temporary_one(tmp_path, caplog):
    import logging

    from core.files import atomic_dir
    from scanamp.cli import _FinalPaths

    rec = logging.LogRecord("x", logging.INFO, __file__, 1, "wrote %s", None, None)
    with atomic_dir(tmp_path / "run") as tmp:
        rec.args = (str(tmp / "animation.mp4"),)
        _FinalPaths().filter(rec)
    assert rec.getMessage() == f"wrote {tmp_path / 'run' / 'animation.mp4'}"


def test_version_names_the_core_dependencies(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    out = capsys.readouterr().out
    assert exc.value.code == 0 and out.startswith("scanamp ")
    for dep in ("numpy", "opencv", "open3d", "pycolmap", "pymeshlab", "pyvista"):
        assert dep in out
