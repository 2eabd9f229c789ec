"""``scanamp evaluate RECON --reference GT.ply``: score a reconstruction against ground truth.

``scanamp evaluate RECON --poses-reference FILE``: the scan poses of a ``reconstruct scans``
folder (or its ``poses.json``, or a ``.conf``) against reference poses (``.conf`` or
``poses.json``): per-scan rotation error and RMS displacement of the scan's own points,
after a robust fit of the free gauge (:mod:`reconstruct.evaluation.scan_poses`); or the
cameras of a ``reconstruct sfm`` folder (or any cameras file) against reference cameras
(a folder of Strecha ``.camera`` files, a COLMAP model, ...): per-view rotation, centre
and focal-length errors after a robust Sim(3) fit
(:mod:`reconstruct.evaluation.camera_poses`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from reconstruct.evaluation.evaluate import EvaluateConfig

NAME = "evaluate"
OUTPUT = "file"
OUTPUT_DEST = "json"
CONFIG = EvaluateConfig
HELP = ("score a reconstruction (mesh or point cloud) against a ground-truth surface: "
        "precision/recall/F-score at tau, accuracy, completeness, Chamfer, Hausdorff; or a "
        "'reconstruct lidar' folder against a forest scene's truth: tree detection, heights, "
        "DTM; or scan poses / SfM cameras against reference ones (--poses-reference)")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("recon", type=Path, metavar="RECON",
                        help="reconstructed mesh or point cloud (.ply .obj .stl .off .glb "
                             ".pcd .xyz ...); a file without faces is a point cloud; or a "
                             "'reconstruct lidar' folder (trees.csv, dtm.tif)")
    parser.add_argument("--reference", type=Path, default=None, metavar="GT",
                        help="ground-truth mesh (or point cloud); for a LiDAR result, the forest "
                             "scene folder (its trees.csv and dtm.tif); required unless "
                             "--poses-reference is given")
    parser.add_argument("--poses-reference", type=Path, default=None, metavar="FILE",
                        help="reference scan poses (.conf or poses.json): compare the poses "
                             "of RECON (a 'reconstruct scans' folder, its poses.json or a "
                             ".conf) per scan after fitting the gauge robustly; or "
                             "reference cameras (a folder of Strecha .camera files, a COLMAP "
                             "model, transforms.json, *_par.txt, .mvs, .sfm): compare the "
                             "cameras of RECON (a 'reconstruct sfm' folder or a cameras "
                             "file) per view after a robust Sim(3) fit")
    parser.add_argument("--json", type=Path, default=None, metavar="OUT",
                        help="also write the figures to this JSON file")
    parser.add_argument("--icp", action="store_true", help="the same as --align icp")


def run(args: argparse.Namespace, config: EvaluateConfig) -> int:
    import numpy as np

    from core.files import write_json
    from core.io.mesh import read_geometry
    from core.validate import InputError
    from reconstruct.evaluation.evaluate import evaluate
    from reconstruct.registration.rigid import LOW_FITNESS

    if args.poses_reference is not None:
        ref = Path(args.poses_reference)
        scans = ref.suffix.lower() in (".conf", ".json") and ref.name != "transforms.json" \
            or (ref / "poses.json").is_file()
        return _run_poses(args) if scans else _run_cameras(args)
    if args.reference is None:
        raise InputError("expected --reference GT (or --poses-reference FILE)",
                         field="--reference")
    if args.recon.is_dir() and (args.recon / "trees.csv").is_file():
        return _run_lidar(args)
    recon = read_geometry(args.recon)
    reference = read_geometry(args.reference)
    align = config.align
    if args.icp:
        if align not in ("none", "icp"):
            raise InputError(f"--icp contradicts --align {align}", field="--align")
        align = "icp"
    try:
        result = evaluate(recon, reference, tau=config.tau, density=config.density,
                          align=align, distance=config.distance,
                          rng=np.random.default_rng(config.seed),
                          max_samples=config.max_samples)
    except ValueError as exc:  # name the file the library's message is about
        msg = str(exc)
        for prefix, path in (("recon", args.recon), ("reference", args.reference)):
            if msg.startswith(prefix):
                raise InputError(msg, path=path) from None
        raise
    sys.stdout.write(f"{args.recon} vs {args.reference}\n{result.table()}\n")
    if result.icp_fitness is not None and result.icp_fitness < LOW_FITNESS:
        sys.stderr.write(f"warning: only {100 * result.icp_fitness:.0f}% of {args.recon} lies "
                         f"near the reference after --align {align}: these scores mean little "
                         + ("(try --align global)" if align == "icp" else
                            "(is it the same object, at the same scale?)") + "\n")
    if args.json is not None:
        write_json(args.json, {"recon": str(args.recon), "reference": str(args.reference),
                               **result.to_dict()})
    return 0


def _read_poses(path: Path) -> tuple[dict, Path]:
    """``{file name: model_from_scan or None}`` and the folder its files are relative to."""
    from core.io.range import read_conf, read_poses_json
    from core.validate import InputError

    if path.is_dir():
        path = path / "poses.json"
    if not path.is_file():
        raise InputError("no such file", path=path)
    if path.suffix.lower() == ".conf":
        return {Path(f).name: T for f, T in read_conf(path)}, path.parent
    if path.suffix.lower() == ".json":
        return {Path(p.file).name: (p.model_from_scan if p.registered else None)
                for p in read_poses_json(path)}, path.parent
    raise InputError("expected a .conf or poses.json", path=path, field="--poses-reference")


def _scan_points(name: str, folders: list[Path]):
    """The points of scan ``name``, found beside either poses file (or in scans/)."""
    from reconstruct.scans import load_scans

    for d in folders:
        for f in (d / name, d / "scans" / name):
            if f.is_file():
                return load_scans([f], min_scans=1)[0].points
    return None


def _run_poses(args: argparse.Namespace) -> int:
    from core.files import write_json
    from core.validate import InputError
    from reconstruct.evaluation.scan_poses import compare_scan_poses

    est, est_dir = _read_poses(Path(args.recon))
    ref, ref_dir = _read_poses(Path(args.poses_reference))
    points = {}
    for n in ref:
        if n in est:
            p = _scan_points(n, [ref_dir, est_dir])
            if p is not None:
                points[n] = p
    if not any(est.get(n) is not None for n in points):
        raise InputError(f"no scan of {args.recon} is both placed and found beside the "
                         "reference", path=args.poses_reference, field="scans")
    errors = compare_scan_poses(est, ref, points)
    sys.stdout.write(f"{args.recon} vs {args.poses_reference}\n{errors.table()}\n")
    if args.json is not None:
        write_json(args.json, {"recon": str(args.recon),
                               "poses_reference": str(args.poses_reference),
                               **errors.to_dict()})
    return 0


def _run_cameras(args: argparse.Namespace) -> int:
    from core.files import write_json
    from core.validate import InputError
    from reconstruct.camera_files import read_cameras
    from reconstruct.evaluation.camera_poses import compare_cameras, read_estimated_cameras

    est, source = read_estimated_cameras(args.recon)
    sizes = {n: (c.width, c.height) for n, c in est.items()}
    ref = read_cameras(args.poses_reference, sizes=sizes)
    try:
        errors = compare_cameras(est, ref)
    except ValueError as exc:
        raise InputError(str(exc), path=args.recon) from None
    head = f"{args.recon} vs {args.poses_reference}"
    sys.stdout.write(head + (f" (intrinsics: {source})" if source else "") + "\n"
                     + errors.table() + "\n")
    if args.json is not None:
        write_json(args.json, {"recon": str(args.recon), "poses_reference":
                               str(args.poses_reference), "intrinsics_source": source,
                               **errors.to_dict()})
    return 0


def _run_lidar(args: argparse.Namespace) -> int:
    """A LiDAR result against a forest scene: lidaRtRee's tree matching and the DTM."""
    from core.files import write_json
    from reconstruct.lidar.evaluation import evaluate_lidar, lidar_table

    scores = evaluate_lidar(args.recon, args.reference)
    sys.stdout.write(f"{args.recon} vs {args.reference}\n{lidar_table(scores)}\n")
    if args.json is not None:
        write_json(args.json, {"recon": str(args.recon), "reference": str(args.reference),
                               **scores})
    return 0
