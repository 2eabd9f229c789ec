"""reconstruct.sfm: structure from motion: the pycolmap calls, photo folders as cameras
write them, and the pipeline (sparse, then the dense stage of :mod:`reconstruct.mvs`).

Modules: ``colmap``, ``escalate`` (the stronger steps for the views the default leaves
out), ``photo_set``, ``pipeline``, ``principal_point``, ``self_check`` (a sparse model
against its own verified matches).

Every name below is importable from the room (``from reconstruct.sfm import NAME``), loaded
on first use.
"""

from core.lazy import lazy_exports

_EXPORTS = {
    "ColmapOptions": "colmap",
    "ColmapResult": "colmap",
    "MAPPERS": "colmap",
    "MATCHERS": "colmap",
    "extract": "colmap",
    "match": "colmap",
    "reconstruct": "colmap",
    "run_colmap": "colmap",
    "EscalationOptions": "escalate",
    "escalate": "escalate",
    "merge_models": "escalate",
    "ring_pairs": "escalate",
    "similarity_from_common_views": "escalate",
    "remap_in_file_order": "escalate",
    "SelfCheck": "self_check",
    "check_model": "self_check",
    "check_reconstruction": "self_check",
    "CAMERA_MODES": "photo_set",
    "CameraGroup": "photo_set",
    "camera_groups": "photo_set",
    "list_photos": "photo_set",
    "scan_photos": "photo_set",
    "upright_folder": "photo_set",
    "SfmConfig": "pipeline",
    "parse_camera": "pipeline",
    "run": "pipeline",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
