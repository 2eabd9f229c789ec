import json

from scanamp.cli import main


def test_demo_runs_and_scores(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--views", "3"]) == 0
    rep = json.loads((out / "report.json").read_text())
    # half-millimetre depth noise against a 2 mm tolerance: nearly every point is precise
    assert rep["evaluation"]["precision"] > 0.95
    assert 0 < rep["evaluation"]["recall"] < 1  # three views cannot see everything
    assert len(list((out / "views").glob("*.png"))) == 3
    assert "F-score" in capsys.readouterr().out


def test_demo_bad_views(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path / "d"), "--views", "0"]) == 2
    assert capsys.readouterr().err.startswith("error: --views")
    assert not (tmp_path / "d").exists()
