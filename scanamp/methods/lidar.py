"""Time-of-flight LiDAR: airborne strips, a vehicle's path or terrestrial stations
surveying a scene (a forest, a city block), and the survey's reconstruction.

``scanamp capture lidar SCENE --preset NAME --out DIR`` writes ``DIR/points.laz`` (LAS 1.4:
the survey's points, the truth as extra bytes), ``DIR/report.json`` (the plan, the scanner,
counts, the density achieved), for terrestrial stations ``DIR/scans.e57`` (one scan per
station with its pose and grid), and with ``per_strip`` ``DIR/strips/*.laz`` (options:
:class:`acquire.lidar.capture.LidarCaptureConfig`; ``--density 10`` plans the flight).
Legs (strips, stations) run one after another in this process, or in parallel in local
worker processes (``--workers 2``) or on a Dask scheduler (``--scheduler
tcp://host:8786``); each worker rebuilds the scene from its name or folder, so the legs'
files are the same bytes wherever they ran (each leg has its own noise seed).

``scanamp reconstruct lidar POINTS.laz --out DIR`` classifies the ground (cloth simulation
filter), writes the DTM and CHM GeoTIFFs and finds the trees
(:func:`reconstruct.lidar.pipeline.run`, options
:class:`reconstruct.lidar.pipeline.LidarReconConfig`), for a simulated or a real survey.
The output is in the scene's projected coordinates (local + ``[scene].origin``); a study
scores the trees and the DTM against a forest scene's truth.
"""

from __future__ import annotations

import concurrent.futures as cf
import logging
import multiprocessing
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from acquire.lidar.capture import (
    LAS_EXTRA,
    LidarCaptureConfig,
    e57_scan,
    make_scanner,
    merge_las,
    nominal_range,
    plan_survey,
    scan_leg_to_las,
    strip_name,
    summary_report,
)
from acquire.lidar.presets import get_preset
from acquire.lidar.simulate import LidarWorld
from core.config import to_dict
from core.files import atomic_dir, write_json
from core.io.las import LasWriter
from core.progress import track
from core.validate import InputError
from reconstruct.lidar.pipeline import LidarReconConfig
from scanamp.methods.protocol import Method, scene_for_capture

log = logging.getLogger(__name__)

__all__ = ["Lidar", "METHOD", "run_lidar_capture", "scene_origin", "scene_crs"]


def scene_origin(bundle) -> np.ndarray:
    """The scene's origin in projected coordinates (``[scene].origin``, else the bundle's
    ``origin``; 0 without one): files carry ``local + origin``."""
    o = bundle.spec.get("scene", {}).get("origin")
    if o is None:
        o = getattr(bundle, "origin", None)
    if o is None:
        return np.zeros(3)
    o = np.asarray(o, np.float64).ravel()
    if o.shape == (2,):
        o = np.append(o, 0.0)
    if o.shape != (3,) or not np.all(np.isfinite(o)):
        raise InputError(f"expected 2 or 3 finite numbers, got {o.tolist()}",
                         field="scene.origin")
    return o


def scene_crs(bundle) -> str | None:
    """The scene's coordinate system as WKT, if it names one (``[scene].crs_wkt``)."""
    head = bundle.spec.get("scene", {})
    wkt = getattr(bundle, "crs_wkt", None) or head.get("crs_wkt")
    return str(wkt) if wkt else None


class _Survey:
    """A scene, its world and the planned survey: rebuilt identically in every worker."""

    def __init__(self, scene: str, config: LidarCaptureConfig, bundle=None):
        self.preset = get_preset(config.preset)
        self.bundle = bundle if bundle is not None else scene_for_capture(scene)
        self.world = LidarWorld(self.bundle.render_scene, self.preset.wavelength_nm)
        self.bounds = self.bundle.bounds()
        self.plan = plan_survey(self.world, self.bounds, config, self.preset)
        self.scanner = make_scanner(config, self.preset, self.plan)
        self.origin = scene_origin(self.bundle)
        self.crs = scene_crs(self.bundle)
        self.intensity_range = config.intensity_range or nominal_range(self.plan) / 2
        self.config = config

    def scan(self, index: int, writer: LasWriter) -> dict:
        c = self.config
        return scan_leg_to_las(self.world, self.scanner, self.plan.legs[index], index, writer,
                               origin=self.origin, seed=c.seed, block=c.block,
                               intensity_range=self.intensity_range,
                               area=self.bounds[:, :2])

    def writer(self, path: Path) -> LasWriter:
        return LasWriter(path, origin=self.origin, extra=LAS_EXTRA, crs_wkt=self.crs)


_WORKER_SURVEY: dict = {}


def _leg_task(task: dict) -> dict:
    """Scan one leg in a worker into ``task['path']`` (or return its bytes when the worker
    may not share the folder: Dask)."""
    from core.config import from_dict

    key = (task["scene"], repr(sorted(task["config"].items())))
    if key not in _WORKER_SURVEY:          # one scene build per worker process
        _WORKER_SURVEY.clear()
        _WORKER_SURVEY[key] = _Survey(task["scene"],
                                      from_dict(LidarCaptureConfig, task["config"]))
    sv = _WORKER_SURVEY[key]
    if task.get("path"):
        with sv.writer(Path(task["path"])) as w:
            s = sv.scan(task["index"], w)
        return {"summary": s}
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "leg.laz"
        with sv.writer(p) as w:
            s = sv.scan(task["index"], w)
        return {"summary": s, "bytes": p.read_bytes()}


def _init_worker() -> None:
    os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")


def _run_parallel(tasks: list, workers: int, client) -> list:
    if client is not None:
        futs = [client.submit(_leg_task, {**t, "path": None}, pure=False) for t in tasks]
        out = []
        for t, f in zip(tasks, futs, strict=True):
            r = f.result()
            Path(t["path"]).write_bytes(r.pop("bytes"))
            out.append(r)
        return out
    ctx = multiprocessing.get_context("spawn")
    with cf.ProcessPoolExecutor(max_workers=workers, mp_context=ctx,
                                initializer=_init_worker) as ex:
        return list(track(ex.map(_leg_task, tasks), "lidar legs", total=len(tasks)))


def run_lidar_capture(scene: str, config: LidarCaptureConfig, out_dir: str | os.PathLike, *,
                      client=None, bundle=None) -> dict:
    """Survey ``scene`` (a built-in name or scene folder) into ``out_dir``; the report.

    ``client``: a ``distributed.Client`` to run the legs on (else ``config.scheduler``
    when given, else ``config.workers`` local processes, else this process). ``bundle``:
    the scene already built from ``scene`` (workers still rebuild it from ``scene``).
    """
    t0 = time.perf_counter()
    get_preset(config.preset)                     # an unknown preset: before any work
    if client is None and config.scheduler:
        from scanamp.cluster import connect

        client = connect(config.scheduler)
    sv = _Survey(sv_scene(scene), config, bundle)
    legs = sv.plan.legs
    stations = sv.plan.platform == "tripod"
    split = config.per_strip or stations or config.workers > 1 or client is not None
    out_dir = Path(out_dir)
    with atomic_dir(out_dir) as tmp:
        if not split:
            with sv.writer(tmp / "points.laz") as w:
                summaries = [sv.scan(i, w) for i in track(range(len(legs)), "lidar legs")]
        else:
            (tmp / "strips").mkdir()
            paths = [tmp / "strips" / strip_name(leg.source_id, i) for i, leg in enumerate(legs)]
            tasks = [{"scene": sv_scene(scene), "config": to_dict(config), "index": i,
                      "path": str(p)} for i, p in enumerate(paths)]
            if client is None and config.workers <= 1:
                summaries = []
                for i, p in track(list(enumerate(paths)), "lidar legs"):
                    with sv.writer(p) as w:
                        summaries.append(sv.scan(i, w))
            else:
                summaries = [r["summary"] for r in _run_parallel(tasks, config.workers, client)]
            merge_las(paths, tmp / "points.laz", origin=sv.origin, crs_wkt=sv.crs)
            if stations:
                from core.io.e57 import write_e57

                scans = [e57_scan(p, leg, sv.origin) for p, leg in zip(paths, legs, strict=True)
                         if _has_points(p)]
                if scans:
                    write_e57(tmp / "scans.e57", scans)
                else:
                    log.warning("no station returned a point: no scans.e57")
            if not config.per_strip:
                for p in paths:
                    p.unlink()
                (tmp / "strips").rmdir()
        report = _report(sv, summaries, time.perf_counter() - t0)
        write_json(tmp / "report.json", report)
    log.info("wrote %s: %d points from %d pulses over %d legs", out_dir, report["points"],
             report["pulses"], len(legs))
    return report


def _has_points(path: Path) -> bool:
    from core.io.las import iter_las_chunks

    try:
        next(iter_las_chunks(path, 1, fields=("x",)))
    except InputError:
        return False
    return True


def sv_scene(scene: str) -> str:
    """The scene as workers rebuild it: a built-in name, or the folder's absolute path."""
    return str(Path(scene).resolve()) if os.path.exists(scene) else scene


def _report(sv: _Survey, summaries: list, seconds: float) -> dict:
    rx = sv.scanner.receiver
    return {"format": "scanamp.lidar-capture/1", "preset": sv.preset.name,
            "model": sv.preset.model, "wavelength_nm": sv.scanner.wavelength_nm,
            "scanner": {"pattern": sv.scanner.pattern.kind,
                        "pulse_rate_hz": sv.scanner.pulse_rate,
                        "scan_rate_hz": sv.scanner.pattern.rate_hz,
                        "divergence_mrad": sv.scanner.divergence_rad * 1e3,
                        "footprint_samples": sv.scanner.footprint_samples,
                        "pulse_width_ns": rx.pulse_width_ns, "bin_ns": rx.bin_ns,
                        "max_returns": rx.max_returns,
                        "min_separation_m": rx.min_separation_m,
                        "detection": rx.detection,
                        "range_noise_law": "sigma_R = sigma_pulse / sqrt(SNR)",
                        "sigma_pulse_m": rx.sigma_m, "noise_energy": rx.noise_energy,
                        "threshold_energy": rx.threshold},
            "plan": sv.plan.to_dict(), "origin": sv.origin.tolist(), "crs_wkt": sv.crs,
            "intensity_reference_range_m": sv.intensity_range,
            **summary_report(summaries, sv.plan, sv.bounds[:, :2]),
            "seconds": seconds}


class Lidar(Method):
    name = "lidar"
    title = "time-of-flight LiDAR (airborne, vehicle, terrestrial)"
    capture_help = ("simulate a time-of-flight LiDAR survey (airborne, vehicle, terrestrial) of "
                    "a scene into LAS/LAZ (and E57 for stations), with per-point truth")
    reconstruct_help = ("ground (cloth simulation filter), DTM and CHM GeoTIFFs, and individual "
                        "trees of an airborne LiDAR survey (LAS/LAZ, simulated or real)")
    capture_config = LidarCaptureConfig
    recon_config = LidarReconConfig
    frame = "projected: the scene's local coordinates + [scene].origin (the LAS files' CRS)"
    metrics = ("evaluation.trees.f", "evaluation.dtm.rmse", "evaluation.trees.height_rmse")
    takes_materials = False

    def check_scene(self, bundle) -> None:
        if not getattr(bundle, "trees", None):
            raise InputError("a LiDAR study needs a forest scene (its truth: trees and "
                             "terrain)", field="study.scene")

    def capture(self, bundle, config, out_dir, *, rng, seed=0, scene_path=None) -> Path:
        """The survey's legs draw their noise from ``seed`` (one stream per leg), so
        ``rng`` is not used; the workers rebuild the scene from ``scene_path`` (else the
        bundle's name)."""
        import dataclasses

        scene = str(scene_path) if scene_path is not None else bundle.name
        run_lidar_capture(scene, dataclasses.replace(config, seed=seed), out_dir,
                          bundle=bundle)
        return Path(out_dir)

    def inputs(self, capture_dir) -> Path:
        return Path(capture_dir) / "points.laz"

    def reconstruct(self, config, inputs, out_dir):
        from reconstruct.lidar.pipeline import run

        return run(config, inputs, out_dir)

    def evaluate(self, capture_dir, result, bundle) -> dict:
        """The survey's report, the reconstruction's, and the trees and DTM scored against
        the forest's truth (written beside the capture, as ``scanamp scene`` writes it)."""
        from core.files import read_json
        from data_synth.scenes import write_scene
        from reconstruct.lidar.evaluation import evaluate_lidar

        truth = write_scene(bundle, Path(capture_dir).parent / "truth")
        return {"capture": read_json(Path(capture_dir) / "report.json"),
                "reconstruction": result.report,
                "evaluation": evaluate_lidar(result.out_dir, truth)}

    def add_reconstruct_arguments(self, p) -> None:
        p.add_argument("points", type=Path, metavar="POINTS.laz",
                       help="the survey (.las or .laz); its coordinates and CRS are kept")

    def reconstruct_from_args(self, config, args):
        return self.reconstruct(config, args.points, args.out)

    def describe(self, result) -> list[str]:
        rep = result.report
        g = rep["ground"]
        source = "classified here" if g["reclassified"] else "the file's class"
        return [f"{rep['points']} points, {100 * g['share']:.1f}% ground ({source}); "
                f"{rep['trees']['count']} trees -> {result.out_dir}"]


METHOD = Lidar()
