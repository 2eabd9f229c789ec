"""Small rendered captures for tests, built once and reused (each builder takes a root
folder and returns the capture folder, rendering it only when it is missing).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

__all__ = ["sfm_capture", "seen_triangles"]


def sfm_capture(root: str | os.PathLike, *, scene: str = "primitives", views: int = 12,
                width: int = 320, height: int = 240, kind: str = "orbit",
                elevations_deg: tuple = (35.0,), distance_factor: float = 0.6,
                seed: int = 0) -> Path:
    """A small SfM capture (default: one ring of 12 orbit views of 'primitives' at 320x240).

    The defaults are chosen for a well-conditioned small problem: 30 degrees between
    neighbouring views and the scene filling the frame (``distance_factor`` 0.6) give
    about 1000 SIFT features per image and 100+ verified matches between neighbours.
    (Two rings of 6 views at 60 degrees with the scene in a quarter of the frame gave
    ~350 features, 15-30 inliers between the rings and none within the low ring: the
    rotations came out 0.3-0.7 degrees off whatever the thread count.)
    """
    from acquire.sfm.capture import PathConfig, capture
    from data_synth.scenes import build_scene

    elev = "-".join(f"{e:g}" for e in elevations_deg)
    out = Path(root) / (f"sfm_{scene}_{kind}_{views}_{width}x{height}_e{elev}"
                        f"_d{distance_factor:g}_s{seed}")
    if (out / "capture.json").is_file():
        return out
    bundle = build_scene(scene)
    cfg = PathConfig(kind=kind, views=views, width=width, height=height,
                     elevations_deg=list(elevations_deg), distance_factor=distance_factor)
    return capture(bundle.render_scene, cfg, out, rng=np.random.default_rng(seed),
                   scene_ref={"name": bundle.name, "seed": bundle.seed, "path": None},
                   gt_mesh=bundle.gt_mesh(), seed=seed)


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
