"""The bare pycolmap calls of sparse structure from motion, on the CPU.

This module is deliberately thin: feature extraction, matching and mapping exactly
as pycolmap exposes them, plus the option plumbing. The SfM pipeline
(:mod:`reconstruct.sfm.pipeline`) wraps it with input checks, evaluation and the dense
stage, and the benchmark times our pipeline against :func:`run_colmap` alone.

Conventions: COLMAP puts the centre of the top-left pixel at (0.5, 0.5); OpenCV
(and scanamp) at (0, 0). :func:`reconstruct.camera_files.colmap_params_from_camera` and
:func:`reconstruct.camera_files.camera_from_colmap` convert between the two.

Determinism: with ``num_threads=1`` and a fixed ``seed`` the whole sparse stage is
deterministic. With more threads, SIFT extraction and matching stay deterministic
but RANSAC and bundle adjustment run in parallel and the poses can differ in the last
digits between runs.
"""

from __future__ import annotations

import contextlib
import logging
import time
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2  # noqa: F401  (cv2 before pycolmap: pycolmap's libpng breaks cv2.imwrite)
import numpy as np

from core.progress import track
from core.validate import check_choice
from reconstruct.camera_files import CAMERA_MODELS

__all__ = ["ColmapOptions", "ColmapResult", "run_colmap", "extract", "match", "reconstruct",
           "MATCHERS", "MAPPERS", "hold_intrinsics"]

log = logging.getLogger(__name__)

MATCHERS = ("exhaustive", "sequential", "spatial")
MAPPERS = ("incremental", "global")


@dataclass
class ColmapOptions:
    """Options of the sparse stage.

    Attributes
    ----------
    camera_model : str
        COLMAP camera model, one of :data:`CAMERA_MODELS`.
    camera_params : str or None
        Initial intrinsics in COLMAP's order and pixel convention (``"f, cx, cy, k"``);
        None lets COLMAP take the focal length from EXIF, or 1.2 x the larger image
        side without EXIF.
    matcher : str
        ``"exhaustive"``, ``"sequential"`` or ``"spatial"`` (needs ``position_priors``).
    mapper : str
        ``"incremental"`` or ``"global"`` (GLOMAP).
    num_threads : int
        Threads for every stage (-1 = all cores).
    seed : int
        Seeds COLMAP's PRNG and the mappers' RANSAC.
    max_features : int
        SIFT features per image.
    sequential_overlap : int
        Neighbours matched by the sequential matcher (plus loop closure on a ring).
    spatial_neighbors : int
        Neighbours matched by the spatial matcher.
    refine_intrinsics : bool
        False holds every camera's intrinsics where they start in the mappers' bundle
        adjustments and registrations (a calibrated camera); True refines the focal
        length and distortion from there, as COLMAP does.
    """

    camera_model: str = "SIMPLE_RADIAL"
    camera_params: str | None = None
    matcher: str = "exhaustive"
    mapper: str = "incremental"
    num_threads: int = -1
    seed: int = 0
    max_features: int = 8192
    sequential_overlap: int = 10
    spatial_neighbors: int = 12
    refine_intrinsics: bool = True

    def __post_init__(self):
        check_choice(self.camera_model, "camera_model", CAMERA_MODELS)
        check_choice(self.matcher, "matcher", MATCHERS)
        check_choice(self.mapper, "mapper", MAPPERS)
        if self.camera_params is not None:
            n = len([p for p in self.camera_params.split(",") if p.strip()])
            want = CAMERA_MODELS[self.camera_model]
            if n != len(want):
                raise ValueError(
                    f"camera_params: model {self.camera_model} expects {len(want)} values "
                    f"({', '.join(want)}), got {n} ({self.camera_params!r})")
            try:
                [float(p) for p in self.camera_params.split(",")]
            except ValueError:
                raise ValueError(f"camera_params: expected numbers separated by commas, got "
                                 f"{self.camera_params!r}") from None


@dataclass
class ColmapResult:
    """What the sparse stage produced.

    Attributes
    ----------
    reconstruction : pycolmap.Reconstruction or None
        The largest model (None when nothing registered).
    num_models : int
        How many separate models the mapper produced.
    timings : dict
        Wall seconds of ``extract``, ``match`` and ``map``.
    database : Path
    """

    reconstruction: object
    num_models: int
    timings: dict
    database: Path


@contextlib.contextmanager
def _quiet_colmap(level: int) -> Iterator[None]:
    import pycolmap

    old = pycolmap.logging.minloglevel
    pycolmap.logging.logtostderr = True  # never glog's files in the temporary directory
    # an empty destination turns glog's files off outright: pycolmap.bundle_adjustment
    # logs its INFO lines to a file in the temporary directory with the two flags above
    # set (seen with pycolmap 4.2)
    for severity in (pycolmap.logging.INFO, pycolmap.logging.WARNING, pycolmap.logging.ERROR):
        pycolmap.logging.set_log_destination(severity, "")
    pycolmap.logging.minloglevel = level
    try:
        yield
    finally:
        pycolmap.logging.minloglevel = old


def _write_position_priors(database: Path, priors: Mapping[str, Sequence[float]],
                           sigma: float) -> None:
    import pycolmap

    db = pycolmap.Database.open(str(database))
    try:
        for image in db.read_all_images():
            if image.name not in priors:
                continue
            prior = pycolmap.PosePrior(
                corr_data_id=image.data_id,
                position=np.asarray(priors[image.name], float),
                position_covariance=np.eye(3) * sigma ** 2,
                coordinate_system=pycolmap.PosePriorCoordinateSystem.CARTESIAN)
            db.write_pose_prior(prior)
    finally:
        db.close()


def _num_pose_priors(database: Path) -> int:
    import pycolmap

    db = pycolmap.Database.open(str(database))
    try:
        return db.num_pose_priors()
    finally:
        db.close()


def run_colmap(image_dir: str | Path, image_names: Sequence[str], work_dir: str | Path, *,
               options: ColmapOptions | None = None,
               position_priors: Mapping[str, Sequence[float]] | None = None,
               prior_sigma: float = 1.0, verbose: bool = False,
               cameras: Sequence[tuple[Sequence[str], str, str | None]] | None = None,
               known_poses: Mapping[str, np.ndarray] | None = None) -> ColmapResult:
    """Extract SIFT, match and map with pycolmap on the CPU.

    Parameters
    ----------
    image_dir : path
        Folder of the images.
    image_names : sequence of str
        Image file names relative to ``image_dir``.
    cameras : sequence of (names, model, params), optional
        One COLMAP camera per entry, shared by its images, with initial parameters
        (None: EXIF or COLMAP's guess). Default: all images one camera with
        ``options.camera_model`` and ``options.camera_params``.
    known_poses : mapping name -> (4, 4) cam_from_world, optional
        Poses known beforehand (a calibrated rig, a turntable): the mapper is replaced by
        triangulation with these poses and the given intrinsics held fixed, so
        ``reconstruction`` holds exactly these cameras and the points they see.
    work_dir : path
        Existing folder; receives ``database.db`` and the mapper's ``sparse/`` models.
    options : ColmapOptions
    position_priors : mapping name -> (3,) float, optional
        Camera-centre priors (GPS-like) for the spatial matcher, added to those COLMAP
        reads from EXIF GPS tags.
    prior_sigma : float
        Standard deviation of the priors, in their units.
    verbose : bool
        Let COLMAP log at INFO level (default: errors only).

    Returns
    -------
    ColmapResult

    Raises
    ------
    ValueError
        ``matcher='spatial'`` and no image has a position prior.
    """
    opt = options or ColmapOptions()
    work_dir = Path(work_dir)
    database = work_dir / "database.db"
    database.unlink(missing_ok=True)
    if cameras is None:
        cameras = [(list(image_names), opt.camera_model, opt.camera_params)]
    last = "map" if known_poses is None else "triangulate"
    steps = (("extract", lambda: extract(database, image_dir, cameras, opt,
                                         position_priors=position_priors,
                                         prior_sigma=prior_sigma, verbose=verbose)),
             ("match", lambda: match(database, opt, verbose=verbose)),
             (last, lambda: reconstruct(database, image_dir, work_dir / "sparse", opt,
                                        known_poses=known_poses, verbose=verbose)))
    timings, out = {}, (None, 0)
    for name, fn in track(steps, f"sparse SfM (pycolmap: extract, match, {last})",
                          total=len(steps)):
        t = time.perf_counter()
        out = fn()
        timings[name] = time.perf_counter() - t
    return ColmapResult(out[0], out[1], timings, database)


def extract(database: str | Path, image_dir: str | Path,
            cameras: Sequence[tuple[Sequence[str], str, str | None]],
            options: ColmapOptions | None = None, *,
            position_priors: Mapping[str, Sequence[float]] | None = None,
            prior_sigma: float = 1.0, verbose: bool = False) -> None:
    """SIFT features of every image into a new ``database``, one camera per entry of
    ``cameras`` ``(names, model, params)`` (params None: EXIF or COLMAP's guess)."""
    import pycolmap

    opt = options or ColmapOptions()
    pycolmap.set_random_seed(int(opt.seed))
    with _quiet_colmap(0 if verbose else 2):
        _extract(opt, Path(database), image_dir, cameras, position_priors, prior_sigma)


def match(database: str | Path, options: ColmapOptions | None = None, *,
          verbose: bool = False) -> None:
    """Match the database's images by ``options.matcher``, with verified geometry."""
    import pycolmap

    opt = options or ColmapOptions()
    pycolmap.set_random_seed(int(opt.seed))
    with _quiet_colmap(0 if verbose else 2):
        _match(opt, Path(database), int(opt.seed))


def reconstruct(database: str | Path, image_dir: str | Path, sparse_dir: str | Path,
                options: ColmapOptions | None = None, *,
                known_poses: Mapping[str, np.ndarray] | None = None,
                verbose: bool = False) -> tuple[object, int]:
    """Map (or, with ``known_poses``, triangulate at those poses); the largest model
    (None when nothing registered) and how many models the mapper made."""
    import pycolmap

    opt = options or ColmapOptions()
    sparse = Path(sparse_dir)
    sparse.mkdir(parents=True, exist_ok=True)
    pycolmap.set_random_seed(int(opt.seed))
    with _quiet_colmap(0 if verbose else 2):
        if known_poses is None:
            models = _map(opt, Path(database), image_dir, sparse, int(opt.seed))
        else:
            models = _triangulate_known(Path(database), image_dir, sparse, known_poses,
                                        opt.num_threads)
    models = models or {}
    if not models:
        return None, 0
    best = max(models.values(), key=lambda r: (r.num_reg_images(), r.num_points3D()))
    return best, len(models)


def _extract_cameras(database: Path, image_dir, cameras, extraction) -> None:
    """SIFT features into ``database`` with ``extraction`` options, one extraction call
    (so one camera) per ``(names, model, params)`` entry of ``cameras``."""
    import pycolmap

    for names, model, params in cameras:
        reader = pycolmap.ImageReaderOptions()
        reader.camera_model = model
        if params is not None:
            reader.camera_params = params
        pycolmap.extract_features(str(database), str(image_dir), image_names=list(names),
                                  camera_mode=pycolmap.CameraMode.SINGLE,
                                  reader_options=reader, extraction_options=extraction,
                                  device=pycolmap.Device.cpu)


def _extract(opt, database: Path, image_dir, cameras, position_priors,
             prior_sigma: float) -> None:
    """Stage extract: SIFT features of every image into the database, one camera per
    entry of ``cameras`` (each extraction call makes its own camera)."""
    import pycolmap

    extraction = pycolmap.FeatureExtractionOptions()
    extraction.num_threads = opt.num_threads
    extraction.sift.max_num_features = opt.max_features
    _extract_cameras(database, image_dir, cameras, extraction)
    if position_priors:
        _write_position_priors(database, position_priors, prior_sigma)
    if opt.matcher == "spatial" and _num_pose_priors(database) == 0:
        raise ValueError("matcher: 'spatial' needs camera position priors (EXIF GPS or a "
                         "rig), and none of the images has one; use 'exhaustive' or "
                         "'sequential'")

def _match(opt, database: Path, seed: int) -> None:
    """Stage match: pairs by the chosen matcher, verified two-view geometry."""
    import pycolmap

    cpu = pycolmap.Device.cpu
    matching = pycolmap.FeatureMatchingOptions()
    matching.num_threads = opt.num_threads
    verification = pycolmap.TwoViewGeometryOptions()
    verification.ransac.random_seed = seed
    if opt.matcher == "exhaustive":
        pycolmap.match_exhaustive(str(database), matching_options=matching,
                                  verification_options=verification, device=cpu)
    elif opt.matcher == "sequential":
        pairing = pycolmap.SequentialPairingOptions()
        pairing.overlap = opt.sequential_overlap
        pairing.quadratic_overlap = True
        pairing.num_threads = opt.num_threads
        pycolmap.match_sequential(str(database), matching_options=matching,
                                  pairing_options=pairing, verification_options=verification,
                                  device=cpu)
    else:
        pairing = pycolmap.SpatialPairingOptions()
        pairing.ignore_z = False
        pairing.max_num_neighbors = opt.spatial_neighbors
        pairing.max_distance = 1e30
        pairing.num_threads = opt.num_threads
        pycolmap.match_spatial(str(database), matching_options=matching,
                               pairing_options=pairing, verification_options=verification,
                               device=cpu)

def hold_intrinsics(mapper_options, opt: ColmapOptions) -> None:
    """With ``opt.refine_intrinsics`` False, the incremental mapper's options hold the
    cameras' focal length and distortion (bundle adjustment and registration)."""
    if not opt.refine_intrinsics:
        mapper_options.ba_refine_focal_length = False
        mapper_options.ba_refine_extra_params = False
        mapper_options.mapper.abs_pose_refine_focal_length = False
        mapper_options.mapper.abs_pose_refine_extra_params = False


def _map(opt, database: Path, image_dir, sparse: Path, seed: int):
    """Stage map: the incremental or global mapper; the models it found."""
    import pycolmap

    if opt.mapper == "incremental":
        mopt = pycolmap.IncrementalPipelineOptions()
        mopt.num_threads = opt.num_threads
        mopt.random_seed = seed
        mopt.mapper.random_seed = seed
        mopt.mapper.num_threads = opt.num_threads
        hold_intrinsics(mopt, opt)
        return pycolmap.incremental_mapping(str(database), str(image_dir), str(sparse),
                                            options=mopt)
    mopt = pycolmap.GlobalPipelineOptions()
    mopt.num_threads = opt.num_threads
    mopt.random_seed = seed
    mopt.mapper.num_threads = opt.num_threads
    mopt.mapper.random_seed = seed
    mopt.mapper.rotation_averaging.random_seed = seed
    mopt.mapper.global_positioning.random_seed = seed
    mopt.mapper.global_positioning.use_gpu = False
    mopt.mapper.bundle_adjustment.ceres.use_gpu = False
    if not opt.refine_intrinsics:
        mopt.mapper.bundle_adjustment.refine_focal_length = False
        mopt.mapper.bundle_adjustment.refine_extra_params = False
    return pycolmap.global_mapping(str(database), str(image_dir), str(sparse), options=mopt)


def _triangulate_known(database: Path, image_dir, sparse: Path, known_poses, num_threads):
    """Stage triangulate: the database's cameras at the known poses (written as a COLMAP
    text model, which gives each image its rig and frame), then COLMAP's triangulation
    with poses and intrinsics fixed. Images without a known pose stay out."""
    import pycolmap

    db = pycolmap.Database.open(str(database))
    try:
        cams, images = db.read_all_cameras(), db.read_all_images()
    finally:
        db.close()
    known = sparse / "known"
    known.mkdir(parents=True, exist_ok=True)
    lines = [f"{c.camera_id} {c.model.name} {c.width} {c.height} "
             + " ".join(repr(float(v)) for v in c.params) for c in cams]
    (known / "cameras.txt").write_text("\n".join(lines) + "\n")
    lines = []
    for im in images:
        if im.name not in known_poses:  # left out of the model
            continue
        T = np.asarray(known_poses[im.name], float)
        q = pycolmap.Rotation3d(T[:3, :3]).quat  # x, y, z, w
        pose = " ".join(f"{float(v):.17g}" for v in (q[3], q[0], q[1], q[2], *T[:3, 3]))
        lines.append(f"{im.image_id} {pose} {im.camera_id} {im.name}\n\n")
    (known / "images.txt").write_text("".join(lines))
    (known / "points3D.txt").write_text("")
    rec = pycolmap.Reconstruction(str(known))
    out = sparse / "0"
    out.mkdir(exist_ok=True)
    options = pycolmap.IncrementalPipelineOptions()
    options.num_threads = num_threads
    rec = pycolmap.triangulate_points(rec, str(database), str(image_dir), str(out),
                                      options=options, refine_intrinsics=False)
    return {0: rec}
