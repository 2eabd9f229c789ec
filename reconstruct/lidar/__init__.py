"""reconstruct.lidar: terrain, canopy and trees of an airborne LiDAR survey, simulated or real.

Modules: ``ground`` (the cloth simulation filter, TIN densification, water), ``rasters``
(DTM by TIN, CHM, DSM), ``trees`` (tops by a variable-window local maximum, crowns by
watershed, heights from the ground at the stem), ``crowns`` (crowns as polygons),
``evaluation`` (lidaRtRee's tree matching, detection scores, DTM errors), ``pipeline``
(``scanamp reconstruct lidar``).

Every name below is importable from the room (``from reconstruct.lidar import NAME``),
loaded on first use.
"""

from core.lazy import lazy_exports

_EXPORTS = {
    "GroundOptions": "ground",
    "classify_ground": "ground",
    "delaunay_2d": "ground",
    "densify_tin": "ground",
    "find_water": "ground",
    "canopy_height": "rasters",
    "dtm_from_ground": "rasters",
    "grid_for": "rasters",
    "height_above": "rasters",
    "surface_model": "rasters",
    "crown_polygons": "crowns",
    "point_in_polygons": "crowns",
    "polygon_area": "crowns",
    "TreeOptions": "trees",
    "detect_trees": "trees",
    "dynamics": "trees",
    "DELTA_GROUND": "evaluation",
    "H_PREC": "evaluation",
    "dtm_errors": "evaluation",
    "evaluate_lidar": "evaluation",
    "lidar_table": "evaluation",
    "match_trees": "evaluation",
    "tree_scores": "evaluation",
    "LidarReconConfig": "pipeline",
    "LidarResult": "pipeline",
    "reconstruct_points": "pipeline",
    "run": "pipeline",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
