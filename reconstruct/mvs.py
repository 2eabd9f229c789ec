"""The dense stage of structure from motion: PatchMatch depth maps, fusion, a surface,
and the files a user looks at.

:func:`dense_surface` takes the registered views (upright images and their cameras) and
the sparse points, and returns the mesh with a report. Written into the output folder:

- ``dense/NAME.depth.npy``, ``.normal.npy``, ``.confidence.npy`` (working resolution,
  float32, 0 = no depth) and ``dense/NAME.preview.png`` (depth, normal, confidence);
- ``fused.ply``: the fused points with normals and colours;
- ``dense/coverage.png``: per view, the fraction of pixels with a depth and with a
  fused depth.

Two depth-map methods: ``patchmatch`` (:mod:`reconstruct.patchmatch`) and ``sgbm``
(rectified pairs, :mod:`reconstruct.dense`), the peer it replaced. Two surfaces: the
screened Poisson surface of the fused points trimmed by density, distance and free
space (:func:`reconstruct.fusion.poisson_surface`), or a TSDF of the fused depth
maps (:func:`reconstruct.tsdf.fuse_depth_maps`), which suits renders of known
exposure; ``report["surface"]`` says which ran.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from acquire.camera import Camera
from core.config import Config, option
from core.image_io import write_image
from reconstruct.dense import DenseOptions, depth_maps, select_neighbors
from reconstruct.fusion import FusionOptions, fuse_points, poisson_surface
from reconstruct.patchmatch import PatchMatchOptions, depth_range, patchmatch, prepare_views

__all__ = ["MvsOptions", "dense_surface", "select_sources", "DENSE_METHODS", "SURFACES"]

log = logging.getLogger(__name__)

DENSE_METHODS = ("patchmatch", "sgbm")
SURFACES = ("poisson", "tsdf")


@dataclass
class MvsOptions(Config):
    """Options of the dense stage."""

    method: str = option("patchmatch", choices=DENSE_METHODS,
                         help="depth maps: PatchMatch multi-view stereo, or rectified-pair "
                              "SGBM (the earlier method)")
    surface: str = option("poisson", choices=SURFACES,
                          help="mesh of the fused points (screened Poisson, trimmed), or a "
                               "TSDF of the fused depth maps")
    voxel_fraction: float = option(1.0 / 300.0, range="(0, 1)",
                                   help="TSDF voxel edge as a fraction of the scene extent "
                                        "(robust sparse-point extent)")
    patchmatch: PatchMatchOptions = option(default_factory=PatchMatchOptions,
                                           help="PatchMatch's options")
    fusion: FusionOptions = option(default_factory=FusionOptions,
                                   help="fusion's and the Poisson surface's options")
    sgbm: DenseOptions = option(default_factory=DenseOptions,
                                help="the SGBM depth maps' options")


def select_sources(cameras: Sequence[Camera], visible: Sequence[np.ndarray],
                   points: np.ndarray, k: int, min_angle_deg: float,
                   max_angle_deg: float) -> list[list[int]]:
    """Source views of each view: by shared sparse points at a useful triangulation
    angle (:func:`reconstruct.dense.select_neighbors`), completed by the views whose
    optical axes make the angle nearest 15 degrees within the range (known cameras of
    textureless objects share few points)."""
    out = select_neighbors(cameras, visible, points, k=k, min_angle_deg=min_angle_deg,
                           max_angle_deg=max_angle_deg)
    axes = np.array([c.world_from_cam[:3, 2] for c in cameras])
    cos = np.clip(axes @ axes.T, -1.0, 1.0)
    ang = np.degrees(np.arccos(cos))
    for i, chosen in enumerate(out):
        if len(chosen) >= k:
            continue
        cand = [j for j in np.argsort(np.abs(ang[i] - 15.0))
                if j != i and j not in chosen and min_angle_deg <= ang[i, j] <= max_angle_deg]
        chosen.extend(int(j) for j in cand[:k - len(chosen)])
    return out


def _preview(depth: np.ndarray, normal: np.ndarray, conf: np.ndarray) -> np.ndarray:
    import cv2

    ok = depth > 0
    lo, hi = np.percentile(depth[ok], [2, 98]) if ok.any() else (0.0, 1.0)
    t = np.clip((depth - lo) / max(hi - lo, 1e-12), 0, 1)
    dc = cv2.applyColorMap((255 * (1 - t)).astype(np.uint8), cv2.COLORMAP_TURBO)[..., ::-1]
    nc = np.clip((0.5 - 0.5 * normal) * 255, 0, 255).astype(np.uint8)
    cc = cv2.applyColorMap((255 * np.clip(conf, 0, 1)).astype(np.uint8),
                           cv2.COLORMAP_VIRIDIS)[..., ::-1]
    for img in (dc, nc, cc):
        img[~ok] = 0
    return np.hstack([dc, nc, cc])


def _coverage_plot(path: Path, names, depth_cov, fused_cov) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(max(6, 0.35 * len(names)), 3.5))
    x = np.arange(len(names))
    ax.bar(x - 0.2, depth_cov, 0.4, label="depth (PatchMatch)")
    ax.bar(x + 0.2, fused_cov, 0.4, label="fused (agreed by other views)")
    ax.set_xticks(x, names, rotation=90, fontsize=7)
    ax.set_ylim(0, 1)
    ax.set_ylabel("fraction of the view's pixels")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def dense_surface(names: Sequence[str], images: Sequence[np.ndarray],
                  cameras: Sequence[Camera], visible: Sequence[np.ndarray],
                  points: np.ndarray, out: Path, options: MvsOptions | None = None):
    """Depth maps, fused points and the mesh of the registered views.

    Parameters
    ----------
    names, images, cameras : sequences
        The registered views: names, upright uint8 images (grey or RGB) and cameras.
    visible : sequence of (m_i,) int
        Sparse points seen by each view.
    points : (n, 3) float
        Sparse points (cameras' frame).
    out : Path
        Existing folder receiving ``dense/``, ``fused.ply`` (and nothing else).

    Returns
    -------
    mesh : open3d TriangleMesh or None
        None when no depth survived.
    report : dict
    """
    opt = options or MvsOptions()
    if opt.method == "sgbm":
        return _sgbm_surface(names, images, cameras, visible, points, opt)
    from core.mesh_io import write_points

    po = opt.patchmatch
    timings = {}
    t = time.perf_counter()
    views = prepare_views(names, images, cameras, po.max_image_size)
    for v, vis in zip(views, visible, strict=True):
        v.depth_range = depth_range(v.camera, points, np.asarray(vis, np.int64),
                                    po.depth_margin)
    wcams = [v.camera for v in views]
    sources = select_sources(wcams, visible, points, po.num_sources, po.min_angle_deg,
                             po.max_angle_deg)
    timings["prepare"] = time.perf_counter() - t
    t = time.perf_counter()
    maps, pm_t = patchmatch(views, sources, po)
    timings["depth_maps"] = time.perf_counter() - t
    timings.update({f"depth_maps_{k}": v for k, v in pm_t.items()})
    for v, m in zip(views, maps, strict=True):
        if not m.sources:
            log.warning("%s: no depth map (no source view shares its scene, or no sparse "
                        "point in front of it); skipped", v.name)
    t = time.perf_counter()
    neighbours = [sorted(set(s) | {j for j, ss in enumerate(sources) if i in ss})
                  for i, s in enumerate(sources)]
    fused = fuse_points(wcams, [m.depth for m in maps], [m.normal for m in maps],
                        [v.color for v in views], neighbours, opt.fusion)
    timings["fuse"] = time.perf_counter() - t
    t = time.perf_counter()
    mesh = _surface(opt, fused, views, maps, points)
    timings["mesh"] = time.perf_counter() - t
    t = time.perf_counter()
    dense = out / "dense"
    dense.mkdir(exist_ok=True)
    for v, m in zip(views, maps, strict=True):
        (dense / v.name).parent.mkdir(parents=True, exist_ok=True)
        for kind, arr in (("depth", m.depth), ("normal", m.normal),
                          ("confidence", m.confidence)):
            np.save(dense / f"{v.name}.{kind}.npy", arr)
        write_image(dense / f"{v.name}.preview.png", _preview(m.depth, m.normal, m.confidence))
    write_points(out / "fused.ply", fused.points, normals=fused.normals, colors=fused.colors)
    depth_cov = [m.coverage for m in maps]
    _coverage_plot(dense / "coverage.png", list(names), depth_cov, fused.coverage)
    timings["write"] = time.perf_counter() - t
    mpix = sum(v.camera.width * v.camera.height for v in views) / 1e6
    report = {
        "method": "patchmatch", "surface": opt.surface,
        "working_size": {v.name: [v.camera.width, v.camera.height] for v in views},
        "views": {v.name: {"depth_coverage": dc, "fused_coverage": fc, "sources": m.sources,
                           "depth_range": list(v.depth_range)}
                  for v, m, dc, fc in zip(views, maps, depth_cov, fused.coverage, strict=True)},
        "fused_points": int(len(fused.points)),
        "min_fused_coverage": float(min(fused.coverage)) if maps else 0.0,
        "megapixel_views_per_s": (mpix * (po.iterations + po.geom_iterations)
                                  / max(timings["depth_maps"], 1e-9)),
        "megapixel_views_per_s_definition": "working-resolution megapixels of all views x "
                                            "PatchMatch iterations / depth-map seconds",
        "timings": timings, "coverage_plot": "dense/coverage.png",
        "triangles": 0 if mesh is None else len(mesh.triangles)}
    return mesh, report


def _surface(opt: MvsOptions, fused, views, maps, points):
    if len(fused.points) < 100:
        return None
    if opt.surface == "poisson":
        return poisson_surface(fused, [v.camera for v in views],
                               [m.depth for m in maps], opt.fusion, seed=opt.patchmatch.seed)
    from reconstruct.tsdf import fuse_depth_maps

    depths = [np.where(mask, m.depth, 0.0).astype(np.float32)
              for mask, m in zip(fused.masks, maps, strict=True)]
    lo, hi = np.percentile(points, [2, 98], axis=0)
    voxel = float(np.linalg.norm(hi - lo)) * opt.voxel_fraction
    zmax = max(float(d.max()) for d in depths)
    return fuse_depth_maps(depths, [v.camera for v in views], voxel_size=voxel,
                           depth_max=1.5 * zmax, colors=[v.color for v in views])


def _sgbm_surface(names, images, cameras, visible, points, opt: MvsOptions):
    """The earlier dense stage: rectified-pair SGBM depth maps and a TSDF (the peer)."""
    import cv2

    from reconstruct.tsdf import fuse_depth_maps

    t = time.perf_counter()
    grays = [img if img.ndim == 2 else cv2.cvtColor(img[..., :3], cv2.COLOR_RGB2GRAY)
             for img in images]
    colors = [img if img.ndim == 3 else np.repeat(img[..., None], 3, 2) for img in images]
    depths, neighbors = depth_maps(grays, cameras, visible, points, options=opt.sgbm)
    timings = {"depth_maps": time.perf_counter() - t}
    lo, hi = np.percentile(points, [2, 98], axis=0)
    voxel = float(np.linalg.norm(hi - lo)) * opt.voxel_fraction
    zmax = max(float(np.max(d)) for d in depths) if depths else 0.0
    mesh = None
    t = time.perf_counter()
    if zmax > 0:
        mesh = fuse_depth_maps(depths, cameras, voxel_size=voxel, depth_max=1.5 * zmax,
                               colors=colors)
    timings["mesh"] = time.perf_counter() - t
    cov = [float((d > 0).mean()) for d in depths]
    report = {"method": "sgbm", "surface": "tsdf",
              "views": {n: {"depth_coverage": c, "fused_coverage": c,
                            "sources": [names[j] for j in nb]}
                        for n, c, nb in zip(names, cov, neighbors, strict=True)},
              "min_fused_coverage": min(cov) if cov else 0.0, "voxel_size": voxel,
              "timings": timings, "triangles": 0 if mesh is None else len(mesh.triangles)}
    return mesh, report
