"""SfM on a synthetic 24-view orbit at 640x480 ('object' scene, two rings of 12).

Targets: all views registered; rotation error <= 0.1 deg; ATE <= 0.1 % of the scene
size (bounding-box diagonal); mean reprojection <= 0.5 px; dense mesh F-score at
tau = 1 % of the scene size >= 0.85. Overhead: our sparse stage <= 1.15x the bare
pycolmap calls on the same images (same run); dense stage <= 2x the sparse stage.
Incremental against global mapping on the same capture.
"""

import os
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")
import cv2  # noqa: E402,F401  (before pycolmap)
import numpy as np  # noqa: E402
from _timing import report  # noqa: E402


def _capture(root: Path) -> Path:
    from acquire.capture_sfm import PathConfig, capture
    from data_synth.scenes import build_scene

    out = root / "orbit24"
    bundle = build_scene("object")
    cfg = PathConfig(kind="orbit", views=24, width=640, height=480)
    return capture(bundle.render_scene, cfg, out, rng=np.random.default_rng(0),
                   scene_ref={"name": "object", "seed": bundle.seed, "path": None},
                   gt_mesh=bundle.gt_mesh(), seed=0)


def _bare(cap: Path, work: Path, mapper: str) -> float:
    from acquire.camera import Camera
    from acquire.capture_io import load_capture
    from reconstruct.colmap_runner import ColmapOptions, colmap_params_from_camera, run_colmap

    c = load_capture(cap)
    nom = c.cameras["cam0"]
    model, params = colmap_params_from_camera(
        Camera(nom["width"], nom["height"], nom["fx"], nom["fy"], nom["cx"], nom["cy"]))
    names = [f["image"] for f in c.frames]
    work.mkdir(parents=True, exist_ok=True)
    t = time.perf_counter()
    run_colmap(cap, names, work, options=ColmapOptions(camera_model=model, camera_params=params,
                                                       mapper=mapper))
    return time.perf_counter() - t


def _ours(cap: Path, out: Path, mapper: str, dense: bool):
    from reconstruct.sfm import SfmConfig, run

    res = run(SfmConfig(mapper=mapper, dense=dense), cap, out)
    return res.report


def main():
    root = Path(os.environ.get("SFM_BENCH_DIR") or tempfile.mkdtemp(prefix="bench_sfm_"))
    cap = root / "orbit24"
    if not (cap / "capture.json").is_file():
        t = time.perf_counter()
        _capture(root)
        print(f"   rendered 24 views at 640x480 in {time.perf_counter() - t:.1f} s", flush=True)
    for mapper in ("incremental", "global"):
        bare = _bare(cap, root / f"bare_{mapper}", mapper)
        rep = _ours(cap, root / f"rec_{mapper}", mapper, dense=(mapper == "incremental"))
        if not rep["ok"]:
            print(f"   {mapper}: FAILED: {rep['message']}")
            continue
        poses = rep["metrics"]["poses"]
        sparse = rep["timings"]["sparse_total"]
        print(f"   [{mapper}] registered {rep['registered']}/{rep['num_images']}, "
              f"{rep['sparse']['num_points']} points, sparse {sparse:.1f} s, "
              f"bare pycolmap {bare:.1f} s", flush=True)
        report(f"{mapper}: registered fraction", rep["registered_fraction"], 1.0, 1.0)
        report(f"{mapper}: mean rotation error", poses["rotation_error_deg"]["mean"], 1.0, 0.1,
               higher_is_better=False, unit=" deg")
        report(f"{mapper}: ATE / scene size", 100 * poses["ate_fraction_of_scene"], 1.0, 0.1,
               higher_is_better=False, unit=" %")
        report(f"{mapper}: mean reprojection", rep["sparse"]["mean_reprojection_error_px"], 1.0,
               0.5, higher_is_better=False, unit=" px")
        report(f"{mapper}: sparse stage vs bare pycolmap", sparse, bare, 1.15,
               higher_is_better=False)
        if "mesh" in rep.get("metrics", {}):
            report(f"{mapper}: dense mesh F-score (tau = 1% scene)",
                   rep["metrics"]["mesh"]["fscore"], 1.0, 0.85)
            report(f"{mapper}: dense stage vs sparse stage", rep["timings"]["dense"], sparse, 2.0,
                   higher_is_better=False)
    print(f"   (outputs in {root})")


if __name__ == "__main__":
    sys.exit(main())
