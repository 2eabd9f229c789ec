"""Derivation oracles from The Algorithmic Beauty of Plants, and engines agreeing."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

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


def test_acropetal_fig_1_31a_first_steps_by_hand():
    # ABOP Fig. 1.31a derived by hand (ignore +-F; modules at the ends of the string or of a
    # branch lack a context and are copied; '+' and '-' swap every step)
    g = load_grammar("acropetal")
    expected = ["F1F1F1", "F1F0F1", "F1F1F1F1", "F1F0F0F1", "F1F0F1[+F1F1]F1",
                "F1F1F1F1[-F0F1]F1"]
    for k, want in enumerate(expected):
        assert derive(g, k).symbols == want
        assert derive_reference(g, k).symbols == want


def test_basipetal_signal_enters_from_any_sibling_branch():
    g = load_grammar("basipetal")
    want = ["Fa[+Fa][-Fa[+Fa][-Fb]Fa]Fa", "Fa[+Fa][-Fb[+Fa][-Fa]Fa]Fa",
            "Fb[+Fa][-Fa[+Fa][-Fa]Fa]Fa", "Fa[+Fa][-Fa[+Fa][-Fa]Fa]Fa"]
    for k, s in enumerate(want):
        assert derive(g, k).symbols == s
        assert derive(g, k, method="general").symbols == s
        assert derive_reference(g, k).symbols == s


@pytest.mark.parametrize("axiom, rule, rewritten", [
    ("A[C][B]D", "A > [B] -> X", True),       # the second sibling branch matches
    ("A[C][B]D", "A > [B]D -> X", True),      # then D after all the branches
    ("A[C][B]D", "A > [D] -> X", False),      # D is not in a branch
    ("A[C][B]", "A > [B][C] -> X", False),    # sibling branches are matched in order
    ("A[B][C]", "A > [B][C] -> X", True),
    ("A+[-C]+[+B]", "A > [B] -> X", True),    # ignored symbols between and inside branches
    ("A[B[C]][B[D]]E", "A > [B[D]]E -> X", True),   # nested pattern: the first branch fails
    ("A[B[C]][B[D]]E", "A > [B[E]] -> X", False),
    ("AB[C]D", "A > B[C]D -> X", True),       # ABOP's G[H]M form
    ("AB[C]D", "A > BD -> X", True),          # a branch not in the pattern is skipped
])
def test_right_context_across_branches(axiom, rule, rewritten):
    g = parse_grammar(f"axiom: {axiom}\nignore: +-\nsymbols: ABCDEX\n{rule}\n")
    want = ("X" + axiom[1:]) if rewritten else axiom
    assert derive(g, 1).symbols == want
    assert derive(g, 1, method="general").symbols == want
    assert derive_reference(g, 1).symbols == want


def test_right_context_binds_parameters_inside_branches():
    g = parse_grammar("axiom: A(1)[B(5)][C(7)]\nsymbols: BC\nA(x) > [C(y)] -> A(x + y)\n")
    assert derive(g, 1).text() == "A(8)[B(5)][C(7)]"
    assert derive_reference(g, 1).text() == "A(8)[B(5)][C(7)]"


@pytest.mark.parametrize("axiom, rule, want", [
    ("F[A]F[B]FA", "A -> F%X", "F[F]F[B]FF"),   # cut to the end of the branch / string
    ("[A[B]C]D", "A -> %", "[]D"),               # nested branches after % go too
    ("A%[B]C[D]", "B -> BB", "A"),               # a % in the axiom cuts after step 1
    ("FA", "A -> [%F]FA", "F[]FA"),
])
def test_cut_symbol(axiom, rule, want):
    g = parse_grammar(f"axiom: {axiom}\nsymbols: ABCDX\n{rule}\n")
    assert g.has_cut
    assert derive(g, 1).symbols == want
    assert derive(g, 1, method="general").symbols == want
    assert derive_reference(g, 1).symbols == want


def test_cut_prunes_growth_every_step():
    # a branch apex that grows, then is cut when it gets old: the tree stays bounded
    g = parse_grammar("axiom: A(0)\nA(t) : t < 3 -> F[+A(t + 1)]A(t + 1)\n"
                      "A(t) : t >= 3 -> %\n")
    for k in (4, 6):
        s = derive(g, k)
        assert s.text() == derive_reference(g, k).text()
        assert "%" not in s.symbols and "A" not in s.symbols
    assert derive(g, 6).symbols == derive(g, 4).symbols  # nothing grows after the cut
    assert len(interpret(derive(g, 6), g)) == 7  # 1 + 2 + 4 internodes


def _bracketed(draw_items):
    """A balanced bracketed string from a list of (kind, symbol) draws."""
    out, depth = [], 0
    for kind, sym in draw_items:
        if kind == 0:
            out.append(sym)
        elif kind == 1:
            out.append("[")
            depth += 1
        elif depth:
            out.append("]")
            depth -= 1
    return "".join(out) + "]" * depth


@settings(max_examples=60, deadline=None)
@given(axiom=st.lists(st.tuples(st.integers(0, 2), st.sampled_from("abc+")), min_size=1,
                      max_size=30),
       right=st.lists(st.tuples(st.integers(0, 2), st.sampled_from("abc")), min_size=1,
                      max_size=5),
       left=st.text(alphabet="abc", max_size=2),
       ignore=st.sampled_from(["", "+", "+c"]))
def test_context_matching_agrees_with_the_reference(axiom, right, left, ignore):
    # random bracketed strings and random (bracketed) right contexts: the compiled matcher
    # and the plain Python one rewrite exactly the same modules
    ax = "a" + _bracketed(axiom)
    rc = _bracketed(right).strip("]") or "a"
    lhs = (f"{left} < " if left else "") + f"a > {rc}"
    text = f"axiom: {ax}\nsymbols: abcX\n" + (f"ignore: {ignore}\n" if ignore else "") + \
        f"{lhs} -> X\n"
    g = parse_grammar(text)
    assert derive(g, 1).symbols == derive_reference(g, 1).symbols
