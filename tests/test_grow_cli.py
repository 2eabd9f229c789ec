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
    out = tmp_path / "bush.ply"
    assert main(["grow", "stochastic_bush", "--out", str(out), "-n", "3", "--seed", "4",
                 "--stats"]) == 0
    first = json.loads(capsys.readouterr().out)
    assert out.stat().st_size > 0
    assert main(["grow", "stochastic_bush", "-n", "3", "--seed", "4", "--stats"]) == 0
    assert json.loads(capsys.readouterr().out) == first


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
