"""core.runs.outputs: an output never replaces what the user had, and never the input."""

from __future__ import annotations

import pytest

from core.files import MANIFEST
from core.runs.outputs import check_output, check_output_file, output_dir, read_manifest
from core.validate import InputError


def _write(path, cmd="scene", **kw):
    with output_dir(path, command=cmd, **kw) as tmp:
        (tmp / "a.txt").write_text("new")
    return path


def test_new_and_empty_folders_are_fine(tmp_path):
    _write(tmp_path / "new")
    (tmp_path / "empty").mkdir()
    _write(tmp_path / "empty")
    assert read_manifest(tmp_path / "empty")["command"] == "scene"
    assert (tmp_path / "new" / "a.txt").read_text() == "new"


@pytest.mark.parametrize("setup, words", [
    (lambda p: p.write_text("notes"), "not a folder"),
    (lambda p: (p.mkdir(), (p / "mine.txt").write_text("x")), "did not write"),
])
def test_what_the_user_had_is_kept(tmp_path, setup, words):
    out = tmp_path / "out"
    setup(out)
    before = {q: q.read_bytes() for q in tmp_path.rglob("*") if q.is_file()}
    with pytest.raises(InputError, match=words):
        _write(out, overwrite=True)
    assert {q: q.read_bytes() for q in tmp_path.rglob("*") if q.is_file()} == before


def test_own_folder_needs_overwrite_and_same_command(tmp_path):
    out = _write(tmp_path / "out")
    with pytest.raises(InputError, match="--overwrite"):
        _write(out)
    with pytest.raises(InputError, match="'scanamp scene', not by 'scanamp capture sfm'"):
        _write(out, cmd="capture sfm", overwrite=True)
    (out / "a.txt").write_text("old")
    _write(out, overwrite=True)
    assert (out / "a.txt").read_text() == "new"


@pytest.mark.parametrize("rel", [".", "sub", ".."])
def test_never_the_input(tmp_path, rel):
    inp = tmp_path / "scene"
    inp.mkdir()
    (inp / "scene.toml").write_text("x")
    out = (inp / rel) if rel != "." else inp
    with pytest.raises(InputError, match="input"):
        _write(out, inputs=[inp], overwrite=True)
    assert (inp / "scene.toml").read_text() == "x"


def test_reuse_starts_from_the_old_folder_and_failure_keeps_it(tmp_path):
    out = _write(tmp_path / "out")
    with output_dir(out, command="scene", overwrite=True, reuse=True) as tmp:
        assert (tmp / "a.txt").read_text() == "new" and not (tmp / MANIFEST).exists()
    with pytest.raises(RuntimeError):
        with output_dir(out, command="scene", overwrite=True) as tmp:
            (tmp / "a.txt").write_text("half")
            raise RuntimeError("stage failed")
    assert (out / "a.txt").read_text() == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # no temporary left


def test_single_files(tmp_path):
    f = tmp_path / "x.ply"
    check_output_file(f)
    f.write_text("mine")
    with pytest.raises(InputError, match="--overwrite"):
        check_output_file(f)
    check_output_file(f, overwrite=True)
    with pytest.raises(InputError, match="is the input"):
        check_output_file(f, inputs=[f], overwrite=True)
    with pytest.raises(InputError, match="is a folder"):
        check_output_file(tmp_path)


def test_api_folders_are_replaced_by_the_api_but_not_by_a_command(tmp_path):
    from core.files import atomic_dir
    from core.runs.outputs import read_manifest

    with atomic_dir(tmp_path / "cap") as d:
        (d / "a").write_text("1")
    assert read_manifest(tmp_path / "cap")["command"] == "api"
    with atomic_dir(tmp_path / "cap") as d:  # the Python API may redo its own output
        (d / "b").write_text("2")
    assert (tmp_path / "cap" / "b").exists()
    with pytest.raises(InputError, match="Python API, not by 'scanamp capture laser'"):
        check_output(tmp_path / "cap", command="capture laser", overwrite=True)


def test_atomic_dir_never_replaces_a_users_folder_or_file(tmp_path):
    from core.files import atomic_dir

    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "thesis.tex").write_text("years of work")
    (tmp_path / "notes.txt").write_text("notes")
    for target in (tmp_path / "mine", tmp_path / "notes.txt"):
        with pytest.raises(InputError, match="nothing was written"):
            with atomic_dir(target) as d:
                (d / "x").write_text("x")
    assert (tmp_path / "mine" / "thesis.tex").read_text() == "years of work"
    assert (tmp_path / "notes.txt").read_text() == "notes"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine", "notes.txt"]
