"""Structure from motion: pycolmap sparse reconstruction on the CPU, our dense surface.

``run(config, input, out_dir)`` takes an SfM capture folder (capture.json) or a plain
folder of photos as cameras write them (JPEG, PNG, TIFF; 8 or 16 bit; grey or colour;
EXIF orientation applied, mixed sizes and orientations) and writes:

- ``sparse/0/`` the COLMAP model in binary, ``sparse/0/text/`` in text,
- ``points.ply`` sparse points (coloured), ``fused.ply`` the fused dense points,
  ``mesh.ply`` the dense surface, ``dense/`` the depth, normal and confidence maps
  (:mod:`reconstruct.mvs.pipeline`),
- ``transforms.json`` the estimated cameras for nerfstudio tools,
- ``report.json`` counts, timings, failures, per-view coverage and, with ground truth,
  the metrics.

Intrinsics: ``--camera MODEL:params`` when given; otherwise the capture's nominal
camera (what a photographer knows from EXIF: focal length, image size) as a starting
value that bundle adjustment refines; otherwise one camera per distinct image size and
EXIF focal length (``--camera-mode``), starting from the EXIF focal length, or COLMAP's
guess of 1.2 x the larger side. Known cameras (``--cameras``: a COLMAP model, a
nerfstudio transforms.json or a Middlebury ``*_par.txt``) replace the mapper: the
sparse points are triangulated with those poses and intrinsics fixed.

``ground_truth`` is read only to score: the Sim(3) alignment of the cameras, pose
errors, and the mesh F-score; when it exists the dense stage works in the aligned
(scene) frame so the mesh can be compared. The scene size is the bounding-box diagonal
of the ground-truth scene.
"""

from __future__ import annotations

import contextlib
import logging
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import cv2  # noqa: F401  (before pycolmap)
import numpy as np

from acquire.camera import Camera
from acquire.capture_io import load_capture
from acquire.sfm.nerfstudio import write_transforms
from core.config import Config, option
from core.files import atomic_dir, json_data, scratch_dir, write_json
from core.io.image import read_image, to_uint8
from core.io.mesh import read_mesh, write_mesh, write_points
from core.meshes import sorted_mesh
from core.validate import InputError, check_choice
from reconstruct.calibration.io import read_camera_yaml
from reconstruct.camera_files import (
    CAMERA_MODELS,
    camera_from_colmap,
    colmap_params_from_camera,
    image_cam_from_world,
    read_cameras,
)
from reconstruct.evaluation.sim3 import align_cameras
from reconstruct.mvs.pipeline import MvsOptions
from reconstruct.result import ReconstructionResult
from reconstruct.sfm.colmap import ColmapOptions
from reconstruct.sfm.photo_set import (
    CAMERA_MODES,
    camera_groups,
    list_photos,
    scan_photos,
    upright_folder,
)

__all__ = ["SfmConfig", "run", "parse_camera"]

log = logging.getLogger(__name__)

MATCHER_CHOICES = ("auto", "exhaustive", "sequential", "spatial")


@dataclass
class SfmConfig(Config):
    """Options of the SfM pipeline (``scanamp reconstruct sfm``)."""

    camera: str | None = option(None, help="intrinsics MODEL:p1,p2,... in COLMAP's order and "
                                           "pixel convention (e.g. SIMPLE_RADIAL:800,320,240,0"
                                           "), or a camera.yaml from scanamp calibrate camera; "
                                           "default: the capture's nominal camera, else EXIF, "
                                           "else estimated")
    camera_mode: str = option("auto", choices=CAMERA_MODES,
                              help="photos sharing a camera: 'auto' one per distinct size "
                                   "and EXIF focal length, 'single' one for all, "
                                   "'per-image' one each")
    cameras: str | None = option(None, help="known cameras: a COLMAP model (folder, text or "
                                            "binary), a nerfstudio transforms.json, a "
                                            "Middlebury *_par.txt, an OpenMVS .mvs, a "
                                            "Meshroom .sfm or a folder of Strecha .camera "
                                            "files; the sparse points are then triangulated "
                                            "with those poses fixed")
    hold_intrinsics: bool = option(False, help="hold the intrinsics of --camera (or the "
                                               "capture's camera) fixed: a calibrated "
                                               "camera, only poses and points adjusted; "
                                               "default: refined from there by bundle "
                                               "adjustment")
    principal_point: str = option("auto", choices=("auto", "centre"),
                                  help="intrinsics not given: 'auto' refines the principal "
                                       "point in a final bundle adjustment where the views "
                                       "constrain it (a spread of view directions, halves "
                                       "of the points agreeing) and keeps it at the image "
                                       "centre, with the reason in report.json, where not "
                                       "(reconstruct.sfm.principal_point); 'centre' always "
                                       "keeps it there, as COLMAP's mapper does")
    mapper: str = option("incremental", choices=("incremental", "global"),
                         help="pycolmap's mapper")
    matcher: str = option("auto", choices=MATCHER_CHOICES,
                          help="'auto': exhaustive up to 100 images, sequential beyond or for "
                               "a hand-held walk of more than 40")
    dense: bool = option(True, help="build the dense surface (else sparse only)")
    num_threads: int = option(-1, range="[-1, 1024]", help="threads (-1 = all cores)")
    seed: int = option(0, range="[0, inf)", help="pycolmap's random seed")
    max_features: int = option(8192, range="[100, 1000000]", help="SIFT features per image")
    mvs: MvsOptions = option(default_factory=MvsOptions,
                             help="the dense stage's options (PatchMatch, fusion, surface)")
    min_keypoints: int = option(30, range="[0, inf)",
                                help="fewer SIFT features than this marks an image "
                                     "textureless")
    escalate: bool = option(True, help="when the default sparse stage leaves views out, "
                                       "try stronger features, guided matching, relaxed "
                                       "mapping, model merging and re-localization on "
                                       "them (reconstruct.sfm.escalate)")
    self_check: bool = option(True, help="check the sparse model against its own verified "
                                         "matches (reconstruct.sfm.self_check: a scene that "
                                         "repeats itself can fold the views onto each "
                                         "other); when the model contradicts them, map "
                                         "again from the pairs of views close in file "
                                         "order and keep the model those pairs agree "
                                         "with more; the findings go to report.json and "
                                         "the log")

    def __post_init__(self):
        super().__post_init__()
        if self.camera is not None:
            parse_camera(self.camera)


def parse_camera(text: str) -> tuple[str, str]:
    """``"MODEL:p1,p2,..."`` -> ``(model, params)``; ValueError naming what is wrong.

    A path to a camera YAML (``scanamp calibrate camera``'s output, read by
    :func:`reconstruct.calibration.io.read_camera_yaml`) gives the OPENCV model from it.
    """
    if Path(text).suffix.lower() in (".yaml", ".yml", ".xml"):
        return colmap_params_from_camera(read_camera_yaml(text), "OPENCV")
    if ":" not in text:
        raise ValueError(f"camera: expected MODEL:params (e.g. SIMPLE_RADIAL:800,320,240,0), "
                         f"got {text!r}")
    model, params = text.split(":", 1)
    model = model.strip().upper()
    check_choice(model, "camera model", CAMERA_MODELS)
    ColmapOptions(camera_model=model, camera_params=params)  # validates the count
    return model, params


# -- input --------------------------------------------------------------------------------

@dataclass
class _Input:
    image_dir: Path
    names: list
    capture: object = None  # acquire.capture_io.Capture or None
    nominal: Camera | None = None
    order: str = "unknown"
    infos: dict | None = None  # name -> core.io.image.PhotoInfo
    known: dict | None = None  # name -> Camera, from --cameras


def _resolve_input(path: Path) -> _Input:
    if not path.exists():
        raise InputError("not found", path=path)
    if (path / "capture.json").is_file() or path.suffix == ".json":
        cap = load_capture(path)
        if cap.kind != "sfm":
            log.info("capture kind %r: using its frames as an image set", cap.kind)
        names = [fr["image"] for fr in cap.frames if "image" in fr]
        nominal = None
        cams = cap.cameras
        if len(cams) == 1:
            c = next(iter(cams.values()))
            if all(k in c for k in ("fx", "fy", "cx", "cy")):
                nominal = Camera(c["width"], c["height"], c["fx"], c["fy"], c["cx"], c["cy"],
                                 np.asarray(c.get("dist", np.zeros(5)), float))
        kind = cap.rig.get("path", {}).get("kind", "unknown") if isinstance(cap.rig, dict) \
            else "unknown"
        return _Input(cap.root, names, cap, nominal, kind)
    if not path.is_dir():
        raise InputError("expected a capture folder or a folder of images", path=path)
    names = list_photos(path)
    if not names:
        raise InputError("no images (JPEG, PNG, TIFF) and no capture.json", path=path)
    return _Input(path, names)


def _check_images(inp: _Input, cameras_file: str | None) -> None:
    """Every photo's header (a bad one is named), and the known cameras if any: each
    must name a photo of the folder, at its size; photos without one are left out."""
    inp.infos = scan_photos(inp.image_dir, inp.names)
    if cameras_file:
        sizes = {n: (i.width, i.height) for n, i in inp.infos.items()}
        known = read_cameras(cameras_file, sizes=sizes)
        missing = [n for n in known if n not in sizes]
        if missing:
            raise InputError(f"names images that are not in {inp.image_dir}: "
                             f"{', '.join(missing[:5])}{' ...' if len(missing) > 5 else ''}",
                             path=cameras_file)
        extra = [n for n in inp.names if n not in known]
        if extra:
            log.warning("%d photos have no camera in %s and are left out: %s", len(extra),
                        cameras_file, ", ".join(extra[:5]))
        inp.names = [n for n in inp.names if n in known]
        inp.known = known
    if len(inp.names) < 3:
        raise InputError(f"structure from motion needs at least 3 images, got {len(inp.names)}",
                         path=inp.image_dir)


def _choose_matcher(config: SfmConfig, inp: _Input) -> str:
    if config.matcher != "auto":
        return config.matcher
    n = len(inp.names)
    if inp.order == "walk" and n > 40:
        return "sequential"
    return "exhaustive" if n <= 100 else "sequential"


# -- evaluation helpers (ground truth only) --------------------------------------------------

def _visible_mask(mesh, cameras: list[Camera], tol: float):
    """``mask(points) -> bool``: points seen unoccluded by at least one camera."""
    import open3d as o3d

    rs = o3d.t.geometry.RaycastingScene()
    tm = o3d.t.geometry.TriangleMesh.from_legacy(mesh)
    rs.add_triangles(tm)

    def mask(points):
        seen = np.zeros(len(points), bool)
        for cam in cameras:
            px, z = cam.project(points)
            inside = (z > 0) & (px[:, 0] >= 0) & (px[:, 1] >= 0) & \
                (px[:, 0] <= cam.width - 1) & (px[:, 1] <= cam.height - 1) & ~seen
            if not inside.any():
                continue
            p = points[inside]
            d = p - cam.center
            dist = np.linalg.norm(d, axis=1)
            rays = np.concatenate([np.broadcast_to(cam.center, p.shape), d / dist[:, None]], 1)
            t = rs.cast_rays(o3d.core.Tensor(rays.astype(np.float32)))["t_hit"].numpy()
            idx = np.nonzero(inside)[0]
            seen[idx[t >= dist - tol]] = True
        return seen

    return mask


def _clean_mesh(mesh, min_fraction: float = 0.02):
    """Drop connected components smaller than ``min_fraction`` of the largest."""
    if len(mesh.triangles) == 0:
        return mesh
    labels, counts, _ = mesh.cluster_connected_triangles()
    labels, counts = np.asarray(labels), np.asarray(counts)
    small = counts[labels] < min_fraction * counts.max()
    mesh.remove_triangles_by_mask(small)
    mesh.remove_unreferenced_vertices()
    if mesh.has_vertex_colors():  # TSDF colour averages can overshoot [0, 1] by rounding
        import open3d as o3d

        mesh.vertex_colors = o3d.utility.Vector3dVector(
            np.clip(np.asarray(mesh.vertex_colors), 0.0, 1.0))
    return mesh


# -- the pipeline -----------------------------------------------------------------------------

# two-view geometries with no baseline to triangulate from (COLMAP's classification)
_NO_BASELINE = {"WATERMARK": "matches at the same pixels (a static camera, or an overlay)",
                "PANORAMIC": "a pure rotation", "PLANAR_OR_PANORAMIC":
                "one homography (a rotating camera, or a flat scene seen from afar)",
                "DEGENERATE": "a degenerate geometry"}


def _failures(database: Path, names: list, registered: set, min_kp: int) -> tuple[dict, str]:
    """Why each unregistered image failed, and a diagnosis of the whole set ("" when
    nothing stands out): no texture, no verified match, or matches that show no camera
    motion (COLMAP's two-view geometry types: watermark, panoramic, planar-or-panoramic)."""
    import pycolmap

    from reconstruct.sfm.escalate import pair_inliers

    out, by_name = {}, pair_inliers(database)
    db = pycolmap.Database.open(str(database))
    try:
        images = {im.name: im for im in db.read_all_images()}
        pairs, kinds = {}, {}
        if db.num_verified_image_pairs():
            ids, geoms = db.read_two_view_geometries()
            for pid, g in zip(ids, geoms, strict=False):
                a, b = pycolmap.pair_id_to_image_pair(pid)
                n = len(g.inlier_matches)
                kind = pycolmap.TwoViewGeometryConfiguration(int(g.config)).name
                for k in (a, b):
                    pairs[k] = max(pairs.get(k, 0), n)
                    if n >= 15:
                        kinds.setdefault(k, []).append(kind)
        for n in names:
            if n in registered:
                continue
            im = images.get(n)
            if im is None:
                out[n] = "not imported by COLMAP"
                continue
            kp = db.num_keypoints_for_image(im.image_id)
            mine = kinds.get(im.image_id, [])
            if kp < min_kp:
                out[n] = f"no texture: {kp} SIFT features"
            elif pairs.get(im.image_id, 0) < 15:
                out[n] = (f"no geometrically verified matches with any other image "
                          f"({kp} SIFT features)")
            elif all(k in _NO_BASELINE for k in mine):
                top = max(set(mine), key=mine.count)
                out[n] = (f"no camera motion: its matches with all {len(mine)} other images "
                          f"fit {_NO_BASELINE[top]}; nothing to triangulate")
            else:
                out[n] = "not registered by the mapper (too few 2D-3D correspondences)"
            out[n] += _inliers_with(n, by_name, registered)
    finally:
        db.close()
    all_kinds = [k for ks in kinds.values() for k in ks]
    diagnosis = ""
    if all_kinds and all(k in _NO_BASELINE for k in all_kinds):
        diagnosis = ("no image pair shows camera motion (COLMAP's two-view geometries: "
                     + ", ".join(f"{all_kinds.count(k) // 2} {k.lower()}"
                                 for k in sorted(set(all_kinds)))
                     + "): SfM needs the camera to move between shots, not only turn")
    return out, diagnosis


def _inliers_with(name: str, pairs: dict, registered: set, top: int = 3) -> str:
    """``"; inlier matches with the registered views: 12 with a.png, ..."`` (the best
    ``top``), or that it has none with any of them."""
    mine = sorted(((n, other) for (a, b), n in pairs.items() if name in (a, b)
                   for other in (b if a == name else a,) if other in registered),
                  key=lambda p: (-p[0], p[1]))
    if not mine:
        return "; no inlier matches with any registered view"
    return "; inlier matches with the registered views: " + ", ".join(
        f"{n} with {other}" for n, other in mine[:top]) + (" ..." if len(mine) > top else "")


#: the named stages of :func:`run`, in order (``scanamp reconstruct sfm --from STAGE``)
STAGES = ("features", "matches", "sparse", "dense", "fuse", "mesh", "evaluate")


def run(config: SfmConfig, input_path: str | os.PathLike, out_dir: str | os.PathLike, *,
        from_stage: str | None = None) -> ReconstructionResult:
    """Reconstruct cameras, sparse points and a dense mesh from images.

    The work is seven named stages (:data:`STAGES`), each cached in ``out_dir/stages``
    with the files it wrote (:class:`core.runs.stages.Stages`): run again into the same
    folder, only the stages whose options or inputs changed are recomputed (a new
    Poisson depth re-runs ``mesh`` and ``evaluate``, not SIFT or PatchMatch).
    ``from_stage`` forces a stage and the later ones.

    Parameters
    ----------
    config : SfmConfig
    input_path : path
        SfM capture folder (capture.json) or a folder of photos.
    out_dir : path
        Written atomically (report.json is written even when SfM fails).

    Returns
    -------
    reconstruct.result.ReconstructionResult
        ``ok`` is False when fewer than 3 images registered or the dense surface came
        out empty: the folder then holds report.json (and the sparse model if any),
        never a mesh.

    Raises
    ------
    InputError
        Fewer than 3 images, a missing, unreadable or truncated image, a cameras file
        that disagrees with the folder, every image textureless.
    """
    from core.runs.stages import Stages

    t_all = time.perf_counter()
    input_path, out_dir = Path(input_path), Path(out_dir)
    inp = _resolve_input(input_path)
    _check_images(inp, config.cameras)
    # one-off costs of the process (open3d alone takes seconds), kept out of the stage
    # timings so that a stage is compared with the bare pycolmap calls on equal terms
    t = time.perf_counter()
    import open3d  # noqa: F401
    import pycolmap  # noqa: F401
    t_imports = time.perf_counter() - t
    groups, intr_source = _intrinsics(config, inp, input_path)
    matcher = _choose_matcher(config, inp)
    opts = ColmapOptions(matcher=matcher, mapper=config.mapper, num_threads=config.num_threads,
                         seed=config.seed, max_features=config.max_features,
                         refine_intrinsics=not config.hold_intrinsics)
    sizes = sorted({(i.width, i.height) for i in inp.infos.values()})
    report = {"input": str(input_path), "kind": "sfm", "num_images": len(inp.names),
              "image_sizes": [list(sz) for sz in sizes],
              "exif_rotated": sorted(n for n in inp.names if inp.infos[n].orientation != 1),
              "intrinsics_source": intr_source,
              "cameras_file": config.cameras,
              "colmap": {k: v for k, v in asdict(opts).items()}, "options": {
                  "mapper": config.mapper, "matcher": matcher, "dense": config.dense,
                  "camera_mode": config.camera_mode, "seed": config.seed,
                  "num_threads": config.num_threads},
              "timings": {"imports": t_imports}}
    with atomic_dir(out_dir) as tmp, _Upright(inp, tmp) as upright:
        st = Stages(tmp, STAGES, from_stage=from_stage,
                    reuse=out_dir if out_dir.is_dir() else None)
        ok, message, views = _sparse_stages(st, config, inp, groups, opts, upright, tmp,
                                            out_dir, report)
        if ok and config.dense:
            ok, message = _dense_stages(st, config, inp, tmp, report, views)
        report["stages"] = {"ran": st.ran, "reused": st.skipped}
        report["timings"]["total"] = time.perf_counter() - t_all
        report["ok"], report["message"] = ok, message
        write_json(tmp / "report.json", report)
    return ReconstructionResult(out_dir, json_data(report), ok, message)


class _Upright:
    """A scratch folder of upright 8-bit photos for COLMAP under ``root`` (the output's
    temporary folder), made on first use (a run whose sparse stages are all reused never
    reads the photos for them) and removed on leaving."""

    def __init__(self, inp: _Input, root: Path):
        self.inp, self.root, self._path = inp, root, None
        self._scratch = contextlib.ExitStack()

    @property
    def path(self) -> Path:
        if self._path is None:
            folder = self._scratch.enter_context(scratch_dir(self.root))
            self._path = upright_folder(self.inp.image_dir, self.inp.names, self.inp.infos,
                                        folder)
        return self._path

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._scratch.close()


def _timed(fn, *args, **kwargs) -> dict:
    t = time.perf_counter()
    value = fn(*args, **kwargs)
    return {"value": value, "seconds": time.perf_counter() - t}


def _features(upright: _Upright, groups, opts, tmp: Path) -> dict:
    """Stage ``features``: SIFT of every photo, in ``colmap/features.db``."""
    from reconstruct.sfm.colmap import extract

    (tmp / "colmap").mkdir(exist_ok=True)
    db = tmp / "colmap" / "features.db"
    db.unlink(missing_ok=True)
    return _timed(extract, db, upright.path, groups, opts)


def _matches(opts, tmp: Path) -> dict:
    """Stage ``matches``: verified matches, in ``colmap/database.db`` (features.db plus
    the matches: a new matcher starts again from the features)."""
    import shutil

    from reconstruct.sfm.colmap import match

    db = tmp / "colmap" / "database.db"
    shutil.copy2(tmp / "colmap" / "features.db", db)
    return _timed(match, db, opts)


def _sparse(config, inp, opts, groups, upright: _Upright, tmp: Path, out_dir: Path) -> dict:
    """Stage ``sparse``: the mapper (or triangulation at known poses); the model, points.ply
    and transforms.json; with ground truth the pose errors. What the dense stages need
    (cameras, sparse points, what each view sees) is returned."""
    from reconstruct.sfm.colmap import reconstruct

    t = time.perf_counter()
    database = tmp / "colmap" / "database.db"
    known = None if inp.known is None else {
        n: c.cam_from_world for n, c in inp.known.items() if n in inp.names}
    rec, num_models = reconstruct(database, upright.path, tmp / "colmap" / "sparse", opts,
                                  known_poses=known)
    seconds = time.perf_counter() - t
    escalation, t = None, time.perf_counter()
    if (known is None and config.escalate and len(inp.names) >= 3
            and (rec.num_reg_images() if rec is not None else 0) < len(inp.names)):
        rec, database, escalation = _escalate(database, inp, groups, opts, upright, tmp, rec)
    registered = sorted(im.name for im in rec.images.values() if im.has_pose) if rec else []
    failures, diagnosis = _failures(database, inp.names, set(registered), config.min_keypoints)
    textureless = [n for n, why in failures.items() if why.startswith("no texture")]
    if len(inp.names) - len(textureless) < 3 and inp.known is None:
        raise InputError("images with no texture (too few SIFT features): "
                         + ", ".join(textureless), path=inp.image_dir)
    part = {"registered": len(registered), "registered_fraction": len(registered)
            / len(inp.names), "failed_images": failures, "num_models": num_models,
            "escalation": escalation}
    if diagnosis:
        part["diagnosis"] = diagnosis
    if known is None and config.self_check and rec is not None and len(registered) >= 3:
        t_check = time.perf_counter()
        rec, database, part["self_check"] = _self_check(rec, database, upright, opts, tmp)
        registered = sorted(im.name for im in rec.images.values() if im.has_pose)
        part.update(registered=len(registered),
                    registered_fraction=len(registered) / len(inp.names))
        if part["self_check"]["recovery"] and part["self_check"]["recovery"]["kept"]:
            part["failed_images"], _ = _failures(database, inp.names, set(registered),
                                                 config.min_keypoints)
        if part["self_check"]["warnings"]:
            part["warnings"] = list(part["self_check"]["warnings"])
        seconds += time.perf_counter() - t_check
    t_pp = time.perf_counter()
    if rec is not None and len(registered) >= 3 and _principal_point_free(config, inp):
        from reconstruct.sfm.principal_point import decisions_report, refine_principal_point

        rec, decisions = refine_principal_point(rec, sorted(rec.cameras.keys()),
                                                num_threads=opts.num_threads,
                                                rng=np.random.default_rng(config.seed))
        part["principal_point"] = decisions_report(decisions)
    seconds += time.perf_counter() - t_pp
    out = {"report": part, "seconds": seconds, "views": None,
           "escalate_seconds": escalation["seconds"] if escalation else 0.0}
    if rec is not None and len(registered) >= 3:
        out["views"] = _sparse_outputs(rec, inp, tmp, out_dir, part)
    return out


def _self_check(rec, database: Path, upright, opts, tmp: Path):
    """The model checked against its verified matches (:mod:`reconstruct.sfm.self_check`);
    when it contradicts them, the mapper again on the pairs close in file order
    (:func:`reconstruct.sfm.escalate.remap_in_file_order`), and the model those pairs
    agree with more kept. Returns the model, its database and the report."""
    from reconstruct.sfm.escalate import ORDERED_OVERLAP, remap_in_file_order
    from reconstruct.sfm.self_check import check_reconstruction

    check = check_reconstruction(rec, database)
    out = {"model": check.to_dict(), "recovery": None, "warnings": []}
    n = rec.num_reg_images()
    overlap = ORDERED_OVERLAP
    if not check.ok and len(rec.images) > 2 * overlap + 1:
        t = time.perf_counter()
        other, db2, step = remap_in_file_order(database, upright.path, opts,
                                               tmp / "colmap" / "self_check", overlap=overlap)
        step["kept"] = False
        if other is not None and other.num_reg_images() >= 3:
            # both models judged on the same evidence: the pairs close in file order
            before, after = check_reconstruction(rec, db2), check_reconstruction(other, db2)
            step["before_on_close_pairs"] = before.to_dict()
            step["after_on_close_pairs"] = after.to_dict()
            if after.pairs and before.pairs and \
                    after.explained_share > before.explained_share + 0.05 and \
                    len(after.contradicted) < len(before.contradicted):
                step["kept"] = True
                out["warnings"].append(
                    f"the model from every verified pair contradicted {len(check.contradicted)}"
                    f" of its {check.pairs} pairs; mapped again from the {step['pairs_kept']}"
                    f" pairs at most {overlap} apart in file order ({step['pairs_left_out']} "
                    f"left out), which it explains better ({100 * after.explained_share:.0f}"
                    f" % of their matches against {100 * before.explained_share:.0f} %): "
                    f"{other.num_reg_images()} of {n} views")
                rec, database, check = other, db2, after
        step["seconds"] = time.perf_counter() - t
        out["recovery"] = step
    out["final"] = check.to_dict()
    out["warnings"] += check.warnings
    for w in out["warnings"]:
        log.warning("sparse self-check: %s", w)
    return rec, database, out


def _principal_point_free(config: SfmConfig, inp: _Input) -> bool:
    """Whether the principal point is ours to estimate: ``--principal-point auto`` and
    no intrinsics given (``--camera``, the capture's nominal camera, ``--cameras``)."""
    return (config.principal_point == "auto" and inp.known is None and not config.camera
            and inp.nominal is None)


def _escalate(database, inp, groups, opts, upright, tmp, rec):
    """The stronger steps on what the default left out (:mod:`reconstruct.sfm.escalate`);
    the model, the database its matches are in, and the report of the steps."""
    from reconstruct.sfm.escalate import escalate

    t = time.perf_counter()
    before = rec.num_reg_images() if rec is not None else 0
    best, db, report = escalate(database, upright.path, inp.names, groups, opts,
                                tmp / "colmap" / "escalate", rec)
    report["seconds"] = time.perf_counter() - t
    log.info("escalation: %d -> %d of %d views registered (%.0f s)", before,
             report["registered"], len(inp.names), report["seconds"])
    if best is None or best.num_reg_images() <= before:
        return rec, database, report
    return best, db, report


def _sparse_stages(st, config, inp, groups, opts, upright, tmp, out_dir, report):
    """features -> matches -> sparse; whether enough registered, and why not."""
    from core.runs.stages import files_key

    t = time.perf_counter()
    photos = files_key([inp.image_dir / n for n in inp.names])
    cams_file = files_key([config.cameras]) if config.cameras else None
    feats = st.run("features", _features, upright, groups, opts, tmp, files=[
        "colmap/features.db"], depends={"photos": photos, "cameras": groups,
                                        "max_features": opts.max_features})
    matches = st.run("matches", _matches, opts, tmp, files=["colmap/database.db"],
                     depends={"matcher": opts.matcher, "seed": opts.seed,
                              "sequential_overlap": opts.sequential_overlap,
                              "spatial_neighbors": opts.spatial_neighbors})
    sparse = st.run("sparse", _sparse, config, inp, opts, groups, upright, tmp, out_dir,
                    files=["sparse", "points.ply", "transforms.json"],
                    depends={"mapper": opts.mapper, "seed": opts.seed, "known": cams_file,
                             "principal_point": config.principal_point,
                             "hold_intrinsics": config.hold_intrinsics,
                             "min_keypoints": config.min_keypoints,
                             "escalate": config.escalate,
                             "self_check": config.self_check})
    report.update(sparse["report"])
    report["timings"].update({"extract": feats["seconds"], "match": matches["seconds"],
                              "map" if inp.known is None else "triangulate":
                              sparse["seconds"]})
    report["timings"]["escalate"] = sparse.get("escalate_seconds", 0.0)
    report["timings"]["pycolmap"] = (feats["seconds"] + matches["seconds"] + sparse["seconds"]
                                     + report["timings"]["escalate"])
    report["timings"]["sparse_total"] = time.perf_counter() - t
    if any(n in st.skipped for n in STAGES[:3]):  # a reused stage's time is its first run's
        report["timings"]["sparse_total"] = report["timings"]["pycolmap"]
    report["timings"]["sparse_overhead"] = (report["timings"]["sparse_total"]
                                            - report["timings"]["pycolmap"])
    if sparse["views"] is None:
        n = len(inp.names)
        diag = sparse["report"].get("diagnosis", "")
        return False, (f"SfM did not register: {report['registered']} of {n} images"
                       + (f": {diag}" if diag else "")
                       + f" (see {out_dir / 'report.json'} for each image)"), None
    check = sparse["report"].get("self_check")
    if check and not check["final"]["ok"]:
        return True, "ok, but the sparse self-check failed: " + check["final"]["warnings"][0], \
            sparse["views"]
    return True, "ok", sparse["views"]


def _intrinsics(config, inp, input_path: Path) -> tuple[list, str]:
    """COLMAP cameras ``[(names, model, params)]`` and where their intrinsics came from:
    known cameras (--cameras), --camera (a string or a camera.yaml), the capture's
    nominal camera, else one camera per group of photos (--camera-mode) from EXIF."""
    sizes = {(i.width, i.height) for n, i in inp.infos.items() if n in inp.names}
    if inp.known is not None:
        groups = [([n], *colmap_params_from_camera(inp.known[n])) for n in inp.names]
        return groups, f"--cameras {config.cameras} (held fixed)"
    one = None
    if config.camera or inp.nominal is not None:
        if len(sizes) > 1:
            what = "--camera" if config.camera else "the capture's nominal camera"
            raise InputError(f"{what} is one camera, but the images have "
                             f"{len(sizes)} sizes: " + ", ".join(f"{w}x{h}" for w, h in
                                                                  sorted(sizes)),
                             path=inp.image_dir)
        width, height = next(iter(sizes))
    if config.camera:
        model, params = parse_camera(config.camera)
        one = (model, params, "--camera")
        if Path(config.camera).suffix.lower() in (".yaml", ".yml", ".xml"):
            cam = read_camera_yaml(config.camera)
            if (cam.width, cam.height) != (width, height):
                raise InputError(f"calibrated for {cam.width}x{cam.height} images, the images "
                                 f"are {width}x{height}", path=config.camera,
                                 field="image_width")
            one = (model, params, f"--camera {config.camera}")
    elif inp.nominal is not None:
        if (inp.nominal.width, inp.nominal.height) != (width, height):
            raise InputError(f"cameras: nominal size {inp.nominal.width}x{inp.nominal.height} "
                             f"differs from the images ({width}x{height})",
                             path=input_path / "capture.json")
        model, params = colmap_params_from_camera(inp.nominal)
        one = (model, params, "capture.json nominal camera (refined by bundle adjustment)")
    if one is not None:
        source = one[2]
        if config.hold_intrinsics:
            source = source.replace(" (refined by bundle adjustment)", "") + " (held)"
        return [(list(inp.names), one[0], one[1])], source
    if config.hold_intrinsics:
        raise InputError("--hold-intrinsics holds given intrinsics: give --camera (or a "
                         "capture with its camera)", field="--hold-intrinsics")
    try:
        groups = camera_groups({n: inp.infos[n] for n in inp.names}, config.camera_mode)
    except ValueError as e:
        raise InputError(str(e), path=inp.image_dir) from None
    out, sources = [], []
    for g in groups:
        if g.focal_px is not None:
            params = f"{g.focal_px!r}, {g.width / 2!r}, {g.height / 2!r}, 0.0"
            sources.append(f"EXIF focal length {g.focal_px:.1f} px")
        else:
            params = None
            sources.append(f"no EXIF focal length: 1.2 x {max(g.width, g.height)} px")
        out.append((g.names, "SIMPLE_RADIAL", params))
    kinds = sorted(set(sources))
    return out, (f"{len(groups)} camera(s) ({config.camera_mode}): " + "; ".join(kinds)
                 + ", refined by bundle adjustment")


def _sparse_outputs(rec, inp, tmp: Path, out_dir: Path, report: dict) -> dict:
    """The sparse model (binary and text), points.ply and transforms.json; with ground
    truth, everything aligned to the true cameras by Sim(3) and the pose errors. The
    registered views' names, cameras, sparse points and what each view sees."""
    sparse = tmp / "sparse" / "0"
    (sparse / "text").mkdir(parents=True)
    rec.write(str(sparse))
    rec.write_text(str(sparse / "text"))
    report["sparse"] = {
        "num_points": rec.num_points3D(),
        "mean_reprojection_error_px": rec.compute_mean_reprojection_error(),
        "mean_track_length": rec.compute_mean_track_length(),
        "cameras": {int(cid): {"model": c.model_name, "params": list(map(float, c.params)),
                               "has_prior_focal_length": bool(c.has_prior_focal_length)}
                    for cid, c in rec.cameras.items()}}
    images = sorted((im for im in rec.images.values() if im.has_pose),
                    key=lambda im: inp.names.index(im.name))
    cams = [camera_from_colmap(im.camera, image_cam_from_world(im)) for im in images]
    ids = sorted(rec.points3D.keys())
    index = {p: i for i, p in enumerate(ids)}
    pts = np.array([rec.points3D[p].xyz for p in ids]).reshape(-1, 3)
    cols = np.array([rec.points3D[p].color for p in ids]).reshape(-1, 3) / 255.0
    visible = [np.array([index[p.point3D_id] for p in im.points2D if p.has_point3D()],
                        np.int64) for im in images]
    gt = inp.capture.ground_truth if inp.capture is not None else None
    true_cams = None
    if gt and "cameras" in gt:
        true_cams = {n: Camera.from_dict(c) for n, c in gt["cameras"].items()}
        est = {im.name: c.cam_from_world for im, c in zip(images, cams, strict=True)}
        errs = align_cameras(est, {n: c.cam_from_world for n, c in true_cams.items()})
        report["metrics"] = {"poses": errs.summary(gt.get("scene_size")),
                             "frame": "aligned to the true cameras by Sim(3)"}
        sim = errs.alignment
        pts = sim.apply(pts)
        cams = [c.with_pose(sim.apply_cam_from_world(c.cam_from_world)) for c in cams]
        report["alignment_scene_from_sfm"] = sim.matrix.tolist()
    report["frame"] = "scene (aligned)" if true_cams else "SfM (arbitrary similarity)"
    write_points(tmp / "points.ply", pts, colors=cols)
    write_transforms(tmp / "transforms.json", cams,
                     [os.path.relpath(inp.image_dir / im.name, out_dir)
                      for im in images])
    return {"names": [im.name for im in images], "cameras": cams, "points": pts,
            "visible": visible}


def _true_cameras(inp) -> tuple[dict | None, dict | None]:
    gt = inp.capture.ground_truth if inp.capture is not None else None
    if gt and "cameras" in gt:
        return {n: Camera.from_dict(c) for n, c in gt["cameras"].items()}, gt
    return None, gt


def _dense_stages(st, config, inp, tmp: Path, report: dict, v: dict) -> tuple[bool, str]:
    """dense -> fuse -> mesh -> evaluate (:mod:`reconstruct.mvs.pipeline`); mesh.ply, and with
    ground truth the mesh's score."""
    from core.runs.stages import files_key
    from reconstruct.mvs.pipeline import (
        dense_report,
        depth_stage,
        fuse_stage,
        mesh_stage,
        working_colors,
    )

    t = time.perf_counter()
    names = v["names"]
    pixels: list = []

    def images():
        if not pixels:
            pixels.extend(to_uint8(read_image(inp.image_dir / n)) for n in names)
        return pixels

    mvs = config.mvs
    method_opts = asdict(mvs.patchmatch) if mvs.method == "patchmatch" else asdict(mvs.sgbm)
    depth = st.run("dense", lambda: depth_stage(names, images(), v["cameras"], v["visible"],
                                                v["points"], tmp, mvs),
                   files=["dense"], depends={"method": mvs.method, "options": method_opts})
    colors: list = []

    def working():  # the views' colours at the depth maps' size, made once for both stages
        if not colors:
            colors.extend(working_colors(depth, images()))
        return colors

    fused = st.run("fuse", lambda: fuse_stage(depth, working(), tmp, mvs),
                   files=["fused.ply"] if mvs.method == "patchmatch" else [],
                   depends={"fusion": asdict(mvs.fusion)})

    def mesh_fn():
        tm = time.perf_counter()
        mesh, surface = mesh_stage(depth, fused, working(), v["points"], tmp, mvs)
        if mesh is not None:
            mesh = sorted_mesh(_clean_mesh(mesh), recompute_normals=True)  # canonical order
            if len(mesh.triangles):
                write_mesh(tmp / "mesh.ply", mesh)
        n = 0 if mesh is None else len(mesh.triangles)
        out = {"surface": surface, "triangles": n}
        if n and fused.get("fused_points") is not None:
            out["seen_precision"] = _seen_precision(mesh, depth, fused["masks"],
                                                    mvs.fusion.seen_grow)
        return {**out, "seconds": time.perf_counter() - tm}

    meshed = st.run("mesh", mesh_fn, files=["mesh.ply"],
                    depends={"surface": mvs.surface, "fusion": asdict(mvs.fusion),
                             "voxel_fraction": mvs.voxel_fraction})
    report["dense"] = dense_report(depth, fused, meshed["surface"], None)
    report["dense"]["triangles"] = meshed["triangles"]
    report["dense"]["timings"]["mesh"] = meshed["seconds"]
    if "seen_precision" in meshed:
        report["dense"]["seen_precision"] = meshed["seen_precision"]
    report["timings"]["dense"] = time.perf_counter() - t
    if any(n in st.skipped for n in ("dense", "fuse", "mesh")):
        report["timings"]["dense"] = sum(report["dense"]["timings"].values())
    if meshed["triangles"] == 0:
        return False, "the dense surface is empty (no consistent depth in any view)"
    true_cams, gt = _true_cameras(inp)
    if true_cams and gt.get("mesh"):
        gt_mesh = inp.capture.path(gt["mesh"])
        scored = st.run("evaluate", lambda: _timed(
            _score_mesh, read_mesh(tmp / "mesh.ply"), gt_mesh, list(true_cams.values()),
            gt.get("scene_size")), depends={"gt": files_key([gt_mesh])})
        report["metrics"]["mesh"] = scored["value"]
        report["timings"]["evaluate_mesh"] = scored["seconds"]
    return True, "ok"


def _seen_precision(mesh, depth: dict, packed_masks: list, grow: int) -> dict:
    """The truth-free precision of the mesh (:func:`reconstruct.mvs.precision.seen_precision`):
    per view and on average, the share of its drawn pixels on what the view saw (its fused
    pixels, grown by ``grow``)."""
    from reconstruct.mvs.precision import seen_masks, seen_precision

    cams = depth["cameras"]
    masks = [np.unpackbits(m, count=c.width * c.height).reshape(c.height, c.width)
             .astype(bool) for m, c in zip(packed_masks, cams, strict=True)]
    sc = seen_precision(mesh, cams, seen_masks(masks, grow=grow))
    return {"mean": sc.mean_inside, "seen_covered": sc.mean_covers,
            "views": dict(zip(depth["names"], sc.inside, strict=True)),
            "definition": "share of the mesh's pixels, drawn into each working view, that "
                          "fall on the view's own fused pixels (grown by the fusion's "
                          "seen_grow, with 2 px of tolerance): what the view saw"}


def _score_mesh(mesh, gt_path: Path, true_cams: list, scene_size: float | None) -> dict:
    from reconstruct.evaluation.evaluate import evaluate

    ref = read_mesh(gt_path)
    if not scene_size:
        v = np.asarray(ref.vertices)
        scene_size = float(np.linalg.norm(v.max(0) - v.min(0)))
    tau = 0.01 * scene_size
    mask = _visible_mask(ref, true_cams, tol=0.5 * tau)
    r = evaluate(mesh, ref, tau=tau, reference_mask=mask)
    half = evaluate(mesh, ref, tau=0.5 * tau, reference_mask=mask)
    return {"tau": tau, "tau_definition": "1% of the scene's bounding-box diagonal",
            "fscore": r.fscore, "precision": r.precision, "recall": r.recall,
            "bias": r.bias, "fscore_half_tau": half.fscore,
            "accuracy_median": r.accuracy_median, "completeness_median": r.completeness_median,
            "reference": "ground-truth surface seen by at least one true camera"}
