"""reconstruct.stereo: stereo and structured light: SGBM matching, Gray-code and phase
decoding, the capture and pair pipelines, their options and scoring.

Modules: ``matching``, ``options``, ``pair``, ``pipeline``, ``scoring``, ``sl_pipeline``,
``structured_light``.

Every name below is importable from the room (``from reconstruct.stereo import NAME``),
loaded on first use.

Names defined by more than one module are reached through their module: ``run_capture``.
"""

from core.lazy import lazy_exports

_EXPORTS = {
    "MatchOptions": "matching",
    "depth_to_points": "matching",
    "disparity_range": "matching",
    "disparity_to_depth": "matching",
    "lr_consistency": "matching",
    "match": "matching",
    "texture_mask": "matching",
    "StereoOptions": "options",
    "read_disparity": "pair",
    "run_pair": "pair",
    "calibrate_capture": "pipeline",
    "calib_errors": "scoring",
    "coarse_align": "scoring",
    "depth_errors": "scoring",
    "gt_disparity": "scoring",
    "raw_depth_at": "scoring",
    "reference_in_table": "scoring",
    "score_mesh": "scoring",
    "SLOptions": "sl_pipeline",
    "decode_stack": "sl_pipeline",
    "decode_gray_code": "structured_light",
    "decode_phase": "structured_light",
    "gray_bit_errors": "structured_light",
    "projector_coords_at": "structured_light",
    "triangulate_columns": "structured_light",
    "unwrap_with_gray": "structured_light",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
