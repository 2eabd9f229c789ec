"""``scanamp grow GRAMMAR --out plant.ply``: derive an L-system and mesh it
(``--lines curve.obj`` writes the turtle's polylines, ``--stats`` prints JSON)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

NAME = "grow"
OUTPUT = "file"
HELP = "grow an L-system grammar (a .lsys file or a shipped example name) into a mesh"


def companions(args, config=None):
    return [args.lines] if args.lines is not None else []


def add_arguments(p):
    p.add_argument("grammar", help="grammar file (.lsys) or example name, e.g. abop_1_24a")
    p.add_argument("--out", type=Path, help="mesh file: .ply, .obj, .gltf (or .stl, .off)")
    p.add_argument("--lines", type=Path,
                   help="also write the turtle's segments as polylines: .obj or .ply (2-D curves)")
    p.add_argument("-n", type=int, default=None, help="derivation steps (default: the grammar's n)")
    p.add_argument("--seed", type=int, default=0, help="seed of stochastic productions")
    p.add_argument("--sides", type=int, default=8, help="tube ring resolution")
    p.add_argument("--min-radius", type=float, default=0.0, help="thinnest tube radius (m)")
    p.add_argument("--no-leaves", action="store_true", help="leave out { . } polygons")
    p.add_argument("--stats", action="store_true",
                   help="print JSON: string length, symbol counts, drawn segments")


def run(args) -> int:
    import numpy as np

    from core.mesh_io import MESH_SUFFIXES, POLYLINE_SUFFIXES, write_mesh, write_polylines
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
    rng = np.random.default_rng(args.seed)
    try:
        string = derive(grammar, args.n, rng=rng)
    except ValueError as exc:  # a limit of the derivation: name the grammar
        raise ValueError(f"{args.grammar}: {exc}") from None
    result = interpret(string, grammar)
    if args.out is not None:
        mesh = to_mesh(result, sides=args.sides, leaves=not args.no_leaves,
                       min_radius=args.min_radius)
        write_mesh(args.out, mesh)
    if args.lines is not None:
        if len(result) == 0:
            raise ValueError(f"--lines: {args.grammar} draws no segments")
        write_polylines(args.lines, result.polylines())
    if args.stats:
        stats = {"grammar": str(args.grammar), "n": grammar.n if args.n is None else args.n,
                 "seed": args.seed, "classes": list(grammar.classes), "length": len(string),
                 "counts": string.counts(), "segments": len(result),
                 "polygons": int(len(np.unique(result.polygon_ids)))}
        sys.stdout.write(json.dumps(stats, indent=2) + "\n")
    return 0
