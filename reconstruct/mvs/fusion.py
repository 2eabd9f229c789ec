"""Depth maps -> fused points -> a surface that never balloons beyond what was seen.

:func:`fuse_points` keeps a pixel's point only where at least ``min_views`` other views
agree with it after reprojection: their depth map, at the pixel the point projects
to, gives back a point that reprojects within ``max_reprojection`` px, at a depth within
``depth_tol`` (relative; or, with ``disparity_tol``, within the depth change that many
pixels of disparity make for that pair, :func:`depth_per_pixel`: the depth's own
uncertainty), with a normal within ``max_normal_deg``. Depths within ``edge_erosion`` px
of an edge of a depth map are not fused: a gap (of at least ``hole_area`` pixels) or a
depth step (``edge_jump``), :func:`depth_edges`. Each kept point carries its normal,
colour and the number of views that saw it (its visibility).

:func:`poisson_surface` meshes the fused points (screened Poisson, open3d) and trims it
three ways: by Poisson density (where the points were sparse), by distance to the
nearest fused point, and by visibility: a vertex that lies in front of a surface that
views saw through it (free space) is removed. With ``unseen_views`` a fourth: a fused
point or vertex that falls, in that many views, where PatchMatch found no plane at all
(:mod:`reconstruct.mvs.precision`) is removed too.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from acquire.camera import Camera
from core.config import Config, option
from core.frames import transform_points
from core.progress import track
from reconstruct.mvs.precision import pixel_lookup, seen_masks, unseen_votes

__all__ = ["FusionOptions", "FusedPoints", "fuse_points", "poisson_surface", "depth_edges",
           "depth_per_pixel", "confirmed_depths"]

log = logging.getLogger(__name__)


@dataclass
class FusionOptions(Config):
    """Options of depth-map fusion and the fused points' surface."""

    min_views: int = option(1, range="[1, 64]",
                            help="other views that must agree with a depth to keep it")
    depth_tol: float = option(0.01, range="(0, 1)", help="relative depth agreement")
    disparity_tol: float = option(0.0, unit="px", range="[0, inf)",
                                  help="depth agreement at the scale of the depth's own "
                                       "uncertainty: within the depth change this many pixels "
                                       "of disparity make for that pair of views (0: "
                                       "depth_tol, relative)")
    max_reprojection: float = option(2.0, unit="px", range="(0, inf)",
                                     help="forward-backward reprojection agreement")
    max_normal_deg: float = option(30.0, unit="deg", range="(0, 180]",
                                   help="normal agreement")
    static_match: float = option(0.0, unit="px", range="[0, inf)",
                                 help="an agreement at the same pixel does not count: the "
                                      "point falls within this many pixels of its own pixel "
                                      "along the other view's epipolar line (what a pattern "
                                      "fixed to the image makes, at any depth: a backdrop "
                                      "behind a turntable, an overlay; 0: off)")
    edge_erosion: int = option(4, unit="px", range="[0, 20]",
                               help="depths this close to the edge of a depth map's valid "
                                    "region are not fused (windows straddling an occlusion "
                                    "edge fatten the foreground)")
    edge_jump: float = option(0.0, range="[0, 1)",
                              help="a depth step is an edge too: 4-neighbours whose depths "
                                   "differ by more than this fraction (0: gaps only)")
    hole_area: int = option(0, unit="px", range="[0, inf)",
                            help="gaps in a depth map smaller than this are holes in a "
                                 "surface, not edges (0: every gap is an edge)")
    poisson_depth: int = option(0, range="[0, 12]",
                                help="screened Poisson octree depth; 0 chooses it: cells "
                                     "of about two pixel footprints (median depth / focal "
                                     "length), depth 8 to 11")
    density_quantile: float = option(0.05, range="[0, 1)",
                                     help="Poisson vertices below this quantile of the "
                                          "density are trimmed")
    free_space: str = option("confirmed", choices=("confirmed", "all"),
                             help="which depths say that views saw through a Poisson vertex "
                                  "(it is then trimmed): those fusion kept (another view "
                                  "agrees), or every depth of the maps (an unconfirmed depth "
                                  "behind the surface cut real parts off the mesh)")
    max_distance: float = option(2.0, range="(0, inf)",
                                 help="vertices farther than this many Poisson cells (the "
                                      "octree's finest, or the points' median spacing if "
                                      "larger) from a fused point are trimmed")
    unseen_views: int = option(0, range="[0, 64]",
                               help="a fused point or Poisson vertex that falls, in at least "
                                    "this many views, on pixels where PatchMatch found no "
                                    "plane at all (the view looked through it at nothing it "
                                    "could match) is dropped (0: off)")
    seen_grow: int = option(3, unit="px", range="[0, 20]",
                            help="what a view saw: its pixels with a depth (for the "
                                 "truth-free precision: with a fused depth) grown by this "
                                 "many pixels")


@dataclass
class FusedPoints:
    """Fused points in the world frame, and which pixels of each view they came from."""

    points: np.ndarray
    normals: np.ndarray
    colors: np.ndarray
    visibility: np.ndarray
    masks: list

    @property
    def coverage(self) -> list[float]:
        """Fraction of each view's pixels that carry a fused depth."""
        return [float(m.mean()) for m in self.masks]


def depth_edges(depth: np.ndarray, *, jump: float, hole_area: int) -> np.ndarray:
    """Where a depth map has an edge: (H, W) bool, True at the pixels on either side of a
    depth step (4-neighbours whose depths differ by more than ``jump``, relative; 0 = no
    step is an edge) and at the pixels of gaps of at least ``hole_area`` pixels (0 = every
    gap). A smaller gap is a hole in a surface, not an edge.

    >>> d = np.ones((5, 8)); d[2, 2] = 0; d[:, 5:] = 2.0
    >>> depth_edges(d, jump=0.03, hole_area=4).astype(int)[2]
    array([0, 0, 0, 0, 1, 1, 0, 0])
    """
    import cv2

    valid = depth > 0
    edge = np.zeros(depth.shape, bool)
    if jump > 0:
        for a, b in (((slice(None), slice(1, None)), (slice(None), slice(None, -1))),
                     ((slice(1, None), slice(None)), (slice(None, -1), slice(None)))):
            da, db = depth[a], depth[b]
            step = valid[a] & valid[b] & (np.abs(da - db) > jump * np.minimum(da, db))
            edge[a] |= step
            edge[b] |= step
    gaps = ~valid
    if hole_area > 0 and gaps.any():
        n, lab, stats, _ = cv2.connectedComponentsWithStats(gaps.astype(np.uint8),
                                                            connectivity=8)
        gaps &= (stats[:, cv2.CC_STAT_AREA] >= hole_area)[lab]
    return edge | gaps


def _backproject(cam: Camera, depth: np.ndarray, erosion: int = 0, *, jump: float = 0.0,
                 hole_area: int = 0):
    valid = depth > 0
    if erosion > 0:
        import cv2

        edge = depth_edges(depth, jump=jump, hole_area=hole_area)
        valid &= ~cv2.dilate(edge.astype(np.uint8), np.ones((3, 3), np.uint8),
                             iterations=erosion).astype(bool)
    v, u = np.nonzero(valid)
    z = depth[v, u].astype(np.float64)
    x = (u - cam.cx) / cam.fx * z
    y = (v - cam.cy) / cam.fy * z
    pc = np.stack([x, y, z], 1)
    return u, v, pc


def depth_per_pixel(cam: Camera, points: np.ndarray, rays: np.ndarray) -> np.ndarray:
    """The depth change along ``rays`` that moves ``points`` one pixel in ``cam``: the
    depth uncertainty of one pixel of disparity for that pair of views.

    ``points`` (n, 3) world, ``rays`` (n, 3) world directions scaled so that a step of
    1 along them is a step of 1 in the depth being judged. For two pinhole cameras of
    focal length f side by side at baseline b it is z^2 / (f b).
    """
    R = cam.cam_from_world[:3, :3]
    Y = transform_points(cam.cam_from_world, points)
    B = rays @ R.T
    z2 = np.maximum(Y[:, 2], 1e-12) ** 2
    du = cam.fx * (B[:, 0] * Y[:, 2] - Y[:, 0] * B[:, 2]) / z2
    dv = cam.fy * (B[:, 1] * Y[:, 2] - Y[:, 1] * B[:, 2]) / z2
    return 1.0 / np.maximum(np.hypot(du, dv), 1e-12)


def fuse_points(cameras: Sequence[Camera], depths: Sequence[np.ndarray],
                normals: Sequence[np.ndarray], colors: Sequence[np.ndarray],
                neighbours: Sequence[Sequence[int]],
                options: FusionOptions | None = None) -> FusedPoints:
    """Points of every view kept where ``min_views`` of its ``neighbours`` agree.

    ``cameras`` are pinhole (no distortion) at the depth maps' resolution; ``normals``
    are in each camera's frame; ``colors`` (H, W, 3) uint8.
    """
    opt = options or FusionOptions()
    cos_max = np.cos(np.radians(opt.max_normal_deg))
    P, Nn, Cc, V, masks = [], [], [], [], []
    for i in track(range(len(cameras)), "fusion", total=len(cameras)):
        cam = cameras[i]
        u, v, pc = _backproject(cam, depths[i], opt.edge_erosion, jump=opt.edge_jump,
                                hole_area=opt.hole_area)
        R_wc = cam.world_from_cam[:3, :3]
        X = pc @ R_wc.T + cam.world_from_cam[:3, 3]
        n_ref = normals[i][v, u].astype(np.float64) @ R_wc.T
        if opt.disparity_tol == 0:  # the same test, compiled, over the whole map
            count = _agree_counts(i, cameras, depths, normals, neighbours[i], opt,
                                  cos_max, opt.static_match)[v, u]
        else:
            count = np.zeros(len(u), np.int32)
            for j in neighbours[i]:
                if j != i:
                    count += _agree(X, n_ref, u, v, cam, cameras[j], depths[j], normals[j],
                                    opt, cos_max, opt.static_match)
        keep = count >= opt.min_views
        mask = np.zeros(depths[i].shape, bool)
        mask[v[keep], u[keep]] = True
        masks.append(mask)
        P.append(X[keep])
        Nn.append(n_ref[keep])
        Cc.append(colors[i][v[keep], u[keep], :3].astype(np.float64) / 255.0)
        V.append(count[keep] + 1)
    def cat(a, d):
        return np.concatenate(a) if a else np.zeros((0, d))

    return FusedPoints(cat(P, 3), cat(Nn, 3), cat(Cc, 3),
                       np.concatenate(V) if V else np.zeros(0, np.int32), masks)


def confirmed_depths(cameras: Sequence[Camera], depths: Sequence[np.ndarray],
                     normals: Sequence[np.ndarray], neighbours: Sequence[Sequence[int]],
                     options: FusionOptions | None = None) -> list[np.ndarray]:
    """(H, W) bool per view: the depths :func:`fuse_points` would keep before its edge
    erosion (at least ``min_views`` of the view's ``neighbours`` agree with them)."""
    opt = options or FusionOptions()
    cos_max = np.cos(np.radians(opt.max_normal_deg))
    out = []
    if opt.disparity_tol == 0:  # the same test, compiled
        return [_agree_counts(i, cameras, depths, normals, neighbours[i], opt, cos_max, 0.0)
                >= opt.min_views for i in range(len(cameras))]
    for i, cam in enumerate(cameras):
        u, v, pc = _backproject(cam, depths[i])
        R_wc = cam.world_from_cam[:3, :3]
        X = pc @ R_wc.T + cam.world_from_cam[:3, 3]
        n_ref = normals[i][v, u].astype(np.float64) @ R_wc.T
        count = np.zeros(len(u), np.int32)
        for j in neighbours[i]:
            if j != i:
                count += _agree(X, n_ref, u, v, cam, cameras[j], depths[j], normals[j], opt,
                                cos_max, 0.0)
        mask = np.zeros(depths[i].shape, bool)
        keep = count >= opt.min_views
        mask[v[keep], u[keep]] = True
        out.append(mask)
    return out


def _agree_counts(i: int, cameras: Sequence[Camera], depths: Sequence[np.ndarray],
                  normals: Sequence[np.ndarray], neighbours: Sequence[int], opt: FusionOptions,
                  cos_max: float, static_px: float) -> np.ndarray:
    """(H, W) int32: how many of ``neighbours`` agree with each depth of view i, by the
    test of :func:`_agree` with a relative depth tolerance, compiled
    (:func:`reconstruct.mvs._patchmatch_kernels.agree_counts`); matches at the same pixel
    (within ``static_px`` along the epipolar line, 0: off) do not count."""
    from reconstruct.mvs import _patchmatch_kernels as pk

    cam = cameras[i]
    count = np.zeros(depths[i].shape, np.int32)
    for j in neighbours:
        if j != i:
            o = cameras[j]
            pk.agree_counts(count, depths[i], normals[i], cam.K, cam.world_from_cam,
                            cam.cam_from_world, depths[j], normals[j], o.K, o.world_from_cam,
                            o.cam_from_world, opt.depth_tol, opt.max_reprojection, cos_max,
                            float(static_px))
    return count


def _agree(X, n_ref, u, v, cam: Camera, other: Camera, depth, normal, opt, cos_max,
           static_px: float = 0.0):
    """1 where ``other``'s depth map agrees with the points X of ``cam``, else 0 (and 0
    where the point falls within ``static_px`` of its own pixel along the epipolar line:
    :func:`reconstruct.mvs._patchmatch_kernels.static_offset`)."""
    out = np.zeros(len(X), np.int32)
    idx, uo, vo, z = pixel_lookup(other, X)
    d = depth[vo, uo].astype(np.float64)
    has = d > 0
    if static_px > 0:
        has &= np.abs(_static_offsets(X[idx], u[idx], v[idx], cam, other)) >= static_px
    idx, uo, vo, d = idx[has], uo[has], vo[has], d[has]
    # the other view's point at that pixel, back in the reference image
    pc = np.stack([(uo - other.cx) / other.fx * d, (vo - other.cy) / other.fy * d, d], 1)
    W = transform_points(other.world_from_cam, pc)
    Z = cam.to_camera(W)
    zr = np.maximum(Z[:, 2], 1e-12)
    pu = cam.fx * Z[:, 0] / zr + cam.cx
    pv = cam.fy * Z[:, 1] / zr + cam.cy
    err = np.hypot(pu - u[idx], pv - v[idx])
    if opt.disparity_tol > 0:  # judged at the depth change one pixel of disparity in this
        # view makes along the other view's ray
        ray = (W - other.world_from_cam[:3, 3]) / d[:, None]
        near = np.abs(z[idx] - d) <= opt.disparity_tol * depth_per_pixel(cam, W, ray)
    else:
        near = np.abs(z[idx] - d) / d <= opt.depth_tol
    n_other = normal[vo, uo].astype(np.float64) @ other.world_from_cam[:3, :3].T
    cosang = np.sum(n_other * n_ref[idx], 1)
    good = (err <= opt.max_reprojection) & near & (cosang >= cos_max)
    out[idx[good]] = 1
    return out


def _static_offsets(X: np.ndarray, u: np.ndarray, v: np.ndarray, cam: Camera,
                    other: Camera) -> np.ndarray:
    """Per point X of pixel (u, v) of ``cam``: how far (px) it falls in ``other`` from that
    same pixel along its epipolar line (the kernels' ``static_offset``, vectorised)."""
    C = cam.world_from_cam[:3, 3]

    def project(P):
        Y = other.to_camera(P)
        z = np.maximum(Y[:, 2], 1e-12)
        return other.fx * Y[:, 0] / z + other.cx, other.fy * Y[:, 1] / z + other.cy

    pu, pv = project(X)
    qu, qv = project(C + 1.01 * (X - C))
    du, dv = qu - pu, qv - pv
    n = np.hypot(du, dv)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(n > 1e-9, ((u - pu) * du + (v - pv) * dv) / n, np.inf)


def poisson_surface(fused: FusedPoints, cameras: Sequence[Camera],
                    depths: Sequence[np.ndarray], options: FusionOptions | None = None,
                    *, max_points: int = 2_000_000, seed: int = 0,
                    confirmed: Sequence[np.ndarray] | None = None):
    """Screened Poisson mesh of the fused points, trimmed by density, distance to the
    points and free space (an open3d TriangleMesh with vertex colours).

    ``confirmed`` (H, W) bool per view: the depths fusion kept; with
    ``options.free_space`` "confirmed" only those say that a view saw through a vertex
    (without them, every depth does)."""
    import open3d as o3d

    opt = options or FusionOptions()
    pts, nrm, col = fused.points, fused.normals, fused.colors
    seen = None
    if opt.unseen_views > 0:  # where PatchMatch found no plane at all (not even one
        # that no other view confirms: a faint surface still gets a depth, a backdrop not)
        seen = seen_masks([d > 0 for d in depths], grow=opt.seen_grow)
        keep = unseen_votes(pts, cameras, seen) < opt.unseen_views
        log.info("fused points that %d views or more saw nothing at: %d of %d, dropped",
                 opt.unseen_views, int((~keep).sum()), len(pts))
        pts, nrm, col = pts[keep], nrm[keep], col[keep]
    if len(pts) > max_points:  # seeded subsample keeps Poisson's memory bounded
        keep = np.sort(np.random.default_rng(seed).choice(len(pts), max_points,
                                                          replace=False))
        pts, nrm, col = pts[keep], nrm[keep], col[keep]
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    pcd.normals = o3d.utility.Vector3dVector(nrm)
    pcd.colors = o3d.utility.Vector3dVector(col)
    from scipy.spatial import cKDTree

    tree = cKDTree(pts)
    sample = np.random.default_rng(seed).choice(len(pts), min(5000, len(pts)), replace=False)
    spacing = float(np.median(tree.query(pts[sample], k=2)[0][:, 1])) if len(pts) > 1 else 0
    extent = float(np.max(np.ptp(pts, axis=0))) * 1.1  # Poisson's bounding cube
    # a pixel's footprint on the surface: the fused cloud repeats each surface once per
    # view, so its own spacing understates how finely the surface was sampled
    foot = [float(np.median(d[d > 0])) / c.fx for c, d in zip(cameras, depths, strict=True)
            if np.any(d > 0)]
    footprint = float(np.median(foot)) if foot else spacing
    depth = opt.poisson_depth or int(np.clip(np.ceil(np.log2(extent / max(2 * footprint,
                                                                        1e-12))), 8, 11))
    # PoissonRecon prints its warnings ("bad average roots") itself: to the log instead
    from core.io.mesh import native_output

    said: list[str] = []
    with native_output(said, fds=(1, 2)):
        mesh, dens = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(
            pcd, depth=depth, n_threads=1)
    if said:
        log.debug("PoissonRecon: %s", " ".join(said))
    dens = np.asarray(dens)
    if len(dens) == 0:
        return mesh
    V = np.asarray(mesh.vertices)
    drop = dens < np.quantile(dens, opt.density_quantile)
    # distance to the nearest fused point, in Poisson cells (or point spacings)
    cell = extent / 2 ** depth
    log.info("Poisson surface: %d points, octree depth %d (cell %.3g, pixel footprint %.3g)",
             len(pts), depth, cell, footprint)
    dist = tree.query(V, k=1)[0]
    drop |= dist > opt.max_distance * max(spacing, cell, 1e-12)
    if confirmed is not None and opt.free_space == "confirmed":
        depths = [np.where(m, d, 0.0) for m, d in zip(confirmed, depths, strict=True)]
    drop |= _free_space(V, cameras, depths, opt.depth_tol) >= 2
    if seen is not None:
        drop |= unseen_votes(V, cameras, seen) >= opt.unseen_views
    mesh.remove_vertices_by_mask(drop)
    mesh.remove_unreferenced_vertices()
    return mesh


def _free_space(V: np.ndarray, cameras: Sequence[Camera], depths: Sequence[np.ndarray],
                tol: float) -> np.ndarray:
    """How many views saw a surface behind each vertex (the vertex is in free space)."""
    votes = np.zeros(len(V), np.int32)
    for cam, depth in zip(cameras, depths, strict=True):
        idx, u, v, z = pixel_lookup(cam, V)
        d = depth[v, u]
        votes[idx[(d > 0) & (z[idx] < d * (1.0 - 5.0 * tol))]] += 1
    return votes
