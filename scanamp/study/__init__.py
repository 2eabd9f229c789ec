"""Scanner studies: grid or random sweeps over capture and reconstruction parameters.

Usage (not run as a doctest: it runs the whole study)::

    from scanamp.study import load_study, run_study
    study = load_study("laser-angle")                    # a shipped name or a TOML path
    summary = run_study(study, "out/laser-angle", workers=2)
    summary["table"]                                     # also out/.../results.csv

See ``docs/study.md`` for the file format and the shipped studies.
"""

from scanamp.cluster import connect
from scanamp.study.kinds import KINDS, get_metric, score_peaks
from scanamp.study.results import results_table, write_results
from scanamp.study.runner import execute_run, load_records, run_study
from scanamp.study.spec import Run, Study, load_study, run_id, shipped_studies, study_path
from scanamp.study.suite import Suite, is_suite, load_suite, run_suite, suite_table

__all__ = ["KINDS", "Run", "Study", "Suite", "connect", "execute_run", "get_metric",
           "is_suite", "load_records", "load_study", "load_suite", "public_kinds",
           "results_table", "run_id", "run_study", "run_suite", "score_peaks",
           "shipped_studies", "study_path", "suite_table", "write_results"]


def public_kinds() -> list[str]:
    """The study kinds users name (``_test`` is the runner's own test kind)."""
    return sorted(k for k in KINDS if not k.startswith("_"))
