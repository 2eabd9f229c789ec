"""Stereo: two cameras (and, for active stereo, a random-dot projector) over a turntable.

``scanamp capture stereo SCENE --out DIR`` renders passive pairs, and active pairs when
the rig projects, with ChArUco calibration captures (options:
:class:`acquire.stereo.rig.StereoCaptureConfig`, ``--rig.baseline 0.12``, or ``--config
rig.toml``, docs/stereo.md; ``--textureless`` renders every object untextured).
``scanamp reconstruct stereo CAPTURE --out DIR`` calibrates, rectifies, matches (SGBM,
+LR check, +WLS), fuses depth (TSDF) and meshes (:func:`reconstruct.stereo.pipeline.run_capture`,
options :class:`reconstruct.stereo.options.StereoOptions`; ``mode="active"`` is active
stereo); ``scanamp reconstruct stereo --left L.png --right R.png --calibration stereo.yaml
--out DIR`` gives the disparity, depth and points of a user's own calibrated pair
(:func:`reconstruct.stereo.pair.run_pair`). The mesh is in the calibrated turntable frame.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from acquire.stereo.rig import StereoCaptureConfig
from reconstruct.stereo.options import StereoOptions
from scanamp.methods.protocol import (
    Method,
    object_name,
    scene_info,
    without_textures,
    world_from_table,
)

__all__ = ["Stereo", "METHOD"]


class Stereo(Method):
    name = "stereo"
    title = "stereo (passive, and active when the rig projects)"
    capture_help = ("render a stereo capture (passive pairs, and active pairs with a random-dot "
                    "projector) of a scene on a turntable, with board calibration views")
    reconstruct_help = ("stereo reconstruction: calibration, rectification, SGBM (+LR check, "
                        "+WLS), depth, TSDF fusion and meshing; or disparity/depth/points of "
                        "one calibrated pair")
    capture_config = StereoCaptureConfig
    recon_config = StereoOptions
    frame = "table: the calibrated turntable frame (the world's when the axis board is mounted)"
    metrics = ("results.active.evaluation.accuracy_mean", "results.active.evaluation.fscore",
               "results.active.disparity_mean.avgerr")

    def scene(self, bundle, config):
        return without_textures(bundle) if getattr(config, "textureless", False) else bundle

    def capture(self, bundle, config, out_dir, *, rng, seed=0, scene_path=None) -> Path:
        from acquire.stereo.capture import capture

        info = {**scene_info(bundle, scene_path),
                "textureless": bool(getattr(config, "textureless", False))}
        return capture(bundle.render_scene, config, out_dir, rng, scene_info=info, seed=seed,
                       object_name=object_name(bundle, config))

    def reconstruct(self, config, inputs, out_dir):
        from reconstruct.stereo.pipeline import run_capture

        return run_capture(inputs, out_dir, config)

    def world_from_output(self, capture_config, capture_dir, result) -> np.ndarray:
        return world_from_table(result.report, "table_from_left", capture_config)

    def add_reconstruct_arguments(self, p) -> None:
        p.add_argument("capture", nargs="?", type=Path, default=None,
                       help="stereo capture folder (omit with --left/--right/--calibration)")
        p.add_argument("--left", type=Path, help="left image of a pair")
        p.add_argument("--right", type=Path, help="right image of a pair")
        p.add_argument("--calibration", type=Path, metavar="stereo.yaml",
                       help="cv2.FileStorage YAML with K1 D1 K2 D2 R T image_size "
                            "(docs/stereo.md)")
        p.add_argument("--disparity-gt", type=Path, default=None, metavar="GT.npy|.pfm|.png",
                       help="ground-truth disparity (rectified left) to score the pair; "
                            "0 = unknown")
        p.add_argument("--disparity-gt-scale", type=float, default=None, metavar="S",
                       help="a PNG ground truth stores disparity x S (default: 256 for 16-bit "
                            "PNGs as KITTI, 1 for 8-bit as Middlebury 2001-2006 full size)")

    def reconstruct_from_args(self, config, args):
        from reconstruct.stereo.pair import run_pair

        pair = [args.left, args.right, args.calibration]
        if args.capture is None:
            if any(x is None for x in pair):
                raise ValueError("expected a CAPTURE folder, or all of --left, --right and "
                                 "--calibration")
            return run_pair(args.left, args.right, args.calibration, args.out, options=config,
                            disparity_gt=args.disparity_gt,
                            disparity_gt_scale=args.disparity_gt_scale)
        if any(x is not None for x in pair):
            raise ValueError("--left/--right/--calibration: not with a CAPTURE folder")
        return self.reconstruct(config, args.capture, args.out)


METHOD = Stereo()
