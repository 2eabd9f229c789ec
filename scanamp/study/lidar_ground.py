"""The ``lidar-ground`` study kind: the ground filter and the trees on a mountainside.

One run grows a forest scene (the study's ``scene``, its ``[forest]`` table overridden by
the run's ``forest.*`` keys, its seed the run's), flies it (``scanamp capture lidar``:
the other keys are the capture's), reconstructs it with ``--reclassify`` (the
simulation's classes are the truth, not the input) and scores it:

- **ground** (Sithole and Vosselman 2004, "Experimental comparison of filter algorithms
  for bare-Earth extraction from airborne laser scanning point clouds", ISPRS J. 59,
  85-101): type I = true ground called non-ground / true ground, type II = the rest
  called ground / the rest, total = all misclassified / all points. True ground is what
  the simulator labels ground or road (ASPRS 2, 11);
- **DTM** RMSE, bias and P95 of ``dtm.tif`` against the true terrain (the ground mesh,
  exactly: :func:`data_synth.forest.terrain_height`) at the DTM's cells over the stand,
  its margin left out;
- **trees**: :func:`reconstruct.lidar.evaluation.evaluate_lidar`'s scores.

The capture config of a run is :class:`GroundSurvey`: the ``[forest]`` table of the
run's TOML is kept apart (checked against :class:`data_synth.forest.ForestConfig`), the
rest is a :class:`acquire.lidar.capture.LidarCaptureConfig`.
"""

from __future__ import annotations

import copy
import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from core.validate import InputError

__all__ = ["GroundSurvey", "load_capture", "recon_default", "execute", "check_scene",
           "ground_errors",
           "stand_dtm_errors", "METRICS"]

TRUE_GROUND_CLASSES = (2, 11)  # ground, road surface
METRICS = ("ground.total", "ground.type_i", "ground.type_ii", "dtm.rmse",
           "trees.f", "terrain.mean_slope_deg")


@dataclass
class GroundSurvey:
    """A run's capture config and its forest overrides."""

    capture: object  # LidarCaptureConfig
    forest: dict = field(default_factory=dict)


def load_capture(path: Path) -> GroundSurvey:
    """The run's TOML: ``[forest]`` (ForestConfig fields) apart, the rest the capture's."""
    from acquire.lidar.capture import LidarCaptureConfig
    from core.config import from_dict
    from core.files import read_toml
    from data_synth.forest import ForestConfig

    table = read_toml(path)
    forest = table.pop("forest", {}) or {}
    if not isinstance(forest, dict):
        raise InputError("expected a table", path=path, field="forest")
    from_dict(ForestConfig, forest, path=path, prefix="forest.")  # checked now
    return GroundSurvey(from_dict(LidarCaptureConfig, table, path=path), dict(forest))


def recon_default():
    from reconstruct.lidar.pipeline import LidarReconConfig

    return LidarReconConfig()


def ground_errors(ground: np.ndarray, truth: np.ndarray) -> dict:
    """Sithole and Vosselman's type I, type II and total errors (fractions).

    >>> ground_errors(np.array([1, 0, 0, 1], bool), np.array([1, 1, 0, 0], bool))
    {'type_i': 0.5, 'type_ii': 0.5, 'total': 0.5, 'points': 4, 'true_ground': 2}
    """
    g = np.asarray(ground, bool)
    t = np.asarray(truth, bool)
    if g.shape != t.shape:
        raise ValueError(f"truth: expected shape {g.shape}, got {t.shape}")
    nan = float("nan")
    n_t, n_o = int(t.sum()), int((~t).sum())
    return {"type_i": float((t & ~g).sum() / n_t) if n_t else nan,
            "type_ii": float((~t & g).sum() / n_o) if n_o else nan,
            "total": float((g != t).mean()) if len(g) else nan,
            "points": int(len(g)), "true_ground": n_t}


def stand_dtm_errors(dtm, truth, *, margin: float) -> dict:
    """:func:`reconstruct.lidar.evaluation.dtm_errors`-like figures of ``dtm`` (Raster)
    against the triangulated true terrain ``truth`` (Raster), at the cells of ``dtm``
    lying ``margin`` or more inside the truth's extent."""
    from data_synth.forest import terrain_height

    r, c = truth.values.shape
    lo = np.array([truth.x0, truth.y0]) + margin
    hi = np.array([truth.x0 + (c - 1) * truth.res, truth.y0 + (r - 1) * truth.res]) - margin
    xs, ys = dtm.centres()
    X, Y = np.meshgrid(xs, ys)
    inside = (X >= lo[0]) & (X <= hi[0]) & (Y >= lo[1]) & (Y <= hi[1])
    if not np.any(inside):
        raise ValueError("dtm: no cell over the stand")
    e = dtm.values[inside] - terrain_height(truth, X[inside], Y[inside])
    e = e[np.isfinite(e)]
    return {"rmse": float(np.sqrt(np.mean(e ** 2))), "bias": float(np.mean(e)),
            "p95_abs": float(np.percentile(np.abs(e), 95)),
            "max_abs": float(np.max(np.abs(e))), "n": int(len(e))}


def check_scene(scene: str) -> dict:
    """The spec of ``scene``, checked to be a forest (a ``[forest]`` table
    :class:`data_synth.forest.ForestConfig` reads) without growing it."""
    from core.config import from_dict
    from core.files import read_toml
    from data_synth.forest import ForestConfig
    from data_synth.scenes import scene_spec_path

    path = scene_spec_path(scene)
    spec = read_toml(path)
    table = dict(spec.get("forest") or {})
    if not table:
        raise InputError("a lidar-ground study needs a forest scene (a [forest] table)",
                         path=path, field="study.scene")
    table.pop("inventory", None)
    from_dict(ForestConfig, table, path=path, prefix="forest.")
    return spec


def execute(cap: GroundSurvey, rec_cfg, *, scene: str, seed: int, work: Path,
            material: dict | None = None) -> dict:
    """Grow, fly, reconstruct and score one stand (see the module docstring)."""
    from core.io.las import read_las
    from core.io.raster import read_raster
    from data_synth.scenes import build_scene, write_scene
    from procgen.terrain import mean_slope
    from reconstruct.lidar.evaluation import evaluate_lidar
    from reconstruct.lidar.pipeline import run as run_lidar
    from scanamp.methods.lidar import run_lidar_capture

    if material:
        raise InputError("a LiDAR study takes no material overrides", field="material")
    spec = copy.deepcopy(check_scene(scene))
    spec["forest"].update(cap.forest)
    spec.setdefault("scene", {})["seed"] = int(seed)
    bundle = build_scene(spec)
    scene_dir = write_scene(bundle, work / "scene")
    capture = run_lidar_capture(str(scene_dir), dataclasses.replace(cap.capture, seed=seed),
                                work / "capture", bundle=bundle)
    rec_cfg = dataclasses.replace(rec_cfg, reclassify=True)
    recon = Path(run_lidar(rec_cfg, work / "capture" / "points.laz", work / "reconstruction"))
    truth_pts, _ = read_las(work / "capture" / "points.laz")
    ours, _ = read_las(recon / "classified.laz")
    truth = np.isin(truth_pts["classification"], TRUE_GROUND_CLASSES)
    ground = ours["classification"] == 2
    margin = float(spec["forest"].get("margin", 10.0))
    true_dtm = read_raster(scene_dir / "dtm.tif")
    report = json.loads((recon / "report.json").read_text())
    r, c = true_dtm.values.shape
    k = int(round(margin / true_dtm.res))
    stand = np.zeros((r - 1, c - 1), bool)
    stand[k:r - 1 - k, k:c - 1 - k] = True
    scores = evaluate_lidar(recon, scene_dir)
    return {"capture": capture, "reconstruction": report,
            "terrain": {"mean_slope_deg": mean_slope(true_dtm.values, true_dtm.res,
                                                     where=stand if stand.any() else None)},
            "ground": ground_errors(ground, truth),
            "dtm": stand_dtm_errors(read_raster(recon / "dtm.tif"), true_dtm, margin=margin),
            "trees": scores["trees"]}
