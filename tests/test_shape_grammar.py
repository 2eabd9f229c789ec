"""Shape grammar: parsing, termination, geometry."""

import numpy as np
import pytest

from core.validate import InputError
from procgen.shape_grammar import (
    PLANT,
    derive_sentence,
    interpret_sentence,
    parse_shape_grammar,
    plant_mesh,
)
from procgen.sweeps import edge_manifold_report


def test_plant_grammar_parses_and_terminates():
    g = parse_shape_grammar(PLANT)
    assert g.start == "Start" and set(g.rules) == {"Start", "Tree", "Branch"}
    for seed in range(20):
        s = derive_sentence(g, np.random.default_rng(seed), max_depth=10)
        assert set(s) <= {"cylinder", "leaf", "[", "]"}
        assert s.count("[") == s.count("]")
        # every Tree ends in a leaf: one leaf per opened branch plus the trunk's
        assert s.count("leaf") == s.count("[") + 1


def test_language_is_the_grammars():
    # the derivation is a word of the grammar: re-parse it with a recursive recognizer
    def tree(s, i):
        while i < len(s) and s[i] in ("cylinder", "["):
            if s[i] == "cylinder":
                i += 1
            else:
                i = tree(s, i + 1)
                assert s[i] == "]"
                i += 1
        assert s[i] == "leaf"
        return i + 1

    g = parse_shape_grammar(PLANT)
    for seed in range(10):
        s = derive_sentence(g, np.random.default_rng(seed))
        assert tree(s, 0) == len(s)


def test_geometry_is_closed_and_seeded():
    v, f = plant_mesh(np.random.default_rng(3))
    v2, f2 = plant_mesh(np.random.default_rng(3))
    np.testing.assert_array_equal(v, v2)
    rep = edge_manifold_report(f)
    assert rep["boundary"] == rep["nonmanifold"] == rep["inconsistent"] == 0
    v, f = interpret_sentence(["cylinder", "cylinder", "leaf"], np.random.default_rng(0),
                              length=1.0, shrink=0.5)
    assert v[:, 2].max() == pytest.approx(1.5 + 0.5 * 0.25, abs=1e-9)  # leaf height 0.5


@pytest.mark.parametrize("text, words", [
    ("A -> B", "unknown symbol 'B'"),
    ("A -> cylinder {x}", "bad weight"),
    ("A -> cylinder {-1}", "> 0"),
    ("just words", "expected"),
])
def test_bad_grammars(text, words):
    with pytest.raises(InputError, match=words):
        parse_shape_grammar(text)


def test_a_typical_plant_branches_several_times():
    """The weighted grammar: the median derivation over 60 seeds branches at least three
    times (with equal weights it is a stick with a leaf or two)."""
    g = parse_shape_grammar(PLANT)
    branches = [derive_sentence(g, np.random.default_rng(s), max_depth=10).count("[")
                for s in range(60)]
    assert np.median(branches) >= 3
    flat = parse_shape_grammar("Start -> Tree\nTree -> Branch Tree | leaf\n"
                               "Branch -> cylinder | [ Tree ]\n")   # the notes' as is
    assert np.median([derive_sentence(flat, np.random.default_rng(s), max_depth=10)
                      .count("[") for s in range(60)]) <= 1
