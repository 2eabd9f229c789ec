"""Structure from motion: pycolmap sparse reconstruction on the CPU, our dense surface.

``run(config, input, out_dir)`` takes an SfM capture folder (capture.json) or a plain
folder of photos (JPEG/PNG, EXIF or not) and writes:

- ``sparse/0/`` the COLMAP model in binary, ``sparse/0/text/`` in text,
- ``points.ply`` sparse points (coloured), ``mesh.ply`` the dense surface,
- ``transforms.json`` the estimated cameras for nerfstudio tools,
- ``report.json`` counts, timings, failures and, with ground truth, the metrics.

Intrinsics: ``--camera MODEL:params`` when given; otherwise the capture's nominal
camera (what a photographer knows from EXIF: focal length, image size) as a starting
value that bundle adjustment refines; otherwise COLMAP's guess (EXIF focal length,
or 1.2 x the larger image side). ``ground_truth`` is read only to score: the Sim(3)
alignment of the cameras, pose errors, and the mesh F-score; when it exists the
dense stage works in the aligned (scene) frame so the mesh can be compared. The scene
size is the bounding-box diagonal of the ground-truth scene.
"""

from __future__ import annotations

import logging
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import cv2  # noqa: F401  (before pycolmap)
import numpy as np

from acquire.camera import Camera
from acquire.capture_io import load_capture
from acquire.nerfstudio import write_transforms
from core.config import Config, option
from core.files import atomic_dir, write_json
from core.mesh_io import read_mesh, write_mesh, write_points
from core.validate import InputError, check_choice
from reconstruct.calib_io import read_camera_yaml
from reconstruct.colmap_runner import (
    CAMERA_MODELS,
    ColmapOptions,
    camera_from_colmap,
    colmap_params_from_camera,
    image_cam_from_world,
    run_colmap,
)
from reconstruct.dense import DenseOptions, depth_maps
from reconstruct.sim3 import align_cameras

__all__ = ["SfmConfig", "SfmResult", "run", "parse_camera", "IMAGE_SUFFIXES"]

log = logging.getLogger(__name__)

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
MATCHER_CHOICES = ("auto", "exhaustive", "sequential", "spatial")


@dataclass
class SfmConfig(Config):
    """Options of the SfM pipeline (``scanamp reconstruct sfm``)."""

    camera: str | None = option(None, help="intrinsics MODEL:p1,p2,... in COLMAP's order and "
                                           "pixel convention (e.g. SIMPLE_RADIAL:800,320,240,0"
                                           "), or a camera.yaml from scanamp calibrate camera; "
                                           "default: the capture's nominal camera, else EXIF, "
                                           "else estimated")
    mapper: str = option("incremental", choices=("incremental", "global"),
                         help="pycolmap's mapper")
    matcher: str = option("auto", choices=MATCHER_CHOICES,
                          help="'auto': exhaustive up to 100 images, sequential beyond or for "
                               "a hand-held walk of more than 40")
    dense: bool = option(True, help="build the dense surface (else sparse only)")
    num_threads: int = option(-1, range="[-1, 1024]", help="threads (-1 = all cores)")
    seed: int = option(0, range="[0, inf)", help="pycolmap's random seed")
    max_features: int = option(8192, range="[100, 1000000]", help="SIFT features per image")
    voxel_fraction: float = option(1.0 / 300.0, range="(0, 1)",
                                   help="TSDF voxel edge as a fraction of the scene extent "
                                        "(robust sparse-point extent)")
    dense_options: DenseOptions = option(default_factory=DenseOptions,
                                         help="the dense stage's options")
    min_keypoints: int = option(30, range="[0, inf)",
                                help="fewer SIFT features than this marks an image "
                                     "textureless")

    def __post_init__(self):
        super().__post_init__()
        if self.camera is not None:
            parse_camera(self.camera)


@dataclass
class SfmResult:
    """Outcome of :func:`run`: ``ok`` False means the output holds a report only."""

    out_dir: Path
    ok: bool
    message: str
    report: dict


def parse_camera(text: str) -> tuple[str, str]:
    """``"MODEL:p1,p2,..."`` -> ``(model, params)``; ValueError naming what is wrong.

    A path to a camera YAML (``scanamp calibrate camera``'s output, read by
    :func:`reconstruct.calib_io.read_camera_yaml`) gives the OPENCV model from it.
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
    names = sorted(p.name for p in path.iterdir()
                   if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES)
    if not names:
        raise InputError(f"no images ({', '.join(IMAGE_SUFFIXES)}) and no capture.json",
                         path=path)
    return _Input(path, names)


def _check_images(inp: _Input) -> tuple[int, int]:
    if len(inp.names) < 3:
        raise InputError(f"structure from motion needs at least 3 images, got {len(inp.names)}",
                         path=inp.image_dir)
    sizes, bad = {}, []
    for n in inp.names:
        img = cv2.imread(str(inp.image_dir / n), cv2.IMREAD_GRAYSCALE)
        if img is None:
            bad.append(n)
            continue
        sizes.setdefault(img.shape[::-1], []).append(n)
    if bad:
        raise InputError(f"unreadable images: {', '.join(bad)}", path=inp.image_dir)
    if len(sizes) > 1:
        common = max(sizes, key=lambda s: len(sizes[s]))
        odd = [f"{n} ({w}x{h})" for (w, h), ns in sizes.items() if (w, h) != common for n in ns]
        raise InputError(f"mixed image sizes: most are {common[0]}x{common[1]}, but "
                         f"{', '.join(odd)}", path=inp.image_dir)
    return next(iter(sizes))


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

    out = {}
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


def _guessed_intrinsics_source(database: Path, width: int, height: int) -> str:
    """Where COLMAP took the focal length from when we gave none (EXIF or a guess)."""
    import pycolmap

    db = pycolmap.Database.open(str(database))
    try:
        cams = db.read_all_cameras()
    finally:
        db.close()
    if cams and cams[0].has_prior_focal_length:
        return (f"EXIF focal length ({cams[0].focal_length:.1f} px), refined by bundle "
                f"adjustment")
    return (f"no EXIF focal length: COLMAP's guess 1.2 x {max(width, height)} px, refined by "
            f"bundle adjustment")


def run(config: SfmConfig, input_path: str | os.PathLike, out_dir: str | os.PathLike,
        ) -> SfmResult:
    """Reconstruct cameras, sparse points and a dense mesh from images.

    Parameters
    ----------
    config : SfmConfig
    input_path : path
        SfM capture folder (capture.json) or a folder of JPEG/PNG images.
    out_dir : path
        Written atomically (report.json is written even when SfM fails).

    Returns
    -------
    SfmResult
        ``ok`` is False when fewer than 3 images registered or the dense surface came
        out empty: the folder then holds report.json (and the sparse model if any),
        never a mesh.

    Raises
    ------
    InputError
        Fewer than 3 images, unreadable or mixed-size images, every image textureless.
    """
    t_all = time.perf_counter()
    input_path = Path(input_path)
    inp = _resolve_input(input_path)
    t_check = time.perf_counter()
    width, height = _check_images(inp)
    t_check = time.perf_counter() - t_check
    # one-off costs of the process (open3d alone takes seconds), kept out of the stage
    # timings so that a stage is compared with the bare pycolmap calls on equal terms
    t = time.perf_counter()
    import open3d  # noqa: F401
    import pycolmap  # noqa: F401
    t_imports = time.perf_counter() - t
    t_sparse = time.perf_counter() - t_check  # the image checks belong to the sparse stage
    model, params, intr_source = _intrinsics(config, inp, width, height, input_path)
    matcher = _choose_matcher(config, inp)
    opts = ColmapOptions(camera_model=model, camera_params=params, matcher=matcher,
                         mapper=config.mapper, num_threads=config.num_threads, seed=config.seed,
                         max_features=config.max_features)
    report = {"input": str(input_path), "kind": "sfm", "num_images": len(inp.names),
              "image_size": [width, height], "intrinsics_source": intr_source,
              "colmap": {k: v for k, v in asdict(opts).items()}, "options": {
                  "mapper": config.mapper, "matcher": matcher, "dense": config.dense,
                  "seed": config.seed, "num_threads": config.num_threads}}
    with atomic_dir(out_dir) as tmp:
        work = tmp / "colmap"
        work.mkdir()
        res = run_colmap(inp.image_dir, inp.names, work, options=opts)
        rec = res.reconstruction
        report["timings"] = dict(res.timings, imports=t_imports)
        report["timings"]["pycolmap"] = sum(res.timings.values())
        if intr_source is None:
            report["intrinsics_source"] = _guessed_intrinsics_source(res.database, width, height)
        registered = sorted(im.name for im in rec.images.values() if im.has_pose) if rec else []
        failures, diagnosis = _failures(res.database, inp.names, set(registered),
                                        config.min_keypoints)
        textureless = [n for n, why in failures.items() if why.startswith("no texture")]
        if len(inp.names) - len(textureless) < 3:
            raise InputError("images with no texture (too few SIFT features): "
                             + ", ".join(textureless), path=inp.image_dir)
        report["registered"] = len(registered)
        report["registered_fraction"] = len(registered) / len(inp.names)
        report["failed_images"] = failures
        report["num_models"] = res.num_models
        ok, message = True, "ok"
        if rec is None or len(registered) < 3:
            ok = False
            message = (f"SfM did not register: {len(registered)} of {len(inp.names)} images"
                       + (f": {diagnosis}" if diagnosis else "")
                       + f" (see {Path(out_dir) / 'report.json'} for each image)")
            if diagnosis:
                report["diagnosis"] = diagnosis
        if ok:
            images, cams, pts, visible, true_cams, gt = _sparse_outputs(
                rec, inp, tmp, Path(out_dir), report)
            report["timings"]["sparse_total"] = time.perf_counter() - t_sparse
            report["timings"]["sparse_overhead"] = (report["timings"]["sparse_total"]
                                                    - report["timings"]["pycolmap"])
            if config.dense:
                ok, message = _dense(config, inp, tmp, images, cams, visible, pts, true_cams,
                                     gt, report, ok, message)
        report["timings"]["total"] = time.perf_counter() - t_all
        report["ok"], report["message"] = ok, message
        write_json(tmp / "report.json", report)
    return SfmResult(Path(out_dir), ok, message, report)


def _intrinsics(config, inp, width: int, height: int, input_path: Path):
    """COLMAP model and parameters, and where they came from: --camera (a string or a
    camera.yaml), the capture's nominal camera, else EXIF or COLMAP's guess (None)."""
    if config.camera:
        model, params = parse_camera(config.camera)
        intr_source = "--camera"
        if Path(config.camera).suffix.lower() in (".yaml", ".yml", ".xml"):
            cam = read_camera_yaml(config.camera)
            if (cam.width, cam.height) != (width, height):
                raise InputError(f"calibrated for {cam.width}x{cam.height} images, the images "
                                 f"are {width}x{height}", path=config.camera,
                                 field="image_width")
            intr_source = f"--camera {config.camera}"
    elif inp.nominal is not None:
        if (inp.nominal.width, inp.nominal.height) != (width, height):
            raise InputError(f"cameras: nominal size {inp.nominal.width}x{inp.nominal.height} "
                             f"differs from the images ({width}x{height})",
                             path=input_path / "capture.json")
        model, params = colmap_params_from_camera(inp.nominal)
        intr_source = "capture.json nominal camera (refined by bundle adjustment)"
    else:
        model, params = "SIMPLE_RADIAL", None
        intr_source = None  # EXIF or COLMAP's guess: known after extraction
    return model, params, intr_source


def _sparse_outputs(rec, inp, tmp: Path, out_dir: Path, report: dict):
    """The sparse model (binary and text), points.ply and transforms.json; with ground
    truth, everything aligned to the true cameras by Sim(3) and the pose errors."""
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
    return images, cams, pts, visible, true_cams, gt


def _dense(config, inp, tmp: Path, images, cams, visible, pts, true_cams, gt, report: dict,
           ok: bool, message: str) -> tuple[bool, str]:
    """Depth maps, TSDF fusion, mesh.ply; with ground truth, the mesh's score."""
    t = time.perf_counter()
    grays = [cv2.imread(str(inp.image_dir / im.name), cv2.IMREAD_GRAYSCALE)
             for im in images]
    colors = [cv2.imread(str(inp.image_dir / im.name))[..., ::-1] for im in images]
    depths, neighbors = depth_maps(grays, cams, visible, pts,
                                   options=config.dense_options)
    lo, hi = np.percentile(pts, [2, 98], axis=0)
    extent = float(np.linalg.norm(hi - lo))
    zmax = max(float(np.max(d)) for d in depths) if depths else 0.0
    mesh = None
    if zmax > 0:
        from reconstruct.tsdf import fuse_depth_maps

        voxel = extent * config.voxel_fraction
        mesh = fuse_depth_maps(depths, cams, voxel_size=voxel,
                               depth_max=1.5 * zmax, colors=colors)
        mesh = _clean_mesh(mesh)
        if len(mesh.triangles):
            write_mesh(tmp / "mesh.ply", mesh)
    report["timings"]["dense"] = time.perf_counter() - t
    report["dense"] = {"depth_pixels": [int((d > 0).sum()) for d in depths],
                       "stereo_partner": {
                           im.name: images[nb[0]].name if nb else None
                           for im, nb in zip(images, neighbors, strict=True)},
                       "voxel_size": extent * config.voxel_fraction,
                       "triangles": 0 if mesh is None else len(mesh.triangles)}
    if mesh is None or len(mesh.triangles) == 0:
        ok = False
        message = "the dense surface is empty (no consistent depth in any view)"
    elif true_cams and gt.get("mesh"):
        t = time.perf_counter()
        report["metrics"]["mesh"] = _score_mesh(
            mesh, inp.capture.path(gt["mesh"]), list(true_cams.values()),
            gt.get("scene_size"))
        report["timings"]["evaluate_mesh"] = time.perf_counter() - t
    return ok, message


def _score_mesh(mesh, gt_path: Path, true_cams: list, scene_size: float | None) -> dict:
    from reconstruct.evaluate import evaluate

    ref = read_mesh(gt_path)
    if not scene_size:
        v = np.asarray(ref.vertices)
        scene_size = float(np.linalg.norm(v.max(0) - v.min(0)))
    tau = 0.01 * scene_size
    mask = _visible_mask(ref, true_cams, tol=0.5 * tau)
    r = evaluate(mesh, ref, tau=tau, reference_mask=mask)
    return {"tau": tau, "tau_definition": "1% of the scene's bounding-box diagonal",
            "fscore": r.fscore, "precision": r.precision, "recall": r.recall,
            "accuracy_median": r.accuracy_median, "completeness_median": r.completeness_median,
            "reference": "ground-truth surface seen by at least one true camera"}
