"""Structure from motion: a camera moved around a scene (orbit rings, hemisphere or a
hand-held walk), or a user's folder of photos.

``scanamp capture sfm SCENE --out DIR`` renders the views and writes capture.json and a
nerfstudio transforms.json (options: :class:`acquire.sfm.capture.SfmCaptureConfig`,
``--kind walk --views 40``). ``scanamp reconstruct sfm CAPTURE_OR_PHOTOS --out DIR`` runs
pycolmap on the CPU (or known cameras, ``--cameras``), then PatchMatch multi-view stereo,
fusion and a trimmed Poisson surface (:func:`reconstruct.sfm.pipeline.run`, options
:class:`reconstruct.sfm.pipeline.SfmConfig`), in named stages: run again into the same
folder with ``--overwrite``, only the stages whose options or inputs changed are
recomputed; ``--from STAGE`` forces that stage and the later ones. With ground truth the
model is aligned to the scene, so the mesh is in the world frame.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from acquire.sfm.capture import SfmCaptureConfig
from reconstruct.sfm.pipeline import STAGES, SfmConfig
from scanamp.methods.protocol import Method, add_from_stage

__all__ = ["Sfm", "METHOD"]


class Sfm(Method):
    name = "sfm"
    title = "structure from motion (pycolmap + dense surface)"
    capture_help = ("render a structure-from-motion capture: orbit rings, hemisphere or "
                    "hand-held walk; writes capture.json and a nerfstudio transforms.json")
    reconstruct_help = ("structure from motion on a capture or a folder of photos (pycolmap, "
                        "CPU; or known cameras) with PatchMatch multi-view stereo; writes the "
                        "COLMAP model, points.ply, dense/ depth maps, fused.ply, mesh.ply and "
                        "report.json")
    capture_config = SfmCaptureConfig
    recon_config = SfmConfig
    frame = ("world: the scene's frame when the capture has ground truth (the model is "
             "aligned to it), else the model's, made upright")
    metrics = ("registered_fraction", "metrics.poses.rotation_error_deg.mean",
               "metrics.poses.ate_fraction_of_scene", "metrics.mesh.fscore")

    def seeded(self, recon_config, seed: int):
        """pycolmap's seed follows the run's."""
        return dataclasses.replace(recon_config, seed=seed)

    def capture(self, bundle, config, out_dir, *, rng, seed=0, scene_path=None) -> Path:
        from acquire.sfm.capture import capture
        from data_synth.scenes import scene_names

        path = None if scene_path is None or str(scene_path) in scene_names() \
            else str(Path(scene_path).resolve())
        ref = {"name": bundle.name, "seed": bundle.seed, "path": path}
        return capture(bundle.render_scene, config, out_dir, rng=rng, scene_ref=ref,
                       gt_mesh=bundle.gt_mesh(), seed=seed)

    def reconstruct(self, config, inputs, out_dir, *, from_stage=None):
        from reconstruct.sfm.pipeline import run

        return run(config, inputs, out_dir, from_stage=from_stage)

    def add_reconstruct_arguments(self, p) -> None:
        p.add_argument("input", type=Path,
                       help="SfM capture folder (capture.json) or a folder of photos (JPEG, "
                            "PNG, TIFF; EXIF orientation applied)")
        add_from_stage(p, STAGES)

    def reconstruct_from_args(self, config, args):
        return self.reconstruct(config, args.input, args.out, from_stage=args.from_stage)

    def describe(self, result) -> list[str]:
        rep = result.report
        line = (f"registered {rep['registered']}/{rep['num_images']} images, "
                f"{rep['sparse']['num_points']} points, reprojection "
                f"{rep['sparse']['mean_reprojection_error_px']:.3f} px")
        poses = rep.get("metrics", {}).get("poses")
        if poses:
            line += (f"; rotation error {poses['rotation_error_deg']['mean']:.4f} deg, ATE "
                     f"{100 * poses.get('ate_fraction_of_scene', float('nan')):.4f}% of scene")
        dense = rep.get("dense")
        if dense and dense.get("views"):
            line += (f"; fused depth on {100 * dense['min_fused_coverage']:.0f}% or more of "
                     f"each view's pixels")
        mesh = rep.get("metrics", {}).get("mesh")
        if mesh:
            line += f"; mesh F-score {mesh['fscore']:.3f}"
        return [f"{line} -> {result.out_dir}"]


METHOD = Sfm()
