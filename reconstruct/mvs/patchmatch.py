"""PatchMatch multi-view stereo on the CPU: a depth, a normal and a confidence per pixel.

The method is Gipuma/ACMM's, on the CPU (the kernels are
:mod:`reconstruct.mvs._patchmatch_kernels`, compiled and parallel over image rows):

1. every view is resized so that its longer side is at most ``max_image_size`` and
   undistorted (:func:`prepare_views`);
2. each view gets its source views (:func:`reconstruct.mvs.dense.select_neighbors`: shared
   sparse points at a useful triangulation angle) and a depth range (its sparse points'
   depths, widened);
3. planes are initialised at random in that range and improved by red-black
   propagation and random refinement against a bilateral-weighted NCC aggregated over
   the ``top_k`` best source views (``iterations``);
4. then, with every view's depth map from step 3, ``geom_iterations`` more iterations
   add geometric consistency: the forward-backward reprojection error through each
   source's depth map.

A pixel keeps its depth when its final cost is below ``max_cost``; its confidence is
``1 - cost`` (the mean NCC of its best views, less the geometric penalty).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np

from acquire.camera import Camera
from core.config import Config, option
from core.progress import track

__all__ = ["PatchMatchOptions", "View", "DepthMap", "prepare_views", "depth_range",
           "patchmatch", "upsample_planes"]

log = logging.getLogger(__name__)


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
    iterations: int = option(3, range="[1, 20]", help="photometric iterations")
    geom_iterations: int = option(2, range="[0, 20]",
                                  help="iterations with geometric consistency")
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
    coarse_to_fine: bool = option(True,
                                  help="the photometric iterations at half resolution, then "
                                       "fine_iterations at full resolution against the "
                                       "sources that matched there (False: every iteration "
                                       "at full resolution, against every source: the "
                                       "earlier, about 3 times slower path)")
    fine_iterations: int = option(1, range="[0, 20]",
                                  help="coarse-to-fine: photometric iterations at full "
                                       "resolution, from the upsampled half-resolution planes")
    source_margin: float = option(0.3, range="[0, 2]",
                                  help="coarse-to-fine: at full resolution a pixel is matched "
                                       "only against the sources whose half-resolution cost "
                                       "was within this of its best")
    settled_cost: float = option(0.3, range="[0, 2]",
                                 help="coarse-to-fine: a full-resolution pixel whose cost is "
                                      "below this tries only its neighbours' different planes "
                                      "and one small perturbation")


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
    raw_normal: np.ndarray | None = None
    source_mask: np.ndarray | None = None  # (H, W) int64 bits of the sources worth matching

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


def _half(v: View) -> View:
    """The view at half resolution (area average), its pinhole camera scaled to match."""
    c = v.camera
    w, h = max(1, (c.width + 1) // 2), max(1, (c.height + 1) // 2)
    sx, sy = w / c.width, h / c.height
    gray = cv2.resize(v.gray, (w, h), interpolation=cv2.INTER_AREA)
    cam = Camera(w, h, c.fx * sx, c.fy * sy, (c.cx + 0.5) * sx - 0.5, (c.cy + 0.5) * sy - 0.5,
                 np.zeros(5), c.cam_from_world)
    return View(v.name, gray, v.color, cam, v.depth_range)


def upsample_planes(depth: np.ndarray, normal: np.ndarray, coarse: Camera, fine: Camera):
    """Each fine pixel takes the plane of the coarse pixel it falls in, carried to its own
    ray (the depth where the ray meets that plane; the coarse depth where the plane is
    nearly edge-on or the carried depth is more than 10 % off).

    Returns (H, W) float64 depths, (H, W, 3) normals and the (H, W) coarse indices
    (rows, columns) each fine pixel took its plane from.
    """
    h, w = fine.height, fine.width
    ys, xs = np.mgrid[0:h, 0:w]
    xc = np.clip(np.rint((xs + 0.5) * coarse.width / w - 0.5), 0, coarse.width - 1)
    yc = np.clip(np.rint((ys + 0.5) * coarse.height / h - 0.5), 0, coarse.height - 1)
    xc, yc = xc.astype(np.int64), yc.astype(np.int64)
    dc = depth[yc, xc].astype(np.float64)
    n = normal[yc, xc].astype(np.float64)
    pc = np.stack([(xc - coarse.cx) / coarse.fx, (yc - coarse.cy) / coarse.fy,
                   np.ones_like(dc)], -1) * dc[..., None]
    ray = np.stack([(xs - fine.cx) / fine.fx, (ys - fine.cy) / fine.fy, np.ones_like(dc)], -1)
    num = np.sum(n * pc, -1)
    den = np.sum(n * ray, -1)
    d = np.divide(num, den, out=dc.copy(), where=np.abs(den) > 1e-9)
    d = np.where((d > 0) & (np.abs(d - dc) < 0.1 * dc), d, dc)
    return d, n, (yc, xc)


def _source_mask(costs: np.ndarray, margin: float) -> np.ndarray:
    """(H, W) int64 bits of the sources within ``margin`` of each pixel's best cost (all
    sources where none matched)."""
    best = costs.min(axis=2, keepdims=True)
    ok = (costs <= best + margin) & (costs < 2.0)
    ok[~ok.any(axis=2)] = True
    return np.sum(ok.astype(np.int64) << np.arange(costs.shape[2], dtype=np.int64), axis=2)


def _run_view(i: int, views: Sequence[View], sources: Sequence[int], opt: PatchMatchOptions,
              init, maps, *, iters: int, p0: float, smask=None, settled: float = -1.0,
              want_mask: bool = False) -> DepthMap:
    """PatchMatch of view ``i``: ``iters`` iterations from random planes (``init`` None) or
    from ``init`` = (depth, normal); with the sources' ``maps``, geometric consistency."""
    from reconstruct.mvs import _patchmatch_kernels as pk

    v = views[i]
    cam = v.camera
    dmin, dmax = v.depth_range
    h, w = cam.height, cam.width
    if not sources or dmax <= 0:
        zero = np.zeros((h, w), np.float32)
        return DepthMap(zero, np.zeros((h, w, 3), np.float32), zero, [], zero,
                        np.zeros((h, w, 3), np.float32))
    kr = cam.K
    kinv = np.linalg.inv(kr)
    src, sdepth, sizes = _stack(views, sources, maps)
    ks = np.stack([views[j].camera.K for j in sources])
    rel = [_relative(cam, views[j].camera) for j in sources]
    rs = np.stack([r for r, _ in rel])
    ts = np.stack([t for _, t in rel])
    wts, stats = pk.bilateral_weights(v.gray, opt.window_radius, opt.window_step,
                                      opt.sigma_color, float(opt.window_radius))
    geom = opt.geom_weight if maps is not None else 0.0
    min_var = opt.min_texture ** 2
    seed = opt.seed * 1_000_003 + i
    if smask is None:
        smask = np.full((h, w), (1 << len(sources)) - 1, np.int64)
    if init is None:
        D, N = np.zeros((h, w)), np.zeros((h, w, 3))
        pk.initialise(D, N, dmin, dmax, kinv, seed)
    else:
        D, N = np.array(init[0], np.float64), np.array(init[1], np.float64)
    C = np.zeros((h, w))
    args = (v.gray, wts, stats, src, sizes, kinv, kr, ks, rs, ts, opt.window_radius,
            opt.window_step, min_var, opt.top_k, geom, sdepth, opt.max_reprojection)
    pk.final_costs(D, N, C, *args, smask)
    for it in range(iters):
        perturb = max(p0 * 0.5 ** it, 0.01)
        for colour in (0, 1):
            pk.sweep(colour, 1 + 2 * it + colour, seed, D, N, C, dmin, dmax, *args, perturb,
                     smask, settled)
    keep = C < opt.max_cost
    depth = np.where(keep, D, 0.0).astype(np.float32)
    normal = np.where(keep[..., None], N, 0.0).astype(np.float32)
    conf = np.where(keep, np.clip(1.0 - C, 0.0, 1.0), 0.0).astype(np.float32)
    out = DepthMap(depth, normal, conf, [views[j].name for j in sources],
                   D.astype(np.float32), N.astype(np.float32))
    if want_mask:
        costs = pk.source_costs(D, N, *args[:6], *args[7:13])
        out.source_mask = _source_mask(costs, opt.source_margin)
    return out


def _restart(m: DepthMap, dmin: float, dmax: float):
    """The geometric iterations' start (the earlier path): kept planes, the others a
    fronto-parallel plane mid-range."""
    D = np.where(m.depth > 0, m.depth, 0.5 * (dmin + dmax))
    N = np.array(m.normal, np.float64)
    N[np.linalg.norm(N, axis=2) < 0.5] = (0.0, 0.0, -1.0)
    return D, N


def _fine_start(views, coarse_views, coarse: Sequence[DepthMap]):
    """Each view's full-resolution start from its half-resolution planes, and the
    sources each pixel is matched against."""
    starts = []
    for v, cv_, m in zip(views, coarse_views, coarse, strict=True):
        if not m.sources:
            starts.append(None)
            continue
        d, n, (yc, xc) = upsample_planes(m.raw_depth, m.raw_normal, cv_.camera, v.camera)
        starts.append(((d, n), m.source_mask[yc, xc]))
    return starts


def patchmatch(views: Sequence[View], sources: Sequence[Sequence[int]],
               options: PatchMatchOptions | None = None) -> tuple[list[DepthMap], dict]:
    """Depth, normal and confidence maps of every view, and timings.

    Parameters
    ----------
    views : sequence of View
        From :func:`prepare_views`, with their depth ranges set.
    sources : sequence of sequence of int
        Source views of each view (indices into ``views``); a view without sources, or
        without a depth range, gets an empty map.

    With ``coarse_to_fine`` the photometric iterations run at half resolution; their
    planes, carried to the full-resolution rays (:func:`upsample_planes`), start
    ``fine_iterations`` at full resolution, each pixel against the sources that matched
    it at half resolution (``source_margin``), settled pixels trying fewer planes
    (``settled_cost``); then the geometric iterations, likewise.
    """
    opt = options or PatchMatchOptions()
    n = len(views)
    t = time.perf_counter()
    starts: list = [None] * n
    if opt.coarse_to_fine:
        small = [_half(v) for v in views]
        coarse = [_run_view(i, small, sources[i], opt, None, None, iters=opt.iterations,
                            p0=0.25, want_mask=True)
                  for i in track(range(n), "PatchMatch (half resolution)", total=n)]
        starts = _fine_start(views, small, coarse)
        first = [_run_view(i, views, sources[i], opt, starts[i] and starts[i][0], None,
                           iters=opt.fine_iterations, p0=0.05,
                           smask=starts[i] and starts[i][1], settled=opt.settled_cost)
                 for i in track(range(n), "PatchMatch (photometric)", total=n)]
    else:
        first = [_run_view(i, views, sources[i], opt, None, None, iters=opt.iterations,
                           p0=0.25) for i in track(range(n), "PatchMatch (photometric)",
                                                   total=n)]
    timings = {"photometric": time.perf_counter() - t}
    if opt.geom_iterations == 0:
        return first, timings
    t = time.perf_counter()
    out = []
    for i in track(range(n), "PatchMatch (geometric)", total=n):
        if opt.coarse_to_fine and starts[i] is not None:
            init, mask = (first[i].raw_depth, first[i].raw_normal), starts[i][1]
            settled = opt.settled_cost
        else:
            init, mask, settled = _restart(first[i], *views[i].depth_range), None, -1.0
        out.append(_run_view(i, views, sources[i], opt, init, first, iters=opt.geom_iterations,
                             p0=0.05, smask=mask, settled=settled))
    timings["geometric"] = time.perf_counter() - t
    return out, timings
