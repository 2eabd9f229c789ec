"""Shape grammar: parsing, termination, geometry."""

import numpy as np
import pytest

from core.validate import InputError
from procgen.shape_grammar import (
    PLANT,
    derive_sentence,
    interpret_sentence,
    leaf_blade,
    parse_shape_grammar,
    plant_mesh,
)
from procgen.sweeps import edge_manifold_report


def test_plant_grammar_parses_and_terminates():
    g = parse_shape_grammar(PLANT)
    assert g.start == "Start" and set(g.rules) == {"Start", "Limb", "Shoot", "Tree", "Branch"}
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
                              length=1.0, shrink=0.5, bend=0.0, leaf_size=0.6)
    # two segments (1 + 0.5) and a leaf of 0.6 s^0.3 at s = 0.25
    assert v[:, 2].max() == pytest.approx(1.5 + 0.6 * 0.25 ** 0.3, abs=1e-9)


def test_branches_taper_and_leaves_are_flat_blades():
    v, f = interpret_sentence(["cylinder"], np.random.default_rng(0), radius=0.1, shrink=0.8,
                              sides=12)
    r = np.linalg.norm(v[:, :2], axis=1)
    assert r[v[:, 2] < 1e-9].max() == pytest.approx(0.1)
    assert r[v[:, 2] > 1 - 1e-9].max() == pytest.approx(0.08)       # the top is 0.8 x base
    lv, lf = leaf_blade()
    ext = lv.max(0) - lv.min(0)
    assert ext[2] == pytest.approx(1.0) and ext[1] < 0.1 * ext[0]      # long, wide, thin
    rep = edge_manifold_report(lf)
    assert rep["boundary"] == rep["nonmanifold"] == rep["inconsistent"] == 0
    # ovate: widest below the middle of the blade, narrow at the petiole and the tip
    z = lv[:, 2]
    widest = z[np.argmax(np.abs(lv[:, 0]))]
    assert 0.3 < widest < 0.6


@pytest.mark.parametrize("text, words", [
    ("A -> B", "unknown symbol 'B'"),
    ("A -> cylinder {x}", "bad weight"),
    ("A -> cylinder {-1}", "> 0"),
    ("just words", "expected"),
])
def test_bad_grammars(text, words):
    with pytest.raises(InputError, match=words):
        parse_shape_grammar(text)


def test_no_degenerate_plant_whatever_the_seed():
    """By construction every derivation has a trunk, three limbs that each carry a stem
    segment and end in a leaf, and more leaves along the shoots; the notes' grammar as is
    gives a stick with a leaf or two at the median."""
    g = parse_shape_grammar(PLANT)
    sentences = [derive_sentence(g, np.random.default_rng(s), max_depth=10) for s in range(300)]
    for s in sentences:
        assert s[:3] == ["cylinder", "cylinder", "["]
        assert s.count("[") >= 3 and s.count("leaf") >= 4 and s.count("cylinder") >= 7
    branches = [s.count("[") for s in sentences]
    assert np.median(branches) >= 10
    # a gallery of 12 seeds: 12 different plants
    assert len({" ".join(s) for s in sentences[:12]}) == 12
    flat = parse_shape_grammar("Start -> Tree\nTree -> Branch Tree | leaf\n"
                               "Branch -> cylinder | [ Tree ]\n")   # the notes' as is
    assert np.median([derive_sentence(flat, np.random.default_rng(s), max_depth=10)
                      .count("[") for s in range(60)]) <= 1
