"""L-system throughput: D0L derivation against a plain per-symbol Python loop (same run),
parametric derivation against the per-module reference engine, turtle + tube meshing; each
also against its absolute target (20 M symbols/s, 1 M modules/s, 1 M segments/s); and a
3-D L-system of at least 10^6 modules derived and interpreted in <= 5 s (ABOP's Honda tree,
Fig. 2.6a, n = 18, and the ternary tree with tropism, Fig. 2.8b, n = 11)."""

import numpy as np
from _timing import best_of, report

from procgen.lsystem import derive, derive_reference, interpret, load_grammar, to_mesh, tube_arrays


def _python_d0l(axiom, rules, n):
    s = axiom
    for _ in range(n):
        out = []
        for c in s:  # the plain per-symbol loop
            out.append(rules.get(c, c))
        s = "".join(out)
    return s


def main():
    cases = [("abop_1_24a", 9, "F", {"F": "F[+F]F[-F]F"}),
             ("abop_1_24d", 12, "X", {"X": "F[+X]F[-X]+X", "F": "FF"})]
    for name, n, axiom, rules in cases:
        g = load_grammar(name)
        assert derive(g, 4).symbols == _python_d0l(axiom, rules, 4)
        ours = best_of(lambda g=g, n=n: derive(g, n), repeat=3)
        length = len(derive(g, n))
        peer = best_of(lambda a=axiom, r=rules, n=n: _python_d0l(a, r, n), repeat=1)
        print(f"   D0L ({name}, n={n}, {length / 1e6:.1f} M symbols): "
              f"{length / ours / 1e6:.0f} M symbols/s; Python loop {length / peer / 1e6:.1f} M/s")
        report(f"D0L {name} vs per-symbol Python loop", 1 / ours, 1 / peer, 20.0)
        report(f"D0L {name} vs 20 M symbols/s", length / ours, 20e6, 1.0)
    g = load_grammar("abop_1_24a")

    gb = load_grammar("stochastic_bush")
    t = best_of(lambda: derive(gb, 9, rng=np.random.default_rng(0)), repeat=3)
    ls = len(derive(gb, 9, rng=np.random.default_rng(0)))
    print(f"   stochastic 0L (bush, n=9): {ls / t / 1e6:.0f} M symbols/s")

    gp = load_grammar("parametric_tree")
    n_p = 17
    tp = best_of(lambda: derive(gp, n_p), repeat=2)
    lp = len(derive(gp, n_p))
    n_ref = 10
    tr = best_of(lambda: derive_reference(gp, n_ref), repeat=1, warmup=0)
    lr = len(derive_reference(gp, n_ref))
    print(f"   parametric (ABOP 2.6 tree, n={n_p}, {lp / 1e6:.2f} M modules): "
          f"{lp / tp / 1e6:.2f} M modules/s; reference engine {lr / tr / 1e6:.3f} M/s")
    report("parametric derivation vs 1 M modules/s", lp / tp, 1e6, 1.0)
    report("parametric derivation vs per-module reference", lp / tp, lr / tr, 1.0)

    for name, n in (("abop_2_6a", 18), ("abop_2_8b", 11)):
        g3 = load_grammar(name)
        interpret(derive(g3, 4), g3)   # compile the kernels once

        def derive_interpret(g3=g3, n=n):
            s3 = derive(g3, n)
            return len(s3), len(interpret(s3, g3))

        t3 = best_of(derive_interpret, repeat=2, warmup=0)
        mods, segs = derive_interpret()
        assert mods >= 1_000_000
        print(f"   3-D derivation + turtle ({name}, n={n}, {mods / 1e6:.2f} M modules, "
              f"{segs / 1e3:.0f} k segments): {t3:.2f} s")
        report(f"3-D L-system {name}, {mods / 1e6:.1f} M modules, derive + interpret time / 5 s",
               t3, 5.0, 1.0, higher_is_better=False)

    s = derive(g, 8)

    def turtle_tubes():
        return tube_arrays(interpret(s, g), sides=8)

    tt = best_of(turtle_tubes, repeat=3)
    m = len(interpret(s, g))
    print(f"   turtle + tubes (8 sides, {m / 1e6:.2f} M segments): {m / tt / 1e6:.2f} M segments/s")
    report("turtle + tube meshing vs 1 M segments/s", m / tt, 1e6, 1.0)
    # information: the same into the canonical open3d mesh (copies + vertex normals)
    s7 = derive(g, 7)
    m7 = len(interpret(s7, g))
    tm = best_of(lambda: to_mesh(interpret(s7, g), sides=8, leaves=False, colors=False),
                 repeat=2)
    print(f"   turtle + tubes + open3d mesh with normals ({m7 / 1e3:.0f} k segments): "
          f"{m7 / tm / 1e6:.2f} M segments/s")


if __name__ == "__main__":
    main()
