"""Derivation oracles from The Algorithmic Beauty of Plants, and engines agreeing."""

import numpy as np
import pytest

from procgen.lsystem import (
    GrammarError,
    GrowthLimitError,
    derive,
    derive_reference,
    interpret,
    load_grammar,
    parse_grammar,
)

# ABOP Fig. 1.24 a-f: (length of the derived string, number of F)
ABOP_1_24 = {"a": (7811, 3125), "b": (9373, 3125), "c": (11116, 4096), "d": (13956, 4118),
             "e": (12863, 4118), "f": (6263, 1488)}


@pytest.mark.parametrize("panel", sorted(ABOP_1_24))
def test_abop_fig_1_24_lengths_and_f_counts(panel):
    g = load_grammar(f"abop_1_24{panel}")
    s = derive(g)
    assert (len(s), s.counts()["F"]) == ABOP_1_24[panel]
    assert len(interpret(s, g)) == ABOP_1_24[panel][1]


def test_dragon_and_sierpinski_segment_counts():
    g = load_grammar("dragon")
    assert g.n == 10 and len(interpret(derive(g), g)) == 1024
    g = load_grammar("sierpinski_gasket")
    assert g.n == 6 and len(interpret(derive(g), g)) == 729


def test_koch_snowflake_and_island_are_closed_curves():
    for name, segs in (("koch_snowflake", 3 * 4 ** 4), ("quadratic_koch_island", 4 * 18 ** 2)):
        g = load_grammar(name)
        r = interpret(derive(g), g)
        assert len(r) == segs
        np.testing.assert_allclose(r.ends[-1], r.starts[0], atol=1e-9)
        assert len(r.polylines()) == 1


def test_tree_2pi16():
    g = load_grammar("tree_2pi16")
    assert g.angle == pytest.approx(360 / 16)
    s = derive(g, 2)
    assert s.symbols == "++++F+[F+[FS]-[FS]-[FS]]-[F+[FS]-[FS]-[FS]]-[F+[FS]-[FS]-[FS]]"
    # F count: 1 + 3 + 9 + ... (S makes three branches per step)
    assert derive(g).counts()["F"] == sum(3 ** k for k in range(g.n + 1))


@pytest.mark.parametrize("name", ["abop_1_24a", "abop_1_24d", "tree_2pi16", "dragon",
                                  "acropetal", "signal", "parametric_tree"])
def test_engines_agree_with_reference(name):
    g = load_grammar(name)
    n = min(g.n, 4) if name != "acropetal" else 12
    ref = derive_reference(g, n).text()
    assert derive(g, n).text() == ref
    assert derive(g, n, method="general").text() == ref


def test_signal_propagation():
    g = load_grammar("signal")
    for k in range(8):
        assert derive(g, k).symbols == "a" * k + "b" + "a" * (7 - k)


def test_context_abop_fig_1_25():
    # ABOP p. 32: BC < S > G[H]M matches S in ABC[DE][SG[HI[JK]L]MNO]
    g = parse_grammar("axiom: ABC[DE][SG[HI[JK]L]MNO]\nsymbols: ABCDEGHIJKLMNOX\n"
                      "BC < S > G[H]M -> X\n")
    assert derive(g, 1).symbols == "ABC[DE][XG[HI[JK]L]MNO]"
    # without the bracketed part of the context, or with a wrong one, no match
    g2 = parse_grammar("axiom: ABC[DE][SG[HI[JK]L]MNO]\nsymbols: ABCDEGHIJKLMNOX\n"
                       "BC < S > G[I]M -> X\n")
    assert "X" not in derive(g2, 1).symbols
    g3 = parse_grammar("axiom: ABC[DE][SG[HI[JK]L]MNO]\nsymbols: ABCDEGHIJKLMNOX\n"
                       "BC < S > GM -> X\n")
    assert "X" in derive(g3, 1).symbols  # the branch [HI[JK]L] is skipped


def test_context_ignore_list_and_branches():
    g = parse_grammar("axiom: b+F[+a]-a[a]a\nignore: +-F\nb < a -> b\nb -> a\n")
    # every a whose nearest non-ignored ancestor-or-predecessor is b becomes b
    assert derive(g, 1).symbols == "a+F[+b]-b[a]a"
    assert derive(g, 2).symbols == "a+F[+a]-a[b]b"


def test_two_sided_context_is_oracle_checked():
    g = parse_grammar("axiom: abcabc\nsymbols: abcX\na < b > c -> X\n")
    assert derive(g, 1).symbols == "aXcaXc"
    g = parse_grammar("axiom: abcabd\nsymbols: abcdX\na < b > c -> X\n")
    assert derive(g, 1).symbols == "aXcabd"


def test_parametric_conditions_and_arithmetic():
    g = parse_grammar("axiom: A(1)\nA(x) : x < 8 -> A(x * 2)F(x)\nA(x) : x >= 8 -> B(x / 2)\n"
                      "symbols: B\n")
    assert derive(g, 5).text() == "B(4)F(4)F(2)F(1)"
    r = interpret(derive(g, 5), g)
    np.testing.assert_allclose(r.ends[-1], [0, 0, 7])


def test_parametric_context():
    g = parse_grammar("axiom: A(1)B(2)B(3)\nA(x) < B(y) -> B(x + y)\nB(y) < B(z) -> B(y * z)\n"
                      "A(x) -> A(x)\n")
    assert derive(g, 1).text() == "A(1)B(3)B(6)"


def test_stochastic_is_seeded_and_fair():
    g = load_grammar("stochastic_bush")
    a = derive(g, rng=np.random.default_rng(7)).symbols
    b = derive(g, rng=np.random.default_rng(7)).symbols
    c = derive(g, rng=np.random.default_rng(8)).symbols
    assert a == b and a != c
    with pytest.raises(ValueError, match="rng"):
        derive(g)
    # one step from a long axiom: each successor about a third of the time
    g2 = parse_grammar("axiom: " + "F" * 3000 + "\nsymbols: XYZ\n"
                       "F -(1/3)-> X\nF -(1/3)-> Y\nF -(1/3)-> Z\n")
    counts = derive(g2, 1, rng=np.random.default_rng(0)).counts()
    for sym in "XYZ":
        assert abs(counts[sym] - 1000) < 5 * np.sqrt(3000 * (1 / 3) * (2 / 3))


def test_stochastic_general_engine_statistics():
    g = parse_grammar("axiom: " + "A(1)" * 2000 + "\n"
                      "A(x) -(0.25)-> A(x + 1)\nA(x) -(0.75)-> A(x)\n")
    s = derive(g, 4, rng=np.random.default_rng(1))
    assert abs(np.mean(s.params[:, 0]) - 2.0) < 0.1  # 1 + 4 * 0.25


def test_growth_limits_stop_runaway():
    g = parse_grammar("axiom: F\nF -> FFFFFFFFFF\n")
    with pytest.raises(GrowthLimitError, match="max_symbols"):
        derive(g, 30)
    with pytest.raises(GrowthLimitError):
        derive(g, 6, max_symbols=10_000)
    g = parse_grammar("axiom: A(1)\nA(x) -> A(x)A(x)\n")
    with pytest.raises(GrowthLimitError, match="max_bytes"):
        derive(g, 25, max_bytes=1_000_000)
    with pytest.raises(ValueError, match="n: expected"):
        derive(g, 10**9)


def test_division_by_zero_names_the_line():
    g = parse_grammar("axiom: A(2)\nA(x) -> B(1 / (x - 1))\nB(y) -> A(y)\n", source="z.lsys")
    with pytest.raises(GrammarError, match=r"z.lsys: line 2, column 11: .*division by zero"):
        derive(g, 3)
