"""Structured light: one camera and a Gray-code + phase-shift projector over a turntable.

``scanamp capture structured-light SCENE --out DIR`` renders the pattern stacks and the
calibration captures (options: :class:`acquire.stereo.rig.SLCaptureConfig`, the stereo
rig's tables; the right camera is the projector, modelled as an inverse camera).
``scanamp reconstruct structured-light CAPTURE --out DIR`` calibrates the camera and the
projector, decodes, triangulates with the projector, fuses (TSDF) and meshes
(:func:`reconstruct.stereo.sl_pipeline.run_capture`, options
:class:`reconstruct.stereo.sl_pipeline.SLOptions`). The mesh is in the calibrated
turntable frame.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from acquire.stereo.rig import SLCaptureConfig
from reconstruct.stereo.sl_pipeline import SLOptions
from scanamp.methods.protocol import Method, object_name, scene_info, world_from_table

__all__ = ["StructuredLight", "METHOD"]


class StructuredLight(Method):
    name = "structured-light"
    title = "structured light (Gray code + phase)"
    capture_help = ("render a structured-light capture (Gray code + phase shift from a "
                    "projector modelled as an inverse camera) of a scene on a turntable, with "
                    "board calibration views")
    reconstruct_help = ("structured-light reconstruction: camera-projector calibration, "
                        "Gray-code + phase decoding, triangulation with the projector, TSDF "
                        "fusion and meshing")
    capture_config = SLCaptureConfig
    recon_config = SLOptions
    frame = "table: the calibrated turntable frame (the world's when the axis board is mounted)"
    metrics = ("evaluation.accuracy_mean", "evaluation.fscore")

    def capture(self, bundle, config, out_dir, *, rng, seed=0, scene_path=None) -> Path:
        from acquire.stereo.capture_sl import capture

        return capture(bundle.render_scene, config, out_dir, rng,
                       scene_info=scene_info(bundle, scene_path), seed=seed,
                       object_name=object_name(bundle, config))

    def reconstruct(self, config, inputs, out_dir):
        from reconstruct.stereo.sl_pipeline import run_capture

        return run_capture(inputs, out_dir, config)

    def world_from_output(self, capture_config, capture_dir, result) -> np.ndarray:
        return world_from_table(result.report, "table_from_cam", capture_config)


METHOD = StructuredLight()
