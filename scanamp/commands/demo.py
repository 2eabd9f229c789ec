"""``scanamp demo --out DIR [--full] [--seed N]``: the end-to-end demo (``make demo``)."""

import logging

NAME = "demo"
HELP = ("the whole pipeline in about a minute: a procedural scene captured by the laser "
        "scanner, stereo and SfM, reconstructed, scored, the best amplified and animated; "
        "writes DIR/report.html and DIR/report.json")
log = logging.getLogger("scanamp")


def add_arguments(p):
    p.add_argument("--out", required=True, help="output folder (replaced atomically)")
    p.add_argument("--seed", type=int, default=0,
                   help="seeds the scene, captures, evaluation and animation (default 0)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--full", action="store_true",
                   help="the heavier capture and reconstruction defaults (several minutes)")
    g.add_argument("--scale", choices=("default", "full", "test"), default=None,
                   help="a size preset (--full is --scale full; 'test' is the smallest)")
    p.add_argument("--methods", default="laser,stereo,sfm",
                   help="comma-separated subset of laser, stereo, sfm (default: all)")


def run(args):
    from scanamp.demo import METHODS
    from scanamp.demo import run as demo

    if args.seed < 0:
        raise ValueError(f"--seed: expected an integer >= 0, got {args.seed}")
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    bad = [m for m in methods if m not in METHODS]
    if bad or not methods:
        raise ValueError(f"--methods: expected a comma-separated subset of "
                         f"{', '.join(METHODS)}, got {args.methods!r}")
    scale = "full" if args.full else (args.scale or "default")
    rep = demo(args.out, seed=args.seed, scale=scale, methods=methods)
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
