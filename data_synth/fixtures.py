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
                seed: int = 0) -> Path:
    """A small SfM capture (default: 12 orbit views of 'primitives' at 320x240, ~20 s)."""
    from acquire.capture_sfm import PathConfig, capture
    from data_synth.scenes import build_scene

    out = Path(root) / f"sfm_{scene}_{kind}_{views}_{width}x{height}_s{seed}"
    if (out / "capture.json").is_file():
        return out
    bundle = build_scene(scene)
    cfg = PathConfig(kind=kind, views=views, width=width, height=height)
    return capture(bundle.render_scene, cfg, out, rng=np.random.default_rng(seed),
                   scene_ref={"name": bundle.name, "seed": bundle.seed, "path": None},
                   gt_mesh=bundle.gt_mesh(), seed=seed)
