"""Small data sets with their truth for tests and benchmarks.

Rendered captures built once and reused (each builder takes a root folder and returns the
capture folder, rendering it only when it is missing), the faces a set of cameras sees of
a mesh, and :func:`sloped_tile`, a quick airborne survey of a sloped forest floor:

A quick airborne survey of a sloped forest floor with its exact truth, without ray casting.

For tests and benchmarks of the ground filter that need seconds, not the minutes a
simulated stand takes (:mod:`data_synth.forest` flown by ``scanamp capture lidar``): a
terrain from :func:`procgen.terrain.mountain_relief` (a fractal floor with breaks of slope,
a ravine and boulders, tilted to a mean slope), pulses at random over a square tile, and
what they return:

- shrubs 0.3-2.5 m tall on discs 0.3-1 m in radius at random, together covering
  ``cover`` of the floor; a pulse under a shrub ends on it four times in five (its
  surface: a half-ellipsoid, times 0.6-1 for the foliage's depth), on the ground otherwise;
- a share ``canopy`` of the pulses ends in a crown 8-25 m up (a single, last return);
- of the rest, 60 % also leave a first return in a crown (not their last).

Every ground and shrub return is a last return; range noise 3 cm.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from core.io.raster import Raster
from core.validate import check_positive, check_range, check_rng

__all__ = ["sfm_capture", "turntable_backdrop", "ring_of_eyes", "seen_triangles", "SlopedTile",
           "sloped_tile"]


def sfm_capture(root: str | os.PathLike, *, scene: str = "primitives", views: int = 12,
                width: int = 320, height: int = 240, kind: str = "orbit",
                elevations_deg: tuple = (35.0,), distance_factor: float = 0.6,
                seed: int = 0, texture_boost: float = 4.0, read_noise: float | None = None,
                blur_sigma: float = 0.0) -> Path:
    """A small SfM capture (default: one ring of 12 orbit views of 'primitives' at 320x240).

    The defaults are chosen for a well-conditioned small problem: 30 degrees between
    neighbouring views and the scene filling the frame (``distance_factor`` 0.6) give
    about 1000 SIFT features per image and 100+ verified matches between neighbours.
    (Two rings of 6 views at 60 degrees with the scene in a quarter of the frame gave
    ~350 features, 15-30 inliers between the rings and none within the low ring: the
    rotations came out 0.3-0.7 degrees off whatever the thread count.)

    ``texture_boost`` 1 keeps the scene's own texture (the capture's default makes it 4
    times finer at full contrast); ``read_noise`` (electrons) and ``blur_sigma`` (px) set
    the sensor's (a noisy black backdrop, soft optics, as real rings have).
    """
    from acquire.sensor import Sensor
    from acquire.sfm.capture import PathConfig, capture
    from data_synth.scenes import build_scene

    elev = "-".join(f"{e:g}" for e in elevations_deg)
    extra = (f"_t{texture_boost:g}_n{read_noise:g}_b{blur_sigma:g}"
             if (texture_boost, read_noise, blur_sigma) != (4.0, None, 0.0) else "")
    out = Path(root) / (f"sfm_{scene}_{kind}_{views}_{width}x{height}_e{elev}"
                        f"_d{distance_factor:g}_s{seed}{extra}")
    if (out / "capture.json").is_file():
        return out
    bundle = build_scene(scene)
    sensor = Sensor(blur_sigma=blur_sigma, **({} if read_noise is None else
                                              {"read_noise": read_noise}))
    cfg = PathConfig(kind=kind, views=views, width=width, height=height,
                     elevations_deg=list(elevations_deg), distance_factor=distance_factor,
                     texture_boost=texture_boost, sensor=sensor)
    return capture(bundle.render_scene, cfg, out, rng=np.random.default_rng(seed),
                   scene_ref={"name": bundle.name, "seed": bundle.seed, "path": None},
                   gt_mesh=bundle.gt_mesh(), seed=seed)


def ring_of_eyes(vertices, n: int = 12, elevations_deg=(15.0, 45.0), seed: int = 0) -> np.ndarray:
    """``n`` camera centres ``(n, 3)`` evenly around a mesh's bounding box centre, at its
    diagonal's distance and elevations drawn uniformly in ``elevations_deg``: a capture
    walked around a scene and above it, for :func:`seen_triangles`."""
    v = np.asarray(vertices, np.float64)
    lo, hi = v.min(0), v.max(0)
    c, r = 0.5 * (lo + hi), np.linalg.norm(hi - lo)
    el = np.radians(np.random.default_rng(seed).uniform(*elevations_deg, n))
    az = 2 * np.pi * np.arange(n) / n
    return c + r * np.stack([np.cos(az) * np.cos(el), np.sin(az) * np.cos(el), np.sin(el)], 1)


def turntable_backdrop(capture_dir: str | os.PathLike, out: str | os.PathLike, *,
                       rng: np.random.Generator, level: float = 14.0,
                       contrast: float = 7.0, scale: float = 24.0,
                       vignetting: float = 0.6) -> Path:
    """A copy of an SfM capture of an object on black, as a turntable would photograph it:
    behind the object, one dim textured backdrop (a cloth: grey ``level`` of 255, with
    ``contrast`` grey levels rms of texture in three octaves from ``scale`` px down,
    darker toward the corners by ``1 / (1 + vignetting r^2)``, r = 1 at the middle of a
    side) at the *same pixels in every view*: the camera and the cloth stand still, the
    object turns.

    The object is composited over it through its true silhouette (the rendered depth > 0,
    softened by 0.7 px), so the truth (``gt/``, ``capture.json``) holds unchanged. A
    pattern fixed to the image matches itself at the same pixels in every pair of views,
    and the rays of one pixel in a ring of views meet beside the object: stereo finds a
    consistent surface there that is in no scene.
    """
    import shutil

    import cv2

    from core.io.image import read_image, write_image

    check_positive(scale, "scale")
    check_rng(rng)
    src, dst = Path(capture_dir), Path(out)
    if (dst / "capture.json").is_file():
        return dst
    tmp = dst.with_name(dst.name + ".partial")
    shutil.rmtree(tmp, ignore_errors=True)
    shutil.copytree(src, tmp)
    images = sorted((tmp / "images").glob("*.png"))
    h, w = read_image(images[0]).shape[:2]
    tex = np.zeros((h, w))
    for s, a in ((scale, 1.0), (scale / 2, 0.5), (scale / 4, 0.25)):
        g = rng.normal(size=(int(h / s) + 2, int(w / s) + 2))
        tex += a * cv2.resize(g, (w, h), interpolation=cv2.INTER_CUBIC)
    tex = (tex - tex.mean()) / max(tex.std(), 1e-12)
    yy, xx = np.mgrid[:h, :w]
    r2 = ((xx - w / 2) ** 2 + (yy - h / 2) ** 2) / (w / 2) ** 2
    back = np.clip(level + contrast * tex, 0.0, None) / (1.0 + vignetting * r2)
    for i, path in enumerate(images):
        img = read_image(path).astype(np.float64)
        sil = (np.load(tmp / "gt" / f"depth_{i:04d}.npy") > 0).astype(np.float64)
        bg = (1.0 - cv2.GaussianBlur(sil, (0, 0), 0.7)) * back
        img = img + (bg[..., None] if img.ndim == 3 else bg)
        write_image(path, np.clip(np.rint(img), 0, 255).astype(np.uint8))
    tmp.rename(dst)
    return dst


def seen_triangles(vertices, triangles, eyes, *, target=None, fov_deg: float = 60.0,
                   rays: int = 120) -> np.ndarray:
    """The triangles a capture from ``eyes (k, 3)`` sees (a ``rays x rays`` grid of rays
    over ``fov_deg`` from each eye toward ``target``, default the bounding box centre):
    what a reconstruction of the scene from those views can hold -- no undersides, no
    hidden faces."""
    import open3d as o3d

    v = np.asarray(vertices, np.float64)
    f = np.asarray(triangles, np.int64)
    c = 0.5 * (v.min(0) + v.max(0)) if target is None else np.asarray(target, np.float64)
    tm = o3d.t.geometry.TriangleMesh()
    tm.vertex.positions = o3d.core.Tensor(v.astype(np.float32))
    tm.triangle.indices = o3d.core.Tensor(f.astype(np.int32))
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(tm)
    seen = np.zeros(len(f), bool)
    half = np.tan(np.radians(fov_deg) / 2)
    s = np.linspace(-half, half, rays)
    X, Y = np.meshgrid(s, s)
    for eye in np.asarray(eyes, np.float64).reshape(-1, 3):
        d = c - eye
        d /= np.linalg.norm(d)
        side = np.cross(d, [0.0, 0.0, 1.0] if abs(d[2]) < 0.99 else [1.0, 0.0, 0.0])
        side /= np.linalg.norm(side)
        upv = np.cross(side, d)
        dirs = d + X.ravel()[:, None] * side + Y.ravel()[:, None] * upv
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        r = np.hstack([np.tile(eye, (len(dirs), 1)), dirs]).astype(np.float32)
        hit = scene.cast_rays(o3d.core.Tensor(r))["primitive_ids"].numpy()
        seen[hit[hit != scene.INVALID_ID].astype(np.int64)] = True
    return f[seen]



@dataclass
class SlopedTile:
    """Points (n, 3), last returns (n,), true ground (n,) and the true terrain."""

    points: np.ndarray
    last: np.ndarray
    ground: np.ndarray
    terrain: Raster


def sloped_tile(slope: float, *, rng: np.random.Generator, size: float = 40.0,
                density: float = 10.0, cover: float = 0.5, canopy: float = 0.5,
                relief: float = 0.7) -> SlopedTile:
    """A ``size`` x ``size`` m tile at ``density`` pulses/m2 on a ``slope``-degree terrain.

    The terrain raster (0.5 m, exact: ground returns lie on its triangles) reaches 10 m
    beyond the tile on every side; the tile spans ``[0, size]`` in x and y.
    """
    from scipy.spatial import cKDTree

    from data_synth.forest import terrain_height
    from procgen.terrain import fractal_terrain, mountain_relief

    check_rng(rng)
    s = check_range(slope, "slope", 0.0, 45.0)
    size = check_positive(size, "size")
    density = check_positive(density, "density")
    cover = check_range(cover, "cover", 0.0, 0.95)
    canopy = check_range(canopy, "canopy", 0.0, 1.0)
    res = 0.5
    cells = int(np.ceil((size + 20) / res)) + 1
    side = 2 ** int(np.ceil(np.log2(cells - 1))) + 1
    base = fractal_terrain(side, rng=rng, method="fbm", hurst=0.8, height=relief,
                           frequency=max(side * res / 80.0, 1.0), octaves=5)[:cells, :cells]
    z = mountain_relief(base, spacing=res, rng=rng, slope=s, slope_breaks=2, ravines=1,
                        boulders=20.0)
    terrain = Raster(z, x0=-10.0, y0=-10.0, res=res)
    mean_area = np.pi * (1.0 - 0.3 ** 3) / (3 * 0.7)  # radii uniform in 0.3-1 m
    span = size + 20
    n_sh = int(-np.log(1 - cover) * span * span / mean_area)  # random discs covering this
    sh_xy = rng.uniform(-10, size + 10, (n_sh, 2))
    sh_r = rng.uniform(0.3, 1.0, n_sh)
    sh_h = rng.uniform(0.3, 2.5, n_sh)
    n = int(size * size * density)
    xy = rng.uniform(0, size, (n, 2))
    g = terrain_height(terrain, xy[:, 0], xy[:, 1])
    if n_sh:
        d, k = cKDTree(sh_xy).query(xy)
        under = d < sh_r[k]
        frac = np.sqrt(np.clip(1 - (d / sh_r[k]) ** 2, 0, 1))
    else:
        under, k, frac = np.zeros(n, bool), np.zeros(n, np.int64), np.zeros(n)
    on_shrub = under & (rng.random(n) < 0.8)
    top = np.where(on_shrub, sh_h[k] * frac * rng.uniform(0.6, 1.0, n), 0.0)
    low = np.column_stack([xy, g + top + rng.normal(0, 0.03, n)])
    crown = rng.random(n) < canopy
    high = np.column_stack([xy, g + rng.uniform(8, 25, n)])
    through = ~crown & (rng.random(n) < 0.6)  # a first return in a crown, then on
    pts = np.vstack([low[~crown], high[crown], high[through]])
    last = np.r_[np.ones((~crown).sum() + crown.sum(), bool), np.zeros(through.sum(), bool)]
    truth = np.r_[~on_shrub[~crown], np.zeros(crown.sum() + through.sum(), bool)]
    return SlopedTile(pts, last, truth, terrain)
