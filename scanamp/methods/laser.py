"""Laser triangulation: a sheet of light over an object on a turntable or linear stage.

``scanamp capture laser SCENE --out DIR`` renders the scan and its calibration captures
(options: :class:`acquire.laser.rig.LaserCaptureConfig`, ``--rig.steps 90``,
``--sensor.read-noise 4``, or ``--config rig.toml`` with ``[rig]``, ``[sensor]``,
``[target]`` tables). ``scanamp reconstruct laser CAPTURE --out DIR`` calibrates (camera,
laser plane, axis) and meshes (:func:`reconstruct.laser.pipeline.run`, options
:class:`reconstruct.laser.pipeline.LaserReconConfig`); run again into the same folder with
``--overwrite``, only the stages whose options or inputs changed are recomputed, ``--from
STAGE`` forces that stage and the later ones. The mesh is in the calibrated turntable
(object) frame.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from acquire.laser.rig import LaserCaptureConfig
from reconstruct.laser.pipeline import STAGES, LaserReconConfig
from scanamp.methods.protocol import Method, add_from_stage, scene_info

__all__ = ["Laser", "METHOD"]


class Laser(Method):
    name = "laser"
    title = "laser triangulation (turntable or stage)"
    capture_help = ("sheet-of-light scan of a scene on a turntable or linear stage, with the "
                    "calibration captures (camera target, laser plane, axis)")
    reconstruct_help = ("calibrate (camera, laser plane, axis) and reconstruct a mesh from a "
                        "laser capture; scores it when the capture has ground truth")
    capture_config = LaserCaptureConfig
    recon_config = LaserReconConfig
    frame = "object: the calibrated turntable (or stage) frame"
    metrics = ("evaluation.depth_error.rms_m", "evaluation.surface.fscore",
               "evaluation.surface.recall", "evaluation.surface.precision")

    def capture(self, bundle, config, out_dir, *, rng, seed=0, scene_path=None) -> Path:
        from acquire.laser.capture import capture

        return capture(bundle.render_scene, config, out_dir, rng,
                       scene_info=scene_info(bundle, scene_path), seed=seed,
                       gt_mesh=bundle.gt_mesh())

    def reconstruct(self, config, inputs, out_dir, *, from_stage=None):
        from reconstruct.laser.pipeline import run

        return run(config, inputs, out_dir, from_stage=from_stage)

    def world_from_output(self, capture_config, capture_dir, result) -> np.ndarray:
        """The true camera pose carries the calibrated object frame into the world:
        world <- camera <- object."""
        object_from_camera = np.asarray(result.report["calibration"]["object_from_camera"])
        return capture_config.rig.camera().world_from_cam @ np.linalg.inv(object_from_camera)

    def add_reconstruct_arguments(self, parser) -> None:
        super().add_reconstruct_arguments(parser)
        add_from_stage(parser, STAGES)

    def reconstruct_from_args(self, config, args):
        return self.reconstruct(config, args.capture, args.out, from_stage=args.from_stage)

    def describe(self, result) -> list[str]:
        rep = result.report
        lines = []
        st = rep.get("stages", {})
        if st.get("reused"):
            lines.append(f"stages reused: {', '.join(st['reused'])}; ran: "
                         f"{', '.join(st['ran']) or 'none'}")
        c = rep["counts"]
        lines.append(f"{c['stripe_points']} stripe points from {c['frames']} frames -> "
                     f"{c['mesh_triangles']} triangles; camera RMS "
                     f"{rep['calibration']['camera']['rms_px']:.3f} px -> {result.out_dir}")
        ev = rep.get("evaluation")
        if ev:
            s, depth = ev["surface"], ev.get("depth_error", {})
            lines.append(
                f"F-score@{1000 * s['tau']:.2g}mm {s['fscore']:.3f} (P {s['precision']:.3f} "
                f"R {s['recall']:.3f}); depth RMS "
                f"{1000 * (depth.get('rms_m') or float('nan')):.3g} mm vs predicted "
                f"{1000 * (depth.get('predicted_rms_m') or float('nan')):.3g} mm")
        return lines


METHOD = Laser()
