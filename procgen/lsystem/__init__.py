"""L-systems: grammar files, derivation, a 3-D turtle, and geometry.

>>> from procgen.lsystem import load_grammar, derive
>>> s = derive(load_grammar("abop_1_24a"))
>>> len(s), s.counts()["F"]
(7811, 3125)

Public API: :func:`parse_grammar`, :func:`load_grammar`, :func:`example_names`,
:func:`derive` (and :func:`derive_reference`, the slow oracle), :func:`interpret` (the
turtle), :func:`to_mesh`, :func:`polylines`, :func:`grow` (all in one). The grammar format
and the turtle conventions are documented in ``docs/lsystem.md``.
"""

from procgen.lsystem.derive import (
    GrowthLimitError,
    LString,
    axiom_string,
    derive,
    derive_reference,
)
from procgen.lsystem.expr import ExprError, evaluate, evaluate_array, parse_expr
from procgen.lsystem.grammar import (
    Grammar,
    GrammarError,
    Module,
    Pattern,
    Production,
    example_names,
    load_grammar,
    parse_grammar,
)

__all__ = [
    "Grammar", "GrammarError", "Module", "Pattern", "Production", "parse_grammar",
    "load_grammar", "example_names", "LString", "GrowthLimitError", "derive",
    "derive_reference", "axiom_string", "ExprError", "parse_expr", "evaluate", "evaluate_array",
]

from procgen.lsystem.geometry import polygon_arrays, to_mesh, tube_arrays  # noqa: E402
from procgen.lsystem.turtle import INITIAL_FRAME, TurtleResult, interpret  # noqa: E402

__all__ += ["interpret", "TurtleResult", "INITIAL_FRAME", "to_mesh", "tube_arrays",
            "polygon_arrays"]
