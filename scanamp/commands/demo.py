"""scanamp demo --out DIR"""

import logging

NAME = "demo"
HELP = "run the end-to-end demo into a folder"
log = logging.getLogger("scanamp")


def add_arguments(p):
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--views", type=int, default=6)


def run(args):
    from scanamp.demo import run as demo

    if args.views < 1:
        raise ValueError(f"--views: expected at least 1, got {args.views}")
    rep = demo(args.out, seed=args.seed, views=args.views)
    print(f"demo written to {args.out} ({rep['seconds']} s)")
    print(f"  scene {rep['scene']!r}, {rep['views']} views rendered, {rep['points']} points")
    ev = rep["evaluation"]
    print(f"  F-score at {ev['tau'] * 1e3:.2f} mm: {ev['fscore']:.3f}  "
          f"accuracy {ev['accuracy_mean'] * 1e3:.3f} mm  "
          f"completeness {ev['completeness_mean'] * 1e3:.3f} mm")
    return 0
