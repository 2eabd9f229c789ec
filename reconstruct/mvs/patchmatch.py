"""PatchMatch multi-view stereo on the CPU: a depth, a normal and a confidence per pixel.

The method is Gipuma/ACMM's, on the CPU (the kernels are
:mod:`reconstruct.mvs._patchmatch_kernels`, compiled and parallel over image rows):

1. every view is resized so that its longer side is at most ``max_image_size`` and
   undistorted (:func:`prepare_views`);
2. each view gets its source views (:func:`reconstruct.mvs.dense.select_neighbors`: shared
   sparse points at a useful triangulation angle) and a depth range (its sparse points'
   depths, widened);
3. planes are initialised by ``coarse_iterations`` iterations of this step at half
   resolution, upsampled (with 0: at random in that range) and improved by red-black
   propagation and random refinement against a bilateral-weighted NCC aggregated over
   the ``top_k`` best source views (``iterations``; the first ``full_iterations`` of
   them against every source, the first ``random_iterations`` with a random plane too,
   at either resolution);
4. then, with every view's depth map from step 3, ``geom_iterations`` more iterations
   add geometric consistency: the forward-backward reprojection error through each
   source's depth map;
5. a second pass over the holes of confirmed surfaces (``holes``, :func:`fill_holes`, as
   COLMAP's and OpenMVS's geometric-consistency passes): pixels without a depth that
   another view confirms, surrounded by confirmed depths of one surface, try only
   those neighbours' planes, scored with geometric consistency against every view's
   final depth map, and keep one only below a stricter cost (``holes.max_cost``,
   against ``holes.top_k`` views).

A pixel keeps its depth when its final cost is below ``max_cost``; its confidence is
``1 - cost`` (the mean NCC of its best views, less the geometric penalty).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from acquire.camera import Camera
from core.config import Config, option
from core.progress import track

__all__ = ["PatchMatchOptions", "HoleOptions", "View", "DepthMap", "prepare_views",
           "depth_range", "patchmatch", "fill_holes"]

log = logging.getLogger(__name__)


@dataclass
class HoleOptions(Config):
    """Options of the second PatchMatch pass over the holes of confirmed surfaces."""

    iterations: int = option(1, range="[0, 20]",
                             help="iterations of the second pass over the holes of confirmed "
                                  "surfaces (0: no second pass)")
    radius: int = option(8, unit="px", range="[1, 64]",
                         help="a pixel without a confirmed depth is a hole when a confirmed "
                              "depth lies within this many pixels; its seeds are the nearest "
                              "confirmed depths in the 8 directions within this distance")
    min_dirs: int = option(5, range="[1, 8]",
                           help="a hole is re-estimated only when confirmed depths lie within "
                                "the radius in at least this many of the 8 directions (it is "
                                "surrounded: not the edge of a surface)")
    max_spread: float = option(0.03, range="[0, inf)",
                               help="a hole is re-estimated only when its seeds lie on one "
                                    "surface: their planes give its ray depths within this "
                                    "fraction of each other (else it is an occlusion)")
    top_k: int = option(2, range="[1, 16]",
                        help="a hole's cost is the mean of its top_k best source views (a "
                             "hole's depth must be seen by more views than a first depth)")
    max_cost: float = option(0.5, range="(0, 2]",
                             help="a hole keeps its new depth when its cost is below this")


@dataclass
class PatchMatchOptions(Config):
    """Options of PatchMatch multi-view stereo."""

    max_image_size: int = option(640, unit="px", range="[64, 20000]",
                                 help="longer image side the depth maps are computed at "
                                      "(the default suits 2 cores)")
    num_sources: int = option(5, range="[1, 16]", help="source views per reference view")
    top_k: int = option(1, range="[1, 16]",
                        help="the cost of a plane is the mean of its top_k best source "
                             "views")
    iterations: int = option(1, range="[1, 20]",
                             help="photometric iterations (at full resolution)")
    coarse_iterations: int = option(3, range="[0, 20]",
                                    help="photometric iterations at half resolution whose "
                                         "planes, upsampled, start the full-resolution "
                                         "ones (0: they start from random planes, and "
                                         "want iterations 3)")
    geom_iterations: int = option(1, range="[0, 20]",
                                  help="iterations with geometric consistency (a second one "
                                       "costs a third of the depth maps' time and moved no "
                                       "target: docs/sfm.md)")
    active_sources: int = option(3, range="[0, 16]",
                                 help="after the first full_iterations photometric "
                                      "iterations, a pixel's planes are scored only against "
                                      "the active_sources views that matched its best plane "
                                      "best (and a neighbour's plane against the "
                                      "neighbour's too); 0: always every source")
    full_iterations: int = option(1, range="[1, 20]",
                                  help="photometric iterations that score every plane "
                                       "against every source view")
    random_iterations: int = option(1, range="[0, 20]",
                                    help="photometric iterations whose refinement also "
                                         "tries a random plane per pixel (after the first "
                                         "it wins for under 0.5 % of the pixels)")
    window_radius: int = option(4, unit="px", range="[1, 15]", help="matching window radius")
    window_step: int = option(2, unit="px", range="[1, 5]",
                              help="the window is sampled every window_step pixels")
    sigma_color: float = option(0.2, range="(0, inf)",
                                help="bilateral weight: grey-level scale (images in [0, 1])")
    geom_weight: float = option(0.2, range="[0, inf)",
                                help="weight of the reprojection error (px) in the cost")
    max_reprojection: float = option(3.0, unit="px", range="(0, inf)",
                                     help="reprojection errors are clipped here")
    max_cost: float = option(0.9, range="(0, 2]",
                             help="a pixel keeps its depth when its cost is below this")
    min_texture: float = option(0.005, range="[0, 1)",
                                help="windows whose grey-level std is below this have no "
                                     "depth")
    depth_margin: float = option(0.3, range="[0, 10]",
                                 help="a view's depth range: its sparse points' widened "
                                      "by this fraction")
    min_angle_deg: float = option(2.0, unit="deg", range="[0, 90]",
                                  help="smallest useful triangulation angle with a source")
    max_angle_deg: float = option(45.0, unit="deg", range="(0, 90]",
                                  help="largest useful triangulation angle with a source")
    seed: int = option(0, range="[0, inf)", help="seed of the random planes")
    holes: HoleOptions = option(default_factory=HoleOptions,
                                help="the second pass over the holes of confirmed surfaces")


@dataclass
class View:
    """A view at the working resolution: undistorted grey image in [0, 1], colours,
    the pinhole camera of those pixels, and its depth range."""

    name: str
    gray: np.ndarray
    color: np.ndarray
    camera: Camera
    depth_range: tuple = (0.0, 0.0)


@dataclass
class DepthMap:
    """PatchMatch's result for one view (0 depth = none)."""

    depth: np.ndarray
    normal: np.ndarray
    confidence: np.ndarray
    sources: list = field(default_factory=list)
    raw_depth: np.ndarray | None = None  # every pixel's best plane, before the cost cut

    @property
    def coverage(self) -> float:
        return float((self.depth > 0).mean())


def prepare_views(names: Sequence[str], images: Sequence[np.ndarray],
                  cameras: Sequence[Camera], max_image_size: int) -> list[View]:
    """Resize (area) and undistort each image; cameras scaled to match, distortion 0."""
    views = []
    for name, img, cam in zip(names, images, cameras, strict=True):
        if img.shape[:2] != (cam.height, cam.width):
            raise ValueError(f"{name}: image is {img.shape[1]}x{img.shape[0]}, its camera "
                             f"{cam.width}x{cam.height}")
        s = min(1.0, max_image_size / max(cam.width, cam.height))
        w, h = max(1, round(cam.width * s)), max(1, round(cam.height * s))
        sx, sy = w / cam.width, h / cam.height
        small = cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA) if s < 1 else img
        K = np.array([[cam.fx * sx, 0, (cam.cx + 0.5) * sx - 0.5],
                      [0, cam.fy * sy, (cam.cy + 0.5) * sy - 0.5], [0, 0, 1]])
        if np.any(cam.dist):
            small = cv2.undistort(small, K, cam.dist, None, K)
        rgb = small if small.ndim == 3 else np.repeat(small[..., None], 3, axis=2)
        gray = cv2.cvtColor(rgb[..., :3], cv2.COLOR_RGB2GRAY).astype(np.float32) / 255.0
        views.append(View(name, gray, rgb[..., :3].copy(),
                          Camera(w, h, K[0, 0], K[1, 1], K[0, 2], K[1, 2], np.zeros(5),
                                 cam.cam_from_world)))
    return views


def depth_range(camera: Camera, points: np.ndarray, visible: np.ndarray,
                margin: float) -> tuple[float, float]:
    """Depths of a view's sparse points, from the 1st percentile to the farthest, widened
    by ``margin`` (near / (1 + margin), far * (1 + margin)); all points in front of the
    view when it sees fewer than 10. Planes are drawn uniformly in inverse depth, so a
    far bound set by a distant background costs the near surfaces little."""
    pts = points[visible] if len(visible) >= 10 else points
    z = camera.to_camera(pts)[:, 2]
    z = z[z > 0]
    if len(z) == 0:
        return 0.0, 0.0
    lo = np.percentile(z, 1) if len(z) >= 10 else z.min()
    return float(lo / (1 + margin)), float(z.max() * (1 + margin))


def _relative(ref: Camera, src: Camera) -> tuple[np.ndarray, np.ndarray]:
    T = src.cam_from_world @ ref.world_from_cam
    return T[:3, :3], T[:3, 3]


def homography_parts(kr: np.ndarray, ks: np.ndarray, rs: np.ndarray,
                     ts: np.ndarray) -> np.ndarray:
    """(n_sources, 12): K_s R K_r^-1 (row by row) and K_s t of each source, the parts of
    every plane's homography K_s (R + t n^T / dp) K_r^-1 that do not depend on the plane."""
    kinv = np.linalg.inv(kr)
    m = np.einsum("sij,sjk,kl->sil", ks, rs, kinv).reshape(len(ks), 9)
    return np.ascontiguousarray(np.hstack([m, np.einsum("sij,sj->si", ks, ts)]))


def _stack(views: Sequence[View], idx: Sequence[int], maps=None):
    hm = max(views[i].camera.height for i in idx)
    wm = max(views[i].camera.width for i in idx)
    img = np.zeros((len(idx), hm, wm), np.float32)
    dep = np.zeros((len(idx), hm, wm), np.float32)
    sizes = np.zeros((len(idx), 2), np.int64)
    for k, i in enumerate(idx):
        c = views[i].camera
        img[k, :c.height, :c.width] = views[i].gray
        sizes[k] = (c.width, c.height)
        if maps is not None and maps[i] is not None:
            dep[k, :c.height, :c.width] = maps[i].raw_depth
    return img, dep, sizes


def _half(views: Sequence[View], idx: Sequence[int]) -> list[View]:
    """``views`` with those of ``idx`` at half resolution (area), cameras to match."""
    out = list(views)
    for j in idx:
        c = views[j].camera
        w, h = (c.width + 1) // 2, (c.height + 1) // 2
        sx, sy = w / c.width, h / c.height
        gray = cv2.resize(views[j].gray, (w, h), interpolation=cv2.INTER_AREA)
        cam = Camera(w, h, c.fx * sx, c.fy * sy, (c.cx + 0.5) * sx - 0.5,
                     (c.cy + 0.5) * sy - 0.5, np.zeros(5), c.cam_from_world)
        out[j] = View(views[j].name, gray, views[j].color, cam, views[j].depth_range)
    return out


def _view_geometry(i: int, views: Sequence[View], sources: Sequence[int],
                   opt: PatchMatchOptions):
    """What the kernels need of view i and its sources: K, K^-1, the sources' K, the
    relative rotations and translations, the window weights and statistics, and the
    homographies' per-source parts."""
    from reconstruct.mvs import _patchmatch_kernels as pk

    v = views[i]
    kr = v.camera.K
    kinv = np.linalg.inv(kr)
    ks = np.stack([views[j].camera.K for j in sources])
    rel = [_relative(v.camera, views[j].camera) for j in sources]
    rs = np.stack([r for r, _ in rel])
    ts = np.stack([t for _, t in rel])
    wts, stats = pk.bilateral_weights(v.gray, opt.window_radius, opt.window_step,
                                      opt.sigma_color, float(opt.window_radius))
    return kr, kinv, ks, rs, ts, wts, stats, homography_parts(kr, ks, rs, ts)


def _run_view(i: int, views: Sequence[View], sources: Sequence[int], opt: PatchMatchOptions,
              init: DepthMap | None, maps) -> DepthMap:
    from reconstruct.mvs import _patchmatch_kernels as pk

    v = views[i]
    cam = v.camera
    dmin, dmax = v.depth_range
    h, w = cam.height, cam.width
    if not sources or dmax <= 0:
        zero = np.zeros((h, w), np.float32)
        return DepthMap(zero, np.zeros((h, w, 3), np.float32), zero, [], zero)
    kr, kinv, ks, rs, ts, wts, stats, hm = _view_geometry(i, views, sources, opt)
    src, sdepth, sizes = _stack(views, sources, maps)
    geom = opt.geom_weight if maps is not None else 0.0
    min_var = opt.min_texture ** 2
    seed = opt.seed * 1_000_003 + i
    D = np.zeros((h, w))
    N = np.zeros((h, w, 3))
    C = np.zeros((h, w))
    coarse = init is None and opt.coarse_iterations > 0
    if coarse:  # planes from half resolution, each pixel taking its coarse pixel's
        small = _run_view(i, _half(views, [i, *sources]), sources,
                          replace(opt, iterations=opt.coarse_iterations, coarse_iterations=0),
                          None, None)
        D[:] = cv2.resize(small.raw_depth, (w, h), interpolation=cv2.INTER_NEAREST)
        N[:] = cv2.resize(small.normal, (w, h), interpolation=cv2.INTER_NEAREST)
        N[np.linalg.norm(N, axis=2) < 0.5] = (0.0, 0.0, -1.0)
        iters, p0 = opt.iterations, 0.05
    elif init is None:
        pk.initialise(D, N, dmin, dmax, kinv, seed)
        iters, p0 = opt.iterations, 0.25
    else:
        D[:] = np.where(init.depth > 0, init.depth, 0.5 * (dmin + dmax))
        N[:] = init.normal
        bad = np.linalg.norm(N, axis=2) < 0.5
        N[bad] = (0.0, 0.0, -1.0)
        iters, p0 = opt.geom_iterations, 0.05
    args = (v.gray, wts, stats, src, sizes, kinv, kr, ks, rs, ts, hm,
            opt.window_radius, opt.window_step, min_var, opt.top_k, geom, sdepth,
            opt.max_reprojection)
    S = np.zeros((h, w), np.int64)  # each pixel's active sources (bits)
    nact = opt.active_sources if opt.active_sources < len(sources) else 0
    pk.final_costs(D, N, C, S, nact, *args)
    for it in range(iters):
        perturb = max(p0 * 0.5 ** it, 0.01)
        full = nact == 0 or (init is None and it < opt.full_iterations)
        for colour in (0, 1):
            pk.sweep(colour, 1 + 2 * it + colour, seed, D, N, C, S, nact, full, dmin, dmax,
                     *args, perturb, init is None and it < opt.random_iterations)
    keep = C < opt.max_cost
    depth = np.where(keep, D, 0.0).astype(np.float32)
    normal = np.where(keep[..., None], N, 0.0).astype(np.float32)
    conf = np.where(keep, np.clip(1.0 - C, 0.0, 1.0), 0.0).astype(np.float32)
    return DepthMap(depth, normal, conf, [views[j].name for j in sources],
                    D.astype(np.float32))


def patchmatch(views: Sequence[View], sources: Sequence[Sequence[int]],
               options: PatchMatchOptions | None = None,
               fusion=None) -> tuple[list[DepthMap], dict]:
    """Depth, normal and confidence maps of every view, and timings.

    Parameters
    ----------
    views : sequence of View
        From :func:`prepare_views`, with their depth ranges set.
    sources : sequence of sequence of int
        Source views of each view (indices into ``views``); a view without sources, or
        without a depth range, gets an empty map.
    fusion : FusionOptions, optional
        The fusion's agreement tests, which say which depths are confirmed for the second
        pass over the holes (:func:`fill_holes`; ``options.holes.iterations`` > 0).
    """
    opt = options or PatchMatchOptions()
    t = time.perf_counter()
    first: list = [None] * len(views)
    for i in track(range(len(views)), "PatchMatch (photometric)", total=len(views)):
        first[i] = _run_view(i, views, sources[i], opt, None, None)
    timings = {"photometric": time.perf_counter() - t}
    if opt.geom_iterations == 0:
        return first, timings
    t = time.perf_counter()
    out = []
    for i in track(range(len(views)), "PatchMatch (geometric)", total=len(views)):
        out.append(_run_view(i, views, sources[i], opt, first[i], first))
    timings["geometric"] = time.perf_counter() - t
    if opt.holes.iterations > 0:
        t, cpu = time.perf_counter(), time.process_time()
        out, st = fill_holes(views, sources, out, opt, fusion)
        timings["holes"] = time.perf_counter() - t
        timings["holes_cpu"] = time.process_time() - cpu
        log.info("PatchMatch holes: %d hole pixels, %d given a depth, %d unconfirmed depths "
                 "replaced (%.1f s)", st["holes"], st["filled"], st["replaced"],
                 timings["holes"])
    return out, timings


def _neighbours(sources: Sequence[Sequence[int]]) -> list[list[int]]:
    """Each view's sources and the views it is a source of (fusion's neighbours)."""
    return [sorted(set(s) | {j for j, ss in enumerate(sources) if i in ss})
            for i, s in enumerate(sources)]


def _fill_view(i: int, views: Sequence[View], sources: Sequence[int], opt: PatchMatchOptions,
               maps: Sequence[DepthMap], hole: np.ndarray, seeds: np.ndarray) -> DepthMap:
    """View i's map with its ``hole`` pixels re-estimated from the planes of its ``seeds``
    (:func:`reconstruct.mvs._patchmatch_kernels.fill_holes`), scored with geometric
    consistency against the other views' final depth maps. A hole keeps its new plane
    when its cost is below ``holes.max_cost``, else what it had."""
    from reconstruct.mvs import _patchmatch_kernels as pk

    v, m = views[i], maps[i]
    dmin, dmax = v.depth_range
    kr, kinv, ks, rs, ts, wts, stats, hm = _view_geometry(i, views, sources, opt)
    src, _, sizes = _stack(views, sources)
    sdepth = np.zeros_like(src)
    for k, j in enumerate(sources):
        c = views[j].camera
        sdepth[k, :c.height, :c.width] = maps[j].depth
    D = np.where(hole, 0.0, m.depth).astype(np.float64)
    N = np.where(hole[..., None], 0.0, m.normal).astype(np.float64)
    C = np.where(hole, np.inf, 1.0 - m.confidence).astype(np.float64)
    hole8 = hole.astype(np.uint8)
    seed8 = seeds.astype(np.uint8)
    seed = (opt.seed * 1_000_003 + i) * 7 + 5
    args = (dmin, dmax, v.gray, wts, stats, src, sizes, kinv, kr, ks, rs, ts,
            hm, opt.window_radius, opt.window_step,
            opt.min_texture ** 2, opt.holes.top_k, max(opt.geom_weight, 1e-3), sdepth,
            opt.max_reprojection)
    for it in range(opt.holes.iterations):
        perturb = max(0.05 * 0.5 ** it, 0.01)
        for colour in (0, 1):
            # seeds and holes are disjoint: the seeds' planes are never written
            pk.fill_holes(colour, it, seed, hole8, seed8, D, N, D, N, C, opt.holes.radius,
                          opt.holes.min_dirs, opt.holes.max_spread, *args, perturb)
    new = hole & (C < opt.holes.max_cost) & (D > 0)
    depth = np.where(new, D, m.depth).astype(np.float32)
    normal = np.where(new[..., None], N, m.normal).astype(np.float32)
    conf = np.where(new, np.clip(1.0 - C, 0.0, 1.0), m.confidence).astype(np.float32)
    raw = np.where(new, D, m.raw_depth if m.raw_depth is not None else m.depth)
    return DepthMap(depth, normal, conf, m.sources, raw.astype(np.float32))


def fill_holes(views: Sequence[View], sources: Sequence[Sequence[int]],
               maps: Sequence[DepthMap], options: PatchMatchOptions | None = None,
               fusion=None) -> tuple[list[DepthMap], dict]:
    """The second pass: the holes of confirmed surfaces re-estimated, as COLMAP's and
    OpenMVS's geometric-consistency passes do.

    A view's depth is confirmed where fusion would keep it (at least ``fusion.min_views``
    other views' maps agree, :func:`reconstruct.mvs.fusion.confirmed_depths`). A hole is a
    pixel without a confirmed depth (none, or one no other view agrees with) that has a
    confirmed depth within ``holes.radius`` pixels; it is re-estimated when confirmed
    depths surround it (``holes.min_dirs``) on one surface (``holes.max_spread``). Its
    candidate planes are only those of the confirmed depths around it (no random plane),
    scored photometrically and by the reprojection error through every source's depth
    map; the depths it gets then go through fusion's checks like every other. Returns the
    maps and the counts of hole pixels, of those given a depth where they had none
    (``filled``) and of those whose unconfirmed depth was replaced (``replaced``).
    """
    import cv2

    from reconstruct.mvs.fusion import confirmed_depths

    opt = options or PatchMatchOptions()
    r = opt.holes.radius
    cams = [v.camera for v in views]
    confirmed = confirmed_depths(cams, [m.depth for m in maps], [m.normal for m in maps],
                                 _neighbours(sources), fusion)
    out, stats = [], {"holes": 0, "filled": 0, "replaced": 0}
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    for i in track(range(len(views)), "PatchMatch (holes)", total=len(views)):
        conf = confirmed[i]
        hole = ~conf & (cv2.dilate(conf.astype(np.uint8), kernel) > 0)
        if not sources[i] or not hole.any() or views[i].depth_range[1] <= 0:
            out.append(maps[i])
            continue
        out.append(_fill_view(i, views, sources[i], opt, maps, hole, conf))
        stats["holes"] += int(hole.sum())
        got = hole & (out[-1].depth > 0)
        stats["filled"] += int((got & (maps[i].depth <= 0)).sum())
        stats["replaced"] += int((got & (maps[i].depth > 0)
                                  & (out[-1].depth != maps[i].depth)).sum())
    return out, stats
