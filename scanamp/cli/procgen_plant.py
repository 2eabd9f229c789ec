"""``scanamp procgen plant --out plant.ply``: the notes' context-free plant grammar
(``Tree -> Branch Tree | leaf``, ``Branch -> cylinder | [Tree]``) with rule weights, a
depth, phyllotaxis, tapering and leaves (:mod:`procgen.shape_grammar`)."""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from core.config import Config, option
from scanamp.cli._procgen_common import (
    MESH_OUT,
    add_output,
    check_out,
    labelled_companions,
    preview_path,
    render_preview,
    write_parts,
)

NAME = "plant"
GROUP = "procgen"
OUTPUT = "file"
HELP = "a plant from the weighted context-free shape grammar: bark and leaves, labelled"

log = logging.getLogger(__name__)

BARK, LEAF = (0.45, 0.33, 0.22), (0.3, 0.55, 0.2)


@dataclass
class PlantConfig(Config):
    """Options of ``scanamp procgen plant``."""

    max_depth: int = option(10, range="[1, 30]",
                            help="recursion depth after which every rule takes its shortest "
                                 "alternative")
    grammar: str | None = option(None, help="rule file (default: procgen.shape_grammar.PLANT)")
    length: float = option(1.0, unit="m", range="(0, inf)", help="length of the first segment")
    radius: float = option(0.08, unit="m", range="(0, inf)", help="radius of the trunk")
    shrink: float = option(0.9, range="(0, 1]", help="taper per segment")
    branch_shrink: float = option(0.75, range="(0, 1]", help="scale of a side branch")


CONFIG = PlantConfig


def companions(args, config=None):
    return labelled_companions(args)


def add_arguments(p):
    add_output(p, kind="mesh")


def run(args, config: PlantConfig) -> int:
    from core.files import read_text
    from core.meshes import make_mesh
    from procgen.shape_grammar import (
        PLANT,
        derive_sentence,
        interpret_sentence,
        parse_shape_grammar,
    )

    out = check_out(args.out, MESH_OUT)
    text = PLANT if config.grammar is None else read_text(config.grammar)
    grammar = parse_shape_grammar(text, source=config.grammar)
    rng = np.random.default_rng(args.seed)
    sentence = derive_sentence(grammar, rng, max_depth=config.max_depth)
    v, f, leaf = interpret_sentence(sentence, rng, length=config.length, radius=config.radius,
                                    shrink=config.shrink, branch_shrink=config.branch_shrink,
                                    leaves=True)
    if len(f) == 0:
        raise RuntimeError("the derivation drew nothing (no cylinder or leaf terminal)")
    tri_leaf = leaf[f[:, 0]]
    parts = [(make_mesh(v, f[sel]), kind, rgb) for sel, kind, rgb in
             ((~tri_leaf, "bark", BARK), (tri_leaf, "leaf", LEAF)) if sel.any()]
    write_parts(out, parts, label_of={"bark": "bark", "leaf": "leaf"})
    log.info("wrote %s: %d branches, %d segments, %d leaves", out, sentence.count("["),
             sentence.count("cylinder"), sentence.count("leaf"))
    if not args.no_preview:
        log.info("wrote %s", render_preview([(m, c) for m, _, c in parts], preview_path(out)))
    return 0
