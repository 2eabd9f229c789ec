"""Suites: several studies sharing one swept parameter, set side by side.

A suite file has a ``[suite]`` table (its ``name`` and ``rows``, the parameter every
member study sweeps) and one ``[[method]]`` table per method: its ``name``, the ``study``
that measures it (a shipped name or a path beside the suite file) and where that study's
results keep the four measures of the comparison (``fscore``, ``precision``,
``recall``, ``bias``: metric keys of the study's ``[output]``). One study may serve two
methods (the stereo study scores the passive and the active pair).

:func:`run_suite` runs each member study, resumably, in its own sub-folder of the
suite's folder, then writes ``results.csv`` (one row per method and row value: F-score,
outliers ``1 - precision``, dropout ``1 - recall``, bias) and one grouped bar plot per
measure under ``plots/``. The shipped suite is ``materials``: which scanning
method fails on which surface.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

from core.files import atomic_file, read_toml
from core.validate import InputError
from scanamp.study.spec import load_study, study_path

__all__ = ["Suite", "SuiteMethod", "is_suite", "load_suite", "run_suite", "suite_table",
           "MEASURES"]

log = logging.getLogger(__name__)

#: The measures of a suite's table: (column, label, what it is).
MEASURES = (("fscore", "F-score", "at the member study's tau"),
            ("outliers", "outliers (1 - precision)", "reconstructed points off the surface"),
            ("dropout", "dropout (1 - recall)", "surface the method did not reconstruct"),
            ("bias", "bias (m)", "mean signed distance of the inliers along the normal"))
_KEYS = ("fscore", "precision", "recall", "bias")


@dataclass(frozen=True)
class SuiteMethod:
    """One method of a suite: its name, its study and its metric keys."""

    name: str
    study: str
    fscore: str
    precision: str
    recall: str
    bias: str


@dataclass(frozen=True)
class Suite:
    """A loaded suite: its name, the shared row parameter and its methods."""

    name: str
    rows: str
    methods: tuple
    path: Path

    def studies(self) -> list[str]:
        """The member studies, each once, in the order of the methods."""
        return list(dict.fromkeys(m.study for m in self.methods))


def is_suite(name_or_path: str | Path) -> bool:
    """Whether a shipped name or a TOML path is a suite (has a ``[suite]`` table)."""
    path = study_path(name_or_path)
    return path.is_file() and "suite" in read_toml(path)


def _member_path(study: str, suite_file: Path) -> str:
    beside = suite_file.parent / study
    return str(beside) if beside.suffix == ".toml" and beside.is_file() else study


def load_suite(name_or_path: str | Path) -> Suite:
    """Read and check a suite; every member study is loaded and validated too.

    Raises InputError naming the file and the field (an unknown table, a method without
    a study or a measure, a member that does not sweep ``rows`` or does not output a
    measure's metric)."""
    path = study_path(name_or_path)
    data = read_toml(path)
    for key in data:
        if key not in ("suite", "method"):
            raise InputError("unknown table; expected suite and method", path=path, field=key)
    head = data["suite"]
    if not isinstance(head, dict):
        raise InputError("expected a table", path=path, field="suite")
    for key in ("name", "rows"):
        if not isinstance(head.get(key), str) or not head[key]:
            raise InputError("expected a non-empty string", path=path, field=f"suite.{key}")
    raw = data.get("method")
    if not isinstance(raw, list) or not raw:
        raise InputError("expected at least one [[method]] table", path=path, field="method")
    methods, loaded = [], {}
    for i, m in enumerate(raw):
        if not isinstance(m, dict):
            raise InputError("expected a table", path=path, field=f"method[{i}]")
        for key in ("name", "study", *_KEYS):
            if not isinstance(m.get(key), str) or not m[key]:
                raise InputError("expected a non-empty string", path=path,
                                 field=f"method[{i}].{key}")
        extra = set(m) - {"name", "study", *_KEYS}
        if extra:
            raise InputError(f"unknown key {sorted(extra)[0]!r}", path=path,
                             field=f"method[{i}]")
        member = _member_path(m["study"], path)
        if member not in loaded:
            loaded[member] = load_study(member)
        study = loaded[member]
        if head["rows"] not in study.params:
            raise InputError(f"study {study.name!r} does not sweep {head['rows']!r}",
                             path=path, field=f"method[{i}].study")
        for key in _KEYS:
            if m[key] not in study.metrics:
                raise InputError(f"study {study.name!r} does not output {m[key]!r}",
                                 path=path, field=f"method[{i}].{key}")
        methods.append(SuiteMethod(m["name"], member, *(m[k] for k in _KEYS)))
    return Suite(head["name"], head["rows"], tuple(methods), path)


def suite_table(suite: Suite, tables: dict):
    """The suite's table from its member studies' result tables (``{study: DataFrame}``):
    one row per method and row value, in the members' sweep order."""
    import numpy as np
    import pandas as pd

    rows = []
    for m in suite.methods:
        df = tables[m.study]
        for _, r in df.iterrows():
            ok = r.get("status") == "ok"

            def get(key, r=r, ok=ok):
                v = r.get(key) if ok else None
                return float(v) if v is not None and pd.notna(v) else np.nan

            rows.append({"method": m.name, suite.rows: r[suite.rows],
                         "fscore": get(m.fscore), "outliers": 1.0 - get(m.precision),
                         "dropout": 1.0 - get(m.recall), "bias": get(m.bias),
                         "status": r.get("status")})
    return pd.DataFrame(rows, columns=["method", suite.rows, *(k for k, *_ in MEASURES),
                                       "status"])


def _plot(table, suite: Suite, column: str, label: str, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    values = list(dict.fromkeys(table[suite.rows]))
    methods = list(dict.fromkeys(table["method"]))
    width = 0.8 / len(methods)
    fig, ax = plt.subplots(figsize=(1.0 + 0.9 * len(values), 3.8))
    x = np.arange(len(values))
    for k, name in enumerate(methods):
        sub = table[table["method"] == name].set_index(suite.rows)[column]
        y = [sub.get(v, np.nan) for v in values]
        ax.bar(x + (k - (len(methods) - 1) / 2) * width, y, width, label=name)
    ax.set_xticks(x, [str(v) for v in values], rotation=30, ha="right", fontsize=8)
    ax.set_ylabel(label)
    ax.set_title(f"{suite.name}: {label} by method and {suite.rows}", fontsize=9)
    ax.axhline(0.0, color="0.3", lw=0.6)
    ax.legend(fontsize=7, ncol=min(len(methods), 6), loc="upper center",
              bbox_to_anchor=(0.5, -0.38), frameon=False)
    fig.tight_layout()
    with atomic_file(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)


def run_suite(suite: Suite, out_dir, **run_options) -> dict:
    """Run every member study into ``out_dir/<study name>/`` (resumable, as
    :func:`scanamp.study.run_study`, which takes ``run_options``), then write the
    suite's ``results.csv`` and ``plots/<measure>.png``.

    Returns ``{"studies": {name: run_study's summary}, "table": DataFrame}``."""
    from scanamp.study.runner import run_study

    out = Path(out_dir)
    summaries, tables = {}, {}
    for member in suite.studies():
        study = load_study(member)
        log.info("suite %r: study %r", suite.name, study.name)
        summaries[study.name] = run_study(study, out / study.name, **run_options)
        tables[member] = summaries[study.name]["table"]
    table = suite_table(suite, tables)
    with atomic_file(out / "results.csv") as tmp:
        table.to_csv(tmp, index=False)
    (out / "plots").mkdir(exist_ok=True)
    for column, label, _ in MEASURES:
        if table[column].notna().any():
            _plot(table, suite, column, label, out / "plots" / f"{column}.png")
    return {"studies": summaries, "table": table}
