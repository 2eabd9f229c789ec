"""The results of a study, rebuilt from its run records: table and plots.

``results.csv`` / ``results.parquet``: one row per recorded run of the study, in the
study's run order: ``run_id``, ``status``, ``error``, ``seconds``, one column per
swept parameter, one per metric (read from each record's report, so editing
``[output] metrics`` and re-running the study recomputes the table without redoing a
run). ``plots/<metric>_vs_<param>.png``: the metric against each swept parameter, one
line per combination of the other swept parameters (at most 10; a scatter beyond).
"""

from __future__ import annotations

import logging
import os
import re
from pathlib import Path

import numpy as np

from core.files import atomic_file

log = logging.getLogger(__name__)

__all__ = ["results_table", "write_results", "plot_name", "metric_column"]


def results_table(study, records: dict):
    """A pandas DataFrame of the recorded runs of ``study`` (see the module docstring)."""
    import pandas as pd

    from scanamp.study.kinds import get_metric

    rows = []
    for run in study.runs:
        rec = records.get(run.run_id)
        if rec is None:
            continue
        row = {"run_id": run.run_id, "status": rec.get("status"), "error": rec.get("error"),
               "seconds": rec.get("seconds")}
        for k in study.params:
            v = run.params.get(k)
            row[k] = v if not isinstance(v, list) else str(v)
        report = rec.get("report") or {}
        for m in study.metrics:
            row[metric_column(study, m)] = get_metric(report, m)
        rows.append(row)
    mcols = [metric_column(study, m) for m in study.metrics]
    cols = ["run_id", "status", "error", "seconds", *study.params, *mcols]
    df = pd.DataFrame(rows, columns=cols)
    for m in mcols:
        conv = pd.to_numeric(df[m], errors="coerce")
        if conv.notna().sum() == df[m].notna().sum():
            df[m] = conv.astype(float)
    return df


def metric_column(study, metric: str) -> str:
    """The table column of a metric (``metric:KEY`` when a swept parameter has its name)."""
    return f"metric:{metric}" if metric in study.params or metric in (
        "run_id", "status", "error", "seconds") else metric


def plot_name(metric: str, param: str) -> str:
    """File name of a plot: ``<metric>_vs_<param>.png`` with path-safe characters."""
    def safe(s):
        return re.sub(r"[^A-Za-z0-9._-]+", "_", s)

    return f"{safe(metric)}_vs_{safe(param)}.png"


def _numeric(series) -> bool:
    import pandas as pd

    return bool(len(series)) and pd.api.types.is_numeric_dtype(series) and not \
        pd.api.types.is_bool_dtype(series)


def _plot(df, study, metric: str, param: str, path: Path) -> None:
    from matplotlib.figure import Figure  # no pyplot: the caller's backend stays untouched

    ok = df[df["status"] == "ok"]
    others = [p for p in study.params if p != param]
    fig = Figure(figsize=(6.0, 4.0), dpi=110)
    ax = fig.subplots()
    xs_num = _numeric(df[param])
    cats = None if xs_num else list(dict.fromkeys(str(v) for v in df[param]))

    def xpos(vals):
        return (np.asarray(vals, float) if xs_num
                else np.array([cats.index(str(v)) for v in vals], float))

    groups = list(ok.groupby(others, sort=False, dropna=False)) if others else [((), ok)]
    lines = study.mode == "grid" and len(groups) <= 10
    for key, g in groups:
        g = g.dropna(subset=[metric])
        if not len(g):
            continue
        key = key if isinstance(key, tuple) else (key,)
        label = ", ".join(f"{p.rsplit('.', 1)[-1]}={v}" for p, v in zip(others, key,
                                                                          strict=False))
        x, y = xpos(g[param]), g[metric].to_numpy(float)
        order = np.argsort(x, kind="stable")
        if lines:
            ax.plot(x[order], y[order], "o-", label=label or None, ms=4)
        else:
            ax.plot(x, y, "o", ms=3, alpha=0.7)
    failed = df[df["status"] != "ok"]
    if len(failed):
        for xv in xpos(failed[param]):
            ax.axvline(xv, color="0.8", ls=":", lw=1)
        ax.plot([], [], color="0.6", ls=":", label=f"failed runs ({len(failed)})")
    if cats is not None:
        ax.set_xticks(range(len(cats)), cats, rotation=20)
    ax.set_xlabel(param)
    ax.set_ylabel(metric)
    ax.set_title(f"{study.name}: {metric.rsplit('.', 1)[-1]} vs {param.rsplit('.', 1)[-1]}",
                 fontsize=10)
    ax.grid(alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7)
    fig.tight_layout()
    with atomic_file(path) as tmp:
        fig.savefig(tmp, format="png")


def _leaf_keys(report, prefix: str = ""):
    """The dotted keys of the numeric leaves of a report (the keys ``get_metric`` reads)."""
    if isinstance(report, dict):
        for k, v in report.items():
            yield from _leaf_keys(v, f"{prefix}{k}.")
    elif isinstance(report, (int, float)) and prefix:
        yield prefix[:-1]


def _warn_missing_metrics(study, records: dict) -> None:
    """Warn about a metric that no finished run reports: a misspelt key in
    ``[output] metrics`` would otherwise give an empty column and no plot, silently."""
    import difflib

    from scanamp.study.kinds import get_metric

    reports = [rec["report"] for rec in records.values()
               if rec.get("status") == "ok" and isinstance(rec.get("report"), dict)]
    if not reports:
        return
    for metric in study.metrics:
        if any(get_metric(r, metric) is not None for r in reports):
            continue
        keys = sorted(set(_leaf_keys(reports[0])))
        near = difflib.get_close_matches(metric, keys, n=3, cutoff=0.5)
        hint = f"; did you mean {', '.join(near)}?" if near else ""
        log.warning("metric %s is in none of the %d finished runs' reports%s",
                    metric, len(reports), hint)


def write_results(study, records: dict, out_dir: str | os.PathLike):
    """Write ``results.csv``, ``results.parquet`` and ``plots/`` into ``out_dir``;
    returns the table."""
    out = Path(out_dir)
    df = results_table(study, records)
    with atomic_file(out / "results.csv") as tmp:
        df.to_csv(tmp, index=False)
    with atomic_file(out / "results.parquet") as tmp:
        df.to_parquet(tmp, index=False)
    _warn_missing_metrics(study, records)
    (out / "plots").mkdir(exist_ok=True)
    for metric in study.metrics:
        col = metric_column(study, metric)
        if not _numeric(df[col]) or df[col].notna().sum() == 0:
            log.info("no numeric values of %s yet: no plot", metric)
            continue
        for param in study.params:
            _plot(df, study, col, param, out / "plots" / plot_name(metric, param))
    return df
