"""scanamp study STUDY.toml --out DIR [--scheduler ADDRESS] [--workers N] (or a suite)"""

import logging
from dataclasses import dataclass

from core.config import Config, option

NAME = "study"
OUTPUT = "resume"
HELP = ("run a scanner study: a grid or random sweep over capture/reconstruction "
        "parameters; resumable; writes results.csv, results.parquet and plots/ (a suite, "
        "such as 'materials', runs its studies in sub-folders and sets them side by side)")
log = logging.getLogger("scanamp")


@dataclass
class StudyOptions(Config):
    """Options of ``scanamp study`` (how it runs; what it sweeps is the study file's)."""

    workers: int = option(1, range="[1, 1024]", help="local worker processes")
    scheduler: str | None = option(None, help="Dask scheduler address (tcp://host:8786): run "
                                              "on that cluster")
    timeout: float = option(5.0, unit="s", range="(0, inf)",
                            help="time to wait for the scheduler")
    keep: bool = option(False, help="keep each run's capture and reconstruction under "
                                    "DIR/work/")
    list: bool = option(False, help="list the runs and exit")


CONFIG = StudyOptions


def add_arguments(p):
    from scanamp.study import shipped_studies

    p.add_argument("study",
                   help=f"study TOML file or shipped name ({', '.join(shipped_studies())})")
    p.add_argument("--out", required=True, help="study folder (runs already recorded there "
                   "are skipped: run the same command again to resume)")


def run(args, config: StudyOptions):
    from scanamp.study import is_suite, load_study, run_study

    if is_suite(args.study):
        return _run_suite(args, config)
    study = load_study(args.study)
    if config.list:
        for r in study.runs:
            print(r.run_id, " ".join(f"{k}={v}" for k, v in r.params.items()))
        return 0
    res = run_study(study, args.out, workers=config.workers, scheduler=config.scheduler,
                    keep=config.keep, timeout=config.timeout)
    df = res["table"]
    print(f"study {study.name!r}: {res['runs']} runs ({res['done_before']} recorded before, "
          f"{res['executed']} run now, {res['failed']} failed) -> {args.out}/results.csv")
    if len(df):
        cols = [*study.params, *study.metrics, "status"]
        _print_table(df[cols].rename(columns=lambda c: c.rsplit(".", 1)[-1]))
    return 0


def _print_table(df) -> None:
    """A results table on stdout, four significant digits."""
    import pandas as pd

    with pd.option_context("display.width", 160, "display.max_columns", 20,
                           "display.float_format", "{:.4g}".format):
        print(df.to_string(index=False))


def _run_suite(args, config: StudyOptions):
    """A suite (``materials``): its member studies in sub-folders, then its table."""
    from scanamp.study import load_study, load_suite, run_suite

    suite = load_suite(args.study)
    if config.list:
        for member in suite.studies():
            for r in load_study(member).runs:
                print(member, r.run_id, " ".join(f"{k}={v}" for k, v in r.params.items()))
        return 0
    res = run_suite(suite, args.out, workers=config.workers, scheduler=config.scheduler,
                    keep=config.keep, timeout=config.timeout)
    for name, summary in res["studies"].items():
        print(f"study {name!r}: {summary['runs']} runs ({summary['done_before']} recorded "
              f"before, {summary['executed']} run now, {summary['failed']} failed) -> "
              f"{args.out}/{name}/")
    table = res["table"]
    print(f"suite {suite.name!r} -> {args.out}/results.csv, {args.out}/plots/")
    if len(table):
        _print_table(table)
    return 0
