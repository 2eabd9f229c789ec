"""reconstruct.mvs: multi-view stereo on the CPU: PatchMatch depth maps (numba kernels),
SGBM pair depth, fusion of depth maps, what the views saw (the unseen trim and the
truth-free precision), and the dense stage that chains them.

Modules: ``dense``, ``fusion``, ``patchmatch``, ``pipeline``, ``precision``.

Every name below is importable from the room (``from reconstruct.mvs import NAME``), loaded
on first use.
"""

from core.lazy import lazy_exports

_EXPORTS = {
    "DenseOptions": "dense",
    "consistency_filter": "dense",
    "depth_maps": "dense",
    "pair_depth": "dense",
    "select_neighbors": "dense",
    "FusedPoints": "fusion",
    "FusionOptions": "fusion",
    "fuse_points": "fusion",
    "poisson_surface": "fusion",
    "DepthMap": "patchmatch",
    "PatchMatchOptions": "patchmatch",
    "View": "patchmatch",
    "depth_range": "patchmatch",
    "prepare_views": "patchmatch",
    "seen_masks": "precision",
    "seen_precision": "precision",
    "unseen_votes": "precision",
    "DENSE_METHODS": "pipeline",
    "MvsOptions": "pipeline",
    "SURFACES": "pipeline",
    "dense_report": "pipeline",
    "dense_surface": "pipeline",
    "depth_stage": "pipeline",
    "fuse_stage": "pipeline",
    "mesh_stage": "pipeline",
    "select_sources": "pipeline",
    "working_colors": "pipeline",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
