"""``scanamp evaluate RECON --reference GT.ply``: score a reconstruction against ground truth."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

NAME = "evaluate"
OUTPUT = "file"
OUTPUT_DEST = "json"
HELP = ("score a reconstruction (mesh or point cloud) against a ground-truth surface: "
        "precision/recall/F-score at tau, accuracy, completeness, Chamfer, Hausdorff")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("recon", type=Path, metavar="RECON",
                        help="reconstructed mesh or point cloud (.ply .obj .stl .off .glb "
                             ".pcd .xyz ...); a file without faces is a point cloud")
    parser.add_argument("--reference", type=Path, required=True, metavar="GT",
                        help="ground-truth mesh (or point cloud)")
    parser.add_argument("--tau", type=float, default=None, metavar="METRES",
                        help="F-score threshold in metres (default: 0.5%% of the reference's "
                             "bounding-box diagonal)")
    parser.add_argument("--json", type=Path, default=None, metavar="OUT",
                        help="also write the figures to this JSON file")
    parser.add_argument("--align", choices=("none", "icp", "global"), default=None,
                        help="align RECON to the reference before scoring: 'icp' from where it "
                             "is, 'global' from any frame (a turntable, SfM or handheld scan: "
                             "seeded coarse registration, then ICP); default none")
    parser.add_argument("--icp", action="store_true", help="the same as --align icp")
    parser.add_argument("--distance", choices=("surface", "samples"), default="surface",
                        help="measure to the other mesh's surface (default, exact) or to its "
                             "nearest sample (the Tanks and Temples / DTU protocol)")
    parser.add_argument("--seed", type=int, default=0, help="sampling seed (default 0)")
    parser.add_argument("--density", type=float, default=None, metavar="PER_M2",
                        help="samples per square metre (default: 8 / tau^2)")
    parser.add_argument("--max-samples", type=int, default=None, metavar="N",
                        help="cap on samples per side (default 200000)")


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from core.files import write_json
    from core.mesh_io import read_geometry
    from core.validate import InputError
    from reconstruct.evaluate import DEFAULT_MAX_SAMPLES, evaluate

    recon = read_geometry(args.recon)
    reference = read_geometry(args.reference)
    max_samples = DEFAULT_MAX_SAMPLES if args.max_samples is None else args.max_samples
    try:
        if args.icp and args.align not in (None, "icp"):
            raise InputError(f"--icp contradicts --align {args.align}", field="--align")
        align = args.align or ("icp" if args.icp else "none")
        result = evaluate(recon, reference, tau=args.tau, density=args.density, align=align,
                          distance=args.distance,
                          rng=np.random.default_rng(args.seed), max_samples=max_samples)
    except ValueError as exc:  # name the file the library's message is about
        msg = str(exc)
        for prefix, path in (("recon", args.recon), ("reference", args.reference)):
            if msg.startswith(prefix):
                raise InputError(msg, path=path) from None
        for option in ("tau", "density", "max_samples"):
            if msg.startswith(option + ":"):
                raise InputError(msg[len(option) + 1:].strip(),
                                 field="--" + option.replace("_", "-")) from None
        raise
    sys.stdout.write(f"{args.recon} vs {args.reference}\n{result.table()}\n")
    from reconstruct.registration import LOW_FITNESS

    if result.icp_fitness is not None and result.icp_fitness < LOW_FITNESS:
        sys.stderr.write(f"warning: only {100 * result.icp_fitness:.0f}% of {args.recon} lies "
                         f"near the reference after --align {align}: these scores mean little "
                         + ("(try --align global)" if align == "icp" else
                            "(is it the same object, at the same scale?)") + "\n")
    if args.json is not None:
        write_json(args.json, {"recon": str(args.recon), "reference": str(args.reference),
                               **result.to_dict()})
    return 0
