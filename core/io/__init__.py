"""core.io: the file formats, one module a format family; computation lives elsewhere.

- :mod:`core.io.mesh`   meshes (PLY, OBJ, glTF, STL, OFF), point clouds, polylines
- :mod:`core.io.image`  images and photos' EXIF
- :mod:`core.io.range`  range grids (PLY), Stanford ``.conf``, MeshLab ``.aln``, ``poses.json``
- :mod:`core.io.e57`    ASTM E57 scans
- :mod:`core.io.las`    LAS/LAZ point clouds, streamed by chunk
- :mod:`core.io.raster` GeoTIFF rasters with their CRS
- :mod:`core.io.trees`  tree inventories (CSV)
- :mod:`core.io.qsm`    quantitative structure models: TreeQSM cylinder tables (CSV)
- :mod:`core.io.vector` polygons with attributes and a CRS (GeoPackage)
- :mod:`core.io.scene_cameras` other tools' scene cameras (OpenMVS ``.mvs``, Meshroom
  ``cameras.sfm``)

Every writer is atomic (:func:`core.files.atomic_file`); every reader raises
:class:`core.validate.InputError` naming the file. Names load on first use (:mod:`core.lazy`).

>>> from core.io import read_mesh, MESH_SUFFIXES
>>> ".ply" in MESH_SUFFIXES
True
"""

from core.lazy import lazy_exports

_MODULES = {
    "mesh": ["read_mesh", "write_mesh", "read_points", "write_points", "read_geometry",
             "write_polylines", "MESH_SUFFIXES", "POINT_SUFFIXES", "POLYLINE_SUFFIXES",
             "write_labeled_mesh", "read_labeled_mesh", "native_output"],
    "image": ["read_image", "write_image", "PhotoInfo", "photo_info", "to_uint8",
              "IMAGE_SUFFIXES"],
    "range": ["RangeGrid", "read_range_grid", "write_range_grid", "is_range_grid", "read_conf",
              "write_conf", "conf_files", "read_aln", "write_aln", "ScanPose", "read_poses_json",
              "write_poses_json", "model_from_conf", "conf_from_model"],
    "e57": ["E57Scan", "read_e57", "write_e57"],
    "las": ["LasWriter", "LasInfo", "read_las", "iter_las_chunks", "STANDARD_FIELDS",
            "SCAN_ANGLE_STEP_DEG", "gps_date", "AsprsClass", "ASPRS_NAMES"],
    "raster": ["Raster", "write_raster", "read_raster"],
    "trees": ["read_tree_table", "write_tree_table", "TEXT_COLUMNS"],
    "vector": ["write_polygons", "read_polygons", "multipolygon_wkb", "parse_multipolygon_wkb"],
    "qsm": ["QSM_COLUMNS", "QSM", "check_qsm", "read_qsm_csv", "write_qsm_csv"],
    "scene_cameras": ["ViewCamera", "read_openmvs_scene", "read_meshroom_sfm",
                      "OPENMVS_VERSIONS"],
}
_EXPORTS = {name: module for module, names in _MODULES.items() for name in names}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
