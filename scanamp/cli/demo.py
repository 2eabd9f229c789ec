"""``scanamp demo --out DIR [--full] [--seed N]``: the end-to-end demo (``make demo``)."""

import logging
from dataclasses import dataclass

from core.config import Config, option

NAME = "demo"
HELP = ("the whole pipeline in about a minute: a procedural scene captured by the laser "
        "scanner, stereo and SfM, reconstructed, scored, the best amplified and animated; "
        "writes DIR/report.html and DIR/report.json")
log = logging.getLogger("scanamp")


@dataclass
class DemoOptions(Config):
    """Options of ``scanamp demo``."""

    seed: int = option(0, range="[0, inf)",
                       help="seeds the scene, captures, evaluation and animation")
    scale: str = option("default", choices=("default", "full", "test"),
                        help="a size preset ('test' is the smallest)")
    full: bool = option(False, help="the heavier capture and reconstruction defaults (several "
                                    "minutes); the same as --scale full")
    methods: tuple[str, ...] = option(("laser", "stereo", "sfm"),
                                      help="comma-separated subset of laser, stereo, sfm")


CONFIG = DemoOptions


def add_arguments(p):
    p.add_argument("--out", required=True, help="output folder (replaced atomically)")


def run(args, config: DemoOptions):
    from scanamp.demo import METHODS
    from scanamp.demo import run as demo

    methods = [m.strip() for m in config.methods if m.strip()]
    bad = [m for m in methods if m not in METHODS]
    if bad or not methods:
        raise ValueError(f"--methods: expected a comma-separated subset of "
                         f"{', '.join(METHODS)}, got {','.join(config.methods)!r}")
    if config.full and config.scale not in ("default", "full"):
        raise ValueError(f"--full contradicts --scale {config.scale}")
    scale = "full" if config.full else config.scale
    rep = demo(args.out, seed=config.seed, scale=scale, methods=methods)
    tau_mm = rep["tau"] * 1e3
    lines = [f"{'method':<8}{'points':>9}{'F@' + format(tau_mm, '.2f') + 'mm':>11}"
             f"{'acc mm':>9}{'comp mm':>9}{'Chamfer':>9}{'time s':>8}"]
    for m in rep["methods"]:
        if not m["ok"]:
            lines.append(f"{m['method']:<8} failed: {m['error']}")
            continue
        lines.append(f"{m['method']:<8}{m['points']:>9}{m['fscore']:>11.3f}"
                     f"{1e3 * m['accuracy_mean']:>9.2f}{1e3 * m['completeness_mean']:>9.2f}"
                     f"{1e3 * m['chamfer']:>9.2f}{m['seconds']:>8.1f}")
    log.info("\n".join(lines))
    log.info("best: %s; report: %s/report.html (%.1f s, seed %d)", rep["best"], args.out,
             rep["timings"]["total"], rep["seed"])
    return 0
