"""The dense stage of structure from motion: PatchMatch depth maps, fusion, a surface,
and the files a user looks at.

:func:`dense_surface` takes the registered views (upright images and their cameras) and
the sparse points, and returns the mesh with a report. Written into the output folder:

- ``dense/NAME.depth.npy``, ``.normal.npy``, ``.confidence.npy`` (working resolution,
  float32, 0 = no depth) and ``dense/NAME.preview.png`` (depth, normal, confidence);
- ``fused.ply``: the fused points with normals and colours;
- ``dense/coverage.png``: per view, the fraction of pixels with a depth and with a
  fused depth.

Two depth-map methods: ``patchmatch`` (:mod:`reconstruct.mvs.patchmatch`) and ``sgbm``
(rectified pairs, :mod:`reconstruct.mvs.dense`), the peer it replaced. Two surfaces: the
screened Poisson surface of the fused points trimmed by density, distance and free
space (:func:`reconstruct.mvs.fusion.poisson_surface`), or a TSDF of the fused depth
maps (:func:`reconstruct.surface.tsdf.fuse_depth_maps`), which suits renders of known
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
from core.io.image import write_image
from reconstruct.mvs.dense import DenseOptions, depth_maps, select_neighbors
from reconstruct.mvs.fusion import FusionOptions, fuse_points, poisson_surface
from reconstruct.mvs.patchmatch import PatchMatchOptions, depth_range, patchmatch, prepare_views

__all__ = ["MvsOptions", "dense_surface", "depth_stage", "fuse_stage", "mesh_stage",
           "working_colors", "dense_report", "select_sources", "DENSE_METHODS", "SURFACES"]

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
    angle (:func:`reconstruct.mvs.dense.select_neighbors`), completed by the views whose
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


def depth_stage(names: Sequence[str], images: Sequence[np.ndarray],
                cameras: Sequence[Camera], visible: Sequence[np.ndarray], points: np.ndarray,
                out: Path, options: MvsOptions | None = None) -> dict:
    """Stage ``dense``: a depth, normal and confidence map per view, in ``out/dense``.

    Returns what the later stages need: the working cameras, each view's sources
    (indices), depth range and depth coverage, timings.
    """
    opt = options or MvsOptions()
    dense = out / "dense"
    dense.mkdir(exist_ok=True)
    t = time.perf_counter()
    if opt.method == "sgbm":
        return _sgbm_depths(names, images, cameras, visible, points, dense, opt)
    po = opt.patchmatch
    views = prepare_views(names, images, cameras, po.max_image_size)
    for v, vis in zip(views, visible, strict=True):
        v.depth_range = depth_range(v.camera, points, np.asarray(vis, np.int64),
                                    po.depth_margin)
    wcams = [v.camera for v in views]
    sources = select_sources(wcams, visible, points, po.num_sources, po.min_angle_deg,
                             po.max_angle_deg)
    timings = {"prepare": time.perf_counter() - t}
    t = time.perf_counter()
    cpu = time.process_time()
    maps, pm_t = patchmatch(views, sources, po, opt.fusion)
    timings["depth_maps"] = time.perf_counter() - t
    cpu = time.process_time() - cpu
    timings.update({f"depth_maps_{k}": v for k, v in pm_t.items()})
    t = time.perf_counter()
    for v, m in zip(views, maps, strict=True):
        if not m.sources:
            log.warning("%s: no depth map (no source view shares its scene, or no sparse "
                        "point in front of it); skipped", v.name)
        (dense / v.name).parent.mkdir(parents=True, exist_ok=True)
        for kind, arr in (("depth", m.depth), ("normal", m.normal),
                          ("confidence", m.confidence)):
            np.save(dense / f"{v.name}.{kind}.npy", arr)
        write_image(dense / f"{v.name}.preview.png", _preview(m.depth, m.normal, m.confidence))
    timings["write"] = time.perf_counter() - t
    mpix = sum(c.width * c.height for c in wcams) / 1e6
    return {"method": "patchmatch", "names": list(names), "cameras": wcams,
            "input_cameras": list(cameras), "max_image_size": po.max_image_size,
            "sources": sources, "depth_range": [list(v.depth_range) for v in views],
            "depth_coverage": [m.coverage for m in maps], "timings": timings,
            "depth_maps_cpu_s": cpu,
            "megapixel_views_per_s": (mpix * (po.iterations + po.coarse_iterations / 4
                                              + po.geom_iterations)
                                      / max(timings["depth_maps"], 1e-9))}


def _maps(out: Path, names, kinds=("depth", "normal")):
    return [[np.load(out / "dense" / f"{n}.{k}.npy") for n in names] for k in kinds]


def fuse_stage(depth: dict, colors: Sequence[np.ndarray], out: Path,
               options: MvsOptions | None = None) -> dict:
    """Stage ``fuse``: the depth maps of ``out/dense`` fused into ``out/fused.ply``.

    ``colors`` are the views' images at the depth maps' resolution (uint8). Returns each
    view's fused coverage and fused-pixel masks (bit-packed), and timings."""
    from core.io.mesh import write_points

    opt = options or MvsOptions()
    t = time.perf_counter()
    names, cams = depth["names"], depth["cameras"]
    if depth["method"] == "sgbm":  # SGBM's maps are filtered already; no normals to fuse
        (depths,) = _maps(out, names, ("depth",))
        masks = [d > 0 for d in depths]
        return {"coverage": [float(m.mean()) for m in masks], "fused_points": None,
                "masks": [np.packbits(m) for m in masks],
                "timings": {"fuse": time.perf_counter() - t}}
    depths, normals = _maps(out, names)
    sources = depth["sources"]
    neighbours = [sorted(set(s) | {j for j, ss in enumerate(sources) if i in ss})
                  for i, s in enumerate(sources)]
    fused = fuse_points(cams, depths, normals, colors, neighbours, opt.fusion)
    write_points(out / "fused.ply", fused.points, normals=fused.normals, colors=fused.colors)
    _coverage_plot(out / "dense" / "coverage.png", list(names), depth["depth_coverage"],
                   fused.coverage)
    return {"coverage": fused.coverage, "fused_points": int(len(fused.points)),
            "masks": [np.packbits(m) for m in fused.masks],
            "timings": {"fuse": time.perf_counter() - t}}


def mesh_stage(depth: dict, fused: dict, colors: Sequence[np.ndarray], points: np.ndarray,
               out: Path, options: MvsOptions | None = None):
    """Stage ``mesh``: the surface of the fused points (Poisson, trimmed) or of the fused
    depth maps (TSDF); None when too little survived fusion."""
    opt = options or MvsOptions()
    cams, names = depth["cameras"], depth["names"]
    (depths,) = _maps(out, names, ("depth",))
    surface = "tsdf" if depth["method"] == "sgbm" else opt.surface
    masks = [np.unpackbits(m, count=d.size).reshape(d.shape).astype(bool)
             for m, d in zip(fused["masks"], depths, strict=True)]
    if surface == "poisson":
        import open3d as o3d

        from reconstruct.mvs.fusion import FusedPoints

        pcd = o3d.io.read_point_cloud(str(out / "fused.ply"))
        if len(pcd.points) < 100:
            return None, surface
        pts = FusedPoints(np.asarray(pcd.points), np.asarray(pcd.normals),
                          np.asarray(pcd.colors), np.zeros(len(pcd.points), np.int32), [])
        return poisson_surface(pts, cams, depths, opt.fusion, seed=opt.patchmatch.seed,
                               confirmed=masks), surface
    from reconstruct.surface.tsdf import fuse_depth_maps

    kept = [np.where(m, d, 0.0).astype(np.float32) for m, d in zip(masks, depths, strict=True)]
    if not any(np.any(d > 0) for d in kept):
        return None, surface
    lo, hi = np.percentile(points, [2, 98], axis=0)
    voxel = float(np.linalg.norm(hi - lo)) * opt.voxel_fraction
    zmax = max(float(d.max()) for d in kept)
    return fuse_depth_maps(kept, cams, voxel_size=voxel, depth_max=1.5 * zmax,
                           colors=list(colors)), surface


def working_colors(depth: dict, images: Sequence[np.ndarray]) -> list[np.ndarray]:
    """The views' colours at the depth maps' resolution (undistorted), uint8 RGB."""
    if depth["method"] == "sgbm":  # full resolution, as SGBM saw them
        return [img if img.ndim == 3 else np.repeat(img[..., None], 3, axis=2)
                for img in images]
    views = prepare_views(depth["names"], images, depth["input_cameras"],
                          depth["max_image_size"])
    return [v.color for v in views]


def dense_report(depth: dict, fused: dict, surface: str, mesh) -> dict:
    """``report.json``'s ``dense``: per view its coverage and sources, the method and the
    surface that ran, timings, megapixel-views per second."""
    names = depth["names"]
    report = {
        "method": depth["method"], "surface": surface,
        "working_size": {n: [c.width, c.height] for n, c in zip(names, depth["cameras"],
                                                                 strict=True)},
        "views": {n: {"depth_coverage": dc, "fused_coverage": fc,
                      "sources": [names[j] for j in src], "depth_range": rng}
                  for n, dc, fc, src, rng in zip(names, depth["depth_coverage"],
                                                 fused["coverage"], depth["sources"],
                                                 depth["depth_range"], strict=True)},
        "fused_points": fused["fused_points"],
        "min_fused_coverage": float(min(fused["coverage"])) if names else 0.0,
        "timings": {**depth["timings"], **fused["timings"]},
        "triangles": 0 if mesh is None else len(mesh.triangles)}
    if "megapixel_views_per_s" in depth:
        report["depth_maps_cpu_s"] = depth.get("depth_maps_cpu_s")
        report["megapixel_views_per_s"] = depth["megapixel_views_per_s"]
        report["megapixel_views_per_s_definition"] = (
            "working-resolution megapixels of all views x PatchMatch iterations (a "
            "half-resolution one counting a quarter) / depth-map seconds")
        report["coverage_plot"] = "dense/coverage.png"
    return report


def dense_surface(names: Sequence[str], images: Sequence[np.ndarray],
                  cameras: Sequence[Camera], visible: Sequence[np.ndarray],
                  points: np.ndarray, out: Path, options: MvsOptions | None = None):
    """The three stages in one call: depth maps, fusion and the mesh of the registered
    views (:func:`depth_stage`, :func:`fuse_stage`, :func:`mesh_stage`).

    Parameters
    ----------
    names, images, cameras : sequences
        The registered views: names, upright uint8 images (grey or RGB) and cameras.
    visible : sequence of (m_i,) int
        Sparse points seen by each view.
    points : (n, 3) float
        Sparse points (cameras' frame).
    out : Path
        Existing folder receiving ``dense/`` and ``fused.ply``.

    Returns
    -------
    mesh : open3d TriangleMesh or None
        None when no depth survived.
    report : dict
        :func:`dense_report`.
    """
    opt = options or MvsOptions()
    depth = depth_stage(names, images, cameras, visible, points, out, opt)
    colors = working_colors(depth, images)
    fused = fuse_stage(depth, colors, out, opt)
    t = time.perf_counter()
    mesh, surface = mesh_stage(depth, fused, colors, points, out, opt)
    fused["timings"]["mesh"] = time.perf_counter() - t
    return mesh, dense_report(depth, fused, surface, mesh)


def _sgbm_depths(names, images, cameras, visible, points, dense: Path, opt: MvsOptions):
    """Stage ``dense`` by the earlier method: rectified-pair SGBM with its consistency
    filter, at full resolution (the peer PatchMatch replaced)."""
    import cv2

    t = time.perf_counter()
    grays = [img if img.ndim == 2 else cv2.cvtColor(img[..., :3], cv2.COLOR_RGB2GRAY)
             for img in images]
    depths, neighbors = depth_maps(grays, cameras, visible, points, options=opt.sgbm)
    timings = {"depth_maps": time.perf_counter() - t}
    for n, d in zip(names, depths, strict=True):
        (dense / n).parent.mkdir(parents=True, exist_ok=True)
        np.save(dense / f"{n}.depth.npy", d.astype(np.float32))
    return {"method": "sgbm", "names": list(names), "cameras": list(cameras),
            "sources": neighbors, "depth_range": [[0.0, 0.0]] * len(names),
            "depth_coverage": [float((d > 0).mean()) for d in depths], "timings": timings}
