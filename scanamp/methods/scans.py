"""Multi-view range scans: a sheet-of-light head on a linear sweep at N free viewpoints
around and above the scene (no turntable), registered to each other with no pose given.

``scanamp capture scans SCENE --views N --out DIR`` writes ``scans/scan_NN.ply`` (range
grids in the scanner's own frame) and the true poses (``poses.json``, ``poses.conf``) for
evaluation only (options: :class:`acquire.scans.capture.ScansCaptureConfig`, ``--views 12
--elevation-max-deg 60 --head.standoff 0.4 --head.steps 100 --sensor.read-noise 4``, or
``--config scans.toml`` with ``[head]`` and ``[sensor]`` tables).
``scanamp reconstruct scans SCANS... --out DIR`` registers range scans from any scanner
(range-image PLY, point clouds and meshes, E57 files with many scans, folders, a
``.conf``) with features, seeded RANSAC, line-of-sight checks, a pose graph and multi-view
ICP, and merges them into one surface (:func:`reconstruct.scans.pipeline.run`, options
:class:`reconstruct.scans.pipeline.ScansReconConfig`); ``--poses`` is an optional initial
guess, never needed. The output is in the frame of the scans' model (the first
registered scan's gauge); a study fits that gauge to the true poses and scores the poses
and the merged mesh in the world.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from acquire.scans.capture import ScansCaptureConfig
from reconstruct.scans.pipeline import STAGES, ScansReconConfig
from scanamp.methods.protocol import Method, add_from_stage

__all__ = ["Scans", "METHOD", "SCANS_TAU"]

#: the F-score's distance for range scans (F at 0.5 mm)
SCANS_TAU = 5e-4


class Scans(Method):
    name = "scans"
    title = "range scans from free viewpoints (registered with no pose given)"
    capture_help = ("multi-view range scanning: a sheet-of-light head on a linear sweep at N "
                    "viewpoints around and above the scene; writes scans/scan_NN.ply (range "
                    "grids) and the true poses (poses.json, poses.conf) for evaluation")
    reconstruct_help = ("register range scans to each other with no initial pose (features, "
                        "seeded RANSAC, line-of-sight checks, pose graph, multi-view ICP) and "
                        "merge them into one mesh")
    capture_config = ScansCaptureConfig
    recon_config = ScansReconConfig
    frame = "model: the registered scans' common frame (a free gauge), not the world's"
    metrics = ("registered_fraction", "poses.rotation_error_deg.max",
               "poses.displacement_max_fraction_of_scene", "mesh.fscore")

    def capture(self, bundle, config, out_dir, *, rng, seed=0, scene_path=None) -> Path:
        from acquire.scans.capture import capture_scans
        from data_synth.scenes import scene_names

        path = bundle.name if scene_path is None else (
            str(scene_path) if str(scene_path) in scene_names()
            else str(Path(scene_path).resolve()))
        return capture_scans(bundle.render_scene, dataclasses.replace(config, seed=seed),
                             out_dir, rng, seed=seed,
                             scene_info={"path": path, "name": bundle.name,
                                         "seed": bundle.seed},
                             gt_mesh=bundle.gt_mesh())

    def inputs(self, capture_dir) -> list[Path]:
        return [Path(capture_dir) / "scans"]

    def reconstruct(self, config, inputs, out_dir, *, poses=None, from_stage=None):
        from reconstruct.scans.pipeline import run

        return run(config, inputs, out_dir, poses=poses, from_stage=from_stage)

    def _pose_errors(self, capture_dir: Path, result):
        """The estimated poses against the capture's true ones (gauge fitted robustly)."""
        from core.io.range import read_poses_json
        from reconstruct.evaluation.scan_poses import compare_scan_poses
        from reconstruct.scans.load import load_scans

        est = {Path(q.file).name: (q.model_from_scan if q.registered else None)
               for q in read_poses_json(Path(result.out_dir) / "poses.json")}
        true = {Path(q.file).name: q.model_from_scan
                for q in read_poses_json(Path(capture_dir) / "poses.json")}
        points = {s.name: s.points for s in load_scans(self.inputs(capture_dir))}
        return est, true, compare_scan_poses(est, true, points)

    def world_from_output(self, capture_config, capture_dir, result) -> np.ndarray:
        """The gauge fitted to the true poses (evaluation only)."""
        return self._pose_errors(Path(capture_dir), result)[2].gauge

    def evaluate(self, capture_dir, result, bundle) -> dict:
        """The poses' errors after the gauge fit, and the merged mesh, carried into the
        world by that gauge, against the ground truth at :data:`SCANS_TAU`."""
        from core.io.mesh import read_mesh
        from reconstruct.evaluation.evaluate import evaluate

        est, true, errors = self._pose_errors(Path(capture_dir), result)
        gt = bundle.gt_mesh()
        diag = float(np.linalg.norm(np.ptp(np.asarray(gt.vertices), axis=0)))
        mesh = read_mesh(Path(result.out_dir) / "mesh.ply").transform(errors.gauge)
        surface = evaluate(mesh, gt, tau=SCANS_TAU)
        return {"reconstruction": result.report,
                "registered_fraction": sum(v is not None for v in est.values()) / len(true),
                "poses": {**errors.to_dict(),
                          "displacement_max_fraction_of_scene":
                              float(errors.displacement_rms.max()) / diag},
                "mesh": surface.to_dict()}

    def add_reconstruct_arguments(self, p) -> None:
        p.add_argument("scans", nargs="+", metavar="SCANS",
                       help="scan files (.ply range images, clouds, meshes, .obj, .pcd), "
                            "folders of them, .e57 files, or a scanalyze .conf")
        p.add_argument("--poses", default=None, metavar="FILE",
                       help="initial guess of the poses (.conf, .aln or poses.json); never "
                            "needed")
        add_from_stage(p, STAGES)

    def reconstruct_from_args(self, config, args):
        return self.reconstruct(config, args.scans, args.out, poses=args.poses,
                                from_stage=args.from_stage)

    def describe(self, result) -> list[str]:
        rep = result.report
        c = rep["counts"]
        lines = [f"{c['registered']} of {c['scans']} scans registered ({c['pairs_verified']} "
                 f"of {c['pairs_tried']} pairs verified, {c['edges_pruned']} pruned) -> "
                 f"{c['mesh_triangles']} triangles in {result.out_dir}"]
        for s in rep["scans"]:
            if s["registered"]:
                lines.append(f"  {s['file']:<32s} rms {1000 * (s['rms'] or 0):.3f} mm, "
                             f"overlap {100 * s['overlap']:.0f} %")
            else:
                lines.append(f"  {s['file']:<32s} NOT REGISTERED: {s['reason']}")
        return lines


METHOD = Scans()
