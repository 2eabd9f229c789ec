"""``scanamp procgen tree-laws QSM.csv --out laws.json``: measure a tree's QSM (ours or a
TreeQSM export) against the laws of real trees (:mod:`procgen.weber_penn.laws`)."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from core.config import Config, option

NAME = "tree-laws"
GROUP = "procgen"
OUTPUT = "file"
HELP = ("measure a QSM: Leonardo's exponent at the forks, taper, branching and divergence "
        "angles, dbh")

log = logging.getLogger(__name__)


@dataclass
class TreeLawsConfig(Config):
    """Options of ``scanamp procgen tree-laws``."""

    min_radius: float = option(0.0, unit="m", range="[0, inf)",
                               help="leave out forks whose parent cylinder is thinner (the "
                                    "noisy twigs of a scanned tree)")


CONFIG = TreeLawsConfig


def add_arguments(p):
    p.add_argument("qsm", type=Path, help="cylinder table (.csv): scanamp's or TreeQSM's")
    p.add_argument("--out", required=True, type=Path, help="the measures as JSON")


def measure(qsm, *, min_radius: float = 0.0) -> dict:
    """The laws measured on ``qsm`` as a JSON-ready dict."""
    from procgen.weber_penn import laws

    D = laws.leonardo_exponents(qsm, min_radius=min_radius)
    ang = laws.branching_angles(qsm)
    div = laws.divergence_angles(qsm)
    z = qsm.end[:, 2]
    return {"cylinders": len(qsm), "height": float(z.max() - qsm.start[:, 2].min()),
            "dbh": laws.dbh(qsm), "forks": int(len(D)),
            "leonardo_median": float(np.median(D)) if len(D) else None,
            "leonardo_iqr": ([float(np.percentile(D, 25)), float(np.percentile(D, 75))]
                             if len(D) else None),
            "taper": laws.taper(qsm),
            "branching_angle_median": {str(k): float(np.median(v)) for k, v in ang.items()},
            "divergence_median": float(np.median(div)) if len(div) else None}


def run(args, config: TreeLawsConfig) -> int:
    from core.files import write_json
    from core.io.qsm import read_qsm_csv

    if args.out.suffix.lower() != ".json":
        raise ValueError(f"--out: expected a .json file, got {str(args.out)!r}")
    qsm = read_qsm_csv(args.qsm)           # not a tree: exits 2, nothing written
    write_json(args.out, measure(qsm, min_radius=config.min_radius))
    log.info("wrote %s", args.out)
    return 0
