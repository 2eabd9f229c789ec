"""Running a study: one task per run, records on disk, resume, results at the end.

Each finished run (success or failure) is one JSON record ``DIR/runs/<run_id>.json``,
written atomically (temporary sibling + rename) as the run's last act. A study
started again skips every run that has a record, so a study killed at any moment
resumes without redoing a finished run or losing one: a run that was mid-way when
killed has no record and runs again from scratch. A run works in a scratch folder
``DIR/.scanamp-scratch-XXXXXXXX`` (never in the system temporary directory), removed when
it ends, well or not; those of runs killed outright are removed when the study resumes.
One process runs a study folder at a time (:func:`core.files.hold`).

Executors
---------
Local (default): a ``concurrent.futures.ProcessPoolExecutor`` over *spawned* worker
processes. Spawn, not fork: the parent may already hold OpenMP/numba/Embree thread
pools, which a fork copies in a broken state. No scheduler process, no ports: a study
on a laptop needs nothing more, and the worker writes its own record, so a record
exists exactly when the run finished. A worker that dies (a segfault in a native
library) breaks the pool; the runs that were in flight are then retried one at a
time in a fresh single-worker pool, and the one that kills its worker again is
recorded as failed with that message; the study goes on.

Dask (``scheduler="tcp://host:8786"``): each run is a ``dask.distributed`` task; the
client writes the record when the result arrives (workers may run on machines that
do not share this folder). A scheduler that cannot be reached within ``timeout``
seconds is an input error.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import logging
import multiprocessing
import os
import shutil
import socket
import tempfile
import time
import traceback
from pathlib import Path

from core.files import hold, read_json, remove_stale, scratch_dir, write_declared, write_json
from core.progress import track
from core.runs.outputs import read_manifest
from core.validate import InputError
from scanamp.cluster import connect

log = logging.getLogger(__name__)

__all__ = ["run_study", "execute_run", "load_records", "RECORD_FORMAT"]

RECORD_FORMAT = "scanamp.study-run/1"
_PARENT_PID: int | None = None


def _task(study, run, record_dir: Path | None, keep_dir: Path | None) -> dict:
    return {"run_id": run.run_id, "kind": study.kind, "scene": study.scene, "seed": run.seed,
            "params": run.params, "overrides": run.overrides, "metrics": list(study.metrics),
            "record_path": str(record_dir / f"{run.run_id}.json") if record_dir else None,
            "keep_dir": str(keep_dir) if keep_dir else None,
            "scratch_root": str(record_dir.parent) if record_dir else None}


def execute_run(task: dict) -> dict:
    """Execute one run (in a worker); returns its record (and writes it when the task
    names a ``record_path``). Never raises for a failing run: the error is recorded."""
    from scanamp.study.kinds import (
        KINDS,
        RunFailed,
        build_configs,
        get_metric,
        material_overrides,
    )

    if _PARENT_PID is not None and os.getppid() != _PARENT_PID:
        os._exit(3)  # orphaned by a killed study: do not start runs nobody will collect
    t0 = time.perf_counter()
    kind = KINDS[task["kind"]]
    rec = {"format": RECORD_FORMAT, "run_id": task["run_id"], "kind": task["kind"],
           "scene": task["scene"], "seed": task["seed"], "params": task["params"],
           "overrides": task["overrides"], "host": socket.gethostname(), "pid": os.getpid()}
    if task.get("keep_dir"):
        work = Path(task["keep_dir"]) / task["run_id"]
        shutil.rmtree(work, ignore_errors=True)
        work.mkdir(parents=True)
        cleanup = None
    else:
        cleanup = contextlib.ExitStack()
        work = Path(cleanup.enter_context(_scratch(task)))
    try:
        cap_cfg, rec_cfg = build_configs(kind, task["overrides"], work / "capture.toml")
        report = kind.execute(cap_cfg, rec_cfg, scene=task["scene"], seed=task["seed"],
                              work=work, material=material_overrides(task["overrides"]))
        rec.update(status="ok", error=None, report=report)
    except Exception as exc:  # a failing run is a result of the study, not its end
        log.debug("run %s failed", task["run_id"], exc_info=True)
        rec.update(status="failed", error=f"{type(exc).__name__}: {exc}",
                   traceback=traceback.format_exc(limit=8),
                   report=getattr(exc, "report", None) if isinstance(exc, RunFailed) else None)
    finally:
        if cleanup is not None:
            cleanup.close()
    rec["seconds"] = round(time.perf_counter() - t0, 3)
    rec["metrics"] = {m: get_metric(rec.get("report") or {}, m) for m in task["metrics"]}
    if task.get("record_path"):
        write_json(task["record_path"], rec)
    return rec


def _scratch(task: dict):
    """The run's scratch folder: under the study folder (:func:`core.files.scratch_dir`,
    removed on success and failure, and by the next resume after a kill), or, on a Dask
    worker that does not share that folder, a temporary folder of the worker's machine."""
    if task.get("scratch_root"):
        return scratch_dir(task["scratch_root"])
    return tempfile.TemporaryDirectory(prefix=f"scanamp-run-{task['run_id'][:40]}-")


def load_records(out_dir: str | os.PathLike) -> dict[str, dict]:
    """Every run record of a study folder, by run id (unreadable ones are skipped)."""
    runs = Path(out_dir) / "runs"
    out = {}
    for p in sorted(runs.glob("*.json")) if runs.is_dir() else []:
        try:
            rec = read_json(p)
        except InputError:
            log.warning("skipping an unreadable record %s", p)
            continue
        if isinstance(rec, dict) and rec.get("format") == RECORD_FORMAT and rec.get("run_id"):
            out[rec["run_id"]] = rec
    return out


def _init_worker(parent_pid: int, level: int) -> None:
    global _PARENT_PID
    _PARENT_PID = parent_pid
    os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")
    logging.basicConfig(level=level, format="%(message)s")
    import cv2  # noqa: F401  (cv2 before pycolmap, as in the CLI)


def _pool(workers: int) -> cf.ProcessPoolExecutor:
    return cf.ProcessPoolExecutor(
        max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
        initializer=_init_worker,
        initargs=(os.getpid(), logging.getLogger().getEffectiveLevel()))


def _run_local(tasks: list[dict], workers: int, done_cb) -> None:
    pending = list(tasks)
    suspects: list[dict] = []
    with _pool(workers) as ex:
        futs = {ex.submit(execute_run, t): t for t in pending}
        for fut in cf.as_completed(futs):
            try:
                done_cb(fut.result())
            except cf.process.BrokenProcessPool:
                suspects.append(futs[fut])
    for t in suspects:  # a worker died: find which run kills it, one at a time
        with _pool(1) as ex:
            try:
                done_cb(ex.submit(execute_run, t).result())
            except cf.process.BrokenProcessPool:
                rec = _crash_record(t, "the worker process died while running it")
                write_json(t["record_path"], rec)
                done_cb(rec)


def _crash_record(task: dict, message: str) -> dict:
    return {"format": RECORD_FORMAT, "run_id": task["run_id"], "kind": task["kind"],
            "scene": task["scene"], "seed": task["seed"], "params": task["params"],
            "overrides": task["overrides"], "status": "failed", "error": message,
            "report": None, "seconds": None, "metrics": {m: None for m in task["metrics"]}}


def _run_dask(tasks: list[dict], client, done_cb) -> None:
    from distributed import as_completed

    futs = {}
    for t in tasks:
        t = {**t, "record_path": None, "keep_dir": None,  # workers may not see this folder
             "scratch_root": None}
        futs[client.submit(execute_run, t, key=f"scanamp-study-{t['run_id']}", pure=False)] = t
    with client.as_current():
        for fut in as_completed(list(futs)):
            t = futs[fut]
            try:
                rec = fut.result()
            except Exception as exc:  # the worker died (KilledWorker) or the task was lost
                rec = _crash_record(t, f"{type(exc).__name__}: {exc}")
            done_cb(rec)


def run_study(study, out_dir: str | os.PathLike, *, workers: int = 1,
              scheduler: str | None = None, client=None, keep: bool = False,
              timeout: float = 5.0) -> dict:
    """Run every unrecorded run of ``study`` into ``out_dir``, then rebuild the results.

    Parameters
    ----------
    study : scanamp.study.Study
    out_dir : path
        Study folder: ``runs/``, ``results.csv``, ``results.parquet``, ``plots/``,
        ``study.toml`` (a copy of the spec).
    workers : int
        Local worker processes (ignored with a scheduler or client).
    scheduler : str, optional
        Address of a Dask scheduler (``tcp://host:8786``).
    client : distributed.Client, optional
        An existing client (takes precedence over ``scheduler``).
    keep : bool
        Keep every run's capture and reconstruction under ``out_dir/work/<run_id>``
        (local workers only).
    timeout : float
        Seconds to wait for the scheduler.

    Returns
    -------
    dict
        ``{"runs", "done_before", "executed", "failed", "table"}``.
    """
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers: expected a positive integer, got {workers!r}")
    own_client = None
    if client is None and scheduler:  # before touching the folder: a bad address leaves none
        client = own_client = connect(scheduler, timeout=timeout)
    out = Path(out_dir)
    try:
        with hold(out):  # one study process per folder
            return _run_study(study, out, workers=workers, client=client, keep=keep)
    finally:
        if own_client is not None:
            own_client.close()


def _run_study(study, out: Path, *, workers, client, keep) -> dict:
    (out / "runs").mkdir(parents=True, exist_ok=True)
    for left in remove_stale(out):  # scratch and temporaries of a study killed before
        log.info("removed %s, left by an earlier run that was killed", left)
    if read_manifest(out) is None:  # ours from the first run on, so a killed study resumes
        write_declared(out, out)
    if study.path is not None:
        spec_copy = out / "study.toml"
        if not spec_copy.exists():
            shutil.copyfile(study.path, spec_copy)
    records = load_records(out)
    wanted = {r.run_id for r in study.runs}
    stale = sorted(set(records) - wanted)
    if stale:
        log.warning("%d record(s) in %s belong to another version of the study; ignored",
                    len(stale), out / "runs")
    todo = [r for r in study.runs if r.run_id not in records]
    done_before = len(study.runs) - len(todo)
    log.info("study %r (%s): %d runs, %d already recorded, %d to run", study.name, study.kind,
             len(study.runs), done_before, len(todo))
    executed = 0
    if todo:
        keep_dir = out / "work" if keep and client is None else None
        tasks = [_task(study, r, out / "runs", keep_dir) for r in todo]
        bar = track(range(len(tasks)), f"study {study.name}", total=len(tasks))

        def done(rec):
            nonlocal executed
            executed += 1
            path = out / "runs" / f"{rec['run_id']}.json"
            if not path.exists():  # dask: the client records
                write_json(path, rec)
            if rec["status"] != "ok":
                log.warning("run %s failed: %s", rec["run_id"], rec["error"])
            else:
                log.info("run %s done in %.1f s", rec["run_id"], rec["seconds"] or 0)
            next(bar, None)

        try:
            if client is not None:
                _run_dask(tasks, client, done)
            else:
                _run_local(tasks, min(workers, len(tasks)), done)
        except KeyboardInterrupt:  # interrupted: the results of what is recorded so far
            _finish(study, out, wanted)
            raise
        finally:
            bar.close()
    table = _finish(study, out, wanted)
    return {"runs": len(study.runs), "done_before": done_before, "executed": executed,
            "failed": int((table["status"] != "ok").sum()) if len(table) else 0,
            "table": table}


def _finish(study, out: Path, wanted: set):
    from scanamp.study.results import write_results

    records = load_records(out)
    return write_results(study, {k: v for k, v in records.items() if k in wanted}, out)
