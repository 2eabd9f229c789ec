"""``scanamp evaluate RECON --reference GT.ply``: score a reconstruction against ground truth."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from reconstruct.evaluation.evaluate import EvaluateConfig

NAME = "evaluate"
OUTPUT = "file"
OUTPUT_DEST = "json"
CONFIG = EvaluateConfig
HELP = ("score a reconstruction (mesh or point cloud) against a ground-truth surface: "
        "precision/recall/F-score at tau, accuracy, completeness, Chamfer, Hausdorff")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("recon", type=Path, metavar="RECON",
                        help="reconstructed mesh or point cloud (.ply .obj .stl .off .glb "
                             ".pcd .xyz ...); a file without faces is a point cloud")
    parser.add_argument("--reference", type=Path, required=True, metavar="GT",
                        help="ground-truth mesh (or point cloud)")
    parser.add_argument("--json", type=Path, default=None, metavar="OUT",
                        help="also write the figures to this JSON file")
    parser.add_argument("--icp", action="store_true", help="the same as --align icp")


def run(args: argparse.Namespace, config: EvaluateConfig) -> int:
    import numpy as np

    from core.files import write_json
    from core.mesh_io import read_geometry
    from core.validate import InputError
    from reconstruct.evaluation.evaluate import evaluate
    from reconstruct.registration.rigid import LOW_FITNESS

    recon = read_geometry(args.recon)
    reference = read_geometry(args.reference)
    align = config.align
    if args.icp:
        if align not in ("none", "icp"):
            raise InputError(f"--icp contradicts --align {align}", field="--align")
        align = "icp"
    try:
        result = evaluate(recon, reference, tau=config.tau, density=config.density,
                          align=align, distance=config.distance,
                          rng=np.random.default_rng(config.seed),
                          max_samples=config.max_samples)
    except ValueError as exc:  # name the file the library's message is about
        msg = str(exc)
        for prefix, path in (("recon", args.recon), ("reference", args.reference)):
            if msg.startswith(prefix):
                raise InputError(msg, path=path) from None
        raise
    sys.stdout.write(f"{args.recon} vs {args.reference}\n{result.table()}\n")
    if result.icp_fitness is not None and result.icp_fitness < LOW_FITNESS:
        sys.stderr.write(f"warning: only {100 * result.icp_fitness:.0f}% of {args.recon} lies "
                         f"near the reference after --align {align}: these scores mean little "
                         + ("(try --align global)" if align == "icp" else
                            "(is it the same object, at the same scale?)") + "\n")
    if args.json is not None:
        write_json(args.json, {"recon": str(args.recon), "reference": str(args.reference),
                               **result.to_dict()})
    return 0
