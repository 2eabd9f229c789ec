"""scanamp study STUDY.toml --out DIR [--scheduler ADDRESS] [--workers N]"""

import logging

NAME = "study"
OUTPUT = "resume"
HELP = ("run a scanner study: a grid or random sweep over capture/reconstruction "
        "parameters; resumable; writes results.csv, results.parquet and plots/")
log = logging.getLogger("scanamp")


def add_arguments(p):
    from scanamp.study import shipped_studies

    p.add_argument("study",
                   help=f"study TOML file or shipped name ({', '.join(shipped_studies())})")
    p.add_argument("--out", required=True, help="study folder (runs already recorded there "
                   "are skipped: run the same command again to resume)")
    p.add_argument("--workers", type=int, default=1, help="local worker processes (default 1)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="Dask scheduler address (tcp://host:8786): run on that cluster")
    p.add_argument("--timeout", type=float, default=5.0,
                   help="seconds to wait for the scheduler (default 5)")
    p.add_argument("--keep", action="store_true",
                   help="keep each run's capture and reconstruction under DIR/work/")
    p.add_argument("--list", action="store_true", help="list the runs and exit")


def run(args):
    from scanamp.study import load_study, run_study

    if args.workers < 1:
        raise ValueError(f"--workers: expected a positive integer, got {args.workers}")
    if args.timeout <= 0:
        raise ValueError(f"--timeout: expected a positive number, got {args.timeout}")
    study = load_study(args.study)
    if args.list:
        for r in study.runs:
            print(r.run_id, " ".join(f"{k}={v}" for k, v in r.params.items()))
        return 0
    res = run_study(study, args.out, workers=args.workers, scheduler=args.scheduler,
                    keep=args.keep, timeout=args.timeout)
    df = res["table"]
    print(f"study {study.name!r}: {res['runs']} runs ({res['done_before']} recorded before, "
          f"{res['executed']} run now, {res['failed']} failed) -> {args.out}/results.csv")
    if len(df):
        import pandas as pd

        cols = [*study.params, *study.metrics, "status"]
        with pd.option_context("display.width", 160, "display.max_columns", 20,
                               "display.float_format", "{:.4g}".format):
            print(df[cols].rename(columns=lambda c: c.rsplit(".", 1)[-1]).to_string(index=False))
    return 0
