"""``scanamp grow GRAMMAR --out plant.ply``: derive an L-system and mesh it
(``--lines curve.obj`` writes the turtle's polylines, ``--stats`` prints JSON)."""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass
from pathlib import Path

from core.config import Config, option

NAME = "grow"
OUTPUT = "file"
HELP = "grow an L-system grammar (a .lsys file or a shipped example name) into a mesh"


def companions(args, config=None):
    return [args.lines] if args.lines is not None else []


@dataclass
class GrowConfig(Config):
    """Options of ``scanamp grow``."""

    n: int | None = option(None, range="[0, 64]", short="-n",
                           help="derivation steps (none: the grammar's n)")
    seed: int = option(0, range="[0, inf)", help="seed of stochastic productions")
    sides: int = option(8, range="[3, 256]", help="tube ring resolution")
    min_radius: float = option(0.0, unit="m", range="[0, inf)", help="thinnest tube radius")
    leaves: bool = option(True, help="draw the { . } polygons (--no-leaves leaves them out)")


CONFIG = GrowConfig


def add_arguments(p):
    p.add_argument("grammar", help="grammar file (.lsys) or example name, e.g. abop_1_24a")
    p.add_argument("--out", type=Path, help="mesh file: .ply, .obj, .gltf (or .stl, .off)")
    p.add_argument("--lines", type=Path,
                   help="also write the turtle's segments as polylines: .obj or .ply (2-D curves)")
    p.add_argument("--stats", action="store_true",
                   help="print JSON: string length, symbol counts, drawn segments")


def run(args, config: GrowConfig) -> int:
    import numpy as np

    from core.io.mesh import MESH_SUFFIXES, POLYLINE_SUFFIXES, write_mesh, write_polylines
    from procgen.lsystem import derive, interpret, load_grammar, to_mesh

    if args.out is None and args.lines is None and not args.stats:
        raise ValueError("--out: give a mesh file to write (or --lines, or --stats)")
    if args.lines is not None and args.lines.suffix.lower() not in POLYLINE_SUFFIXES:
        raise ValueError(f"--lines: expected a suffix in {', '.join(POLYLINE_SUFFIXES)}, "
                         f"got {args.lines.suffix!r}")
    if args.out is not None and args.out.suffix.lower() not in MESH_SUFFIXES:
        raise ValueError(f"--out: expected a suffix in {', '.join(MESH_SUFFIXES)}, "
                         f"got {args.out.suffix!r}")
    if args.out is not None and args.out.suffix.lower() == ".glb":
        raise ValueError("--out: open3d 0.20 writes .glb files without their binary chunk; "
                         "write .gltf instead")
    grammar = load_grammar(args.grammar)
    c = config
    rng = np.random.default_rng(c.seed)
    try:
        string = derive(grammar, c.n, rng=rng)
    except ValueError as exc:  # a limit of the derivation: name the grammar
        raise ValueError(f"{args.grammar}: {exc}") from None
    result = interpret(string, grammar)
    if args.out is not None:
        mesh = to_mesh(result, sides=c.sides, leaves=c.leaves, min_radius=c.min_radius)
        write_mesh(args.out, mesh)
    if args.lines is not None:
        if len(result) == 0:
            raise ValueError(f"--lines: {args.grammar} draws no segments")
        write_polylines(args.lines, result.polylines())
    if args.stats:
        stats = {"grammar": str(args.grammar), "n": grammar.n if c.n is None else c.n,
                 "seed": c.seed, "classes": list(grammar.classes), "length": len(string),
                 "counts": string.counts(), "segments": len(result),
                 "polygons": int(len(np.unique(result.polygon_ids)))}
        sys.stdout.write(json.dumps(stats, indent=2) + "\n")
    return 0
