"""Small rendered captures for tests, built once and reused (each builder takes a root
folder and returns the capture folder, rendering it only when it is missing).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

__all__ = ["sfm_capture"]


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
