"""The demo: the main job `make demo` runs.

Now: build the `object` scene, render it from a ring of views with the sensor model,
back-project each view's depth (perturbed by a depth-sensor noise model) into one
point cloud, and score it against the ground truth with the evaluation yardstick.
The pipeline issue grows this into capture -> reconstruct -> amplify -> animate.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

from acquire.camera import Camera
from acquire.render import render
from acquire.sensor import Sensor
from data_synth.scenes import build_scene, write_scene
from procgen.files import atomic_dir, write_json
from procgen.mesh_io import write_image, write_points
from procgen.progress import track
from reconstruct.evaluate import evaluate

log = logging.getLogger(__name__)


def run(out_dir, *, seed: int = 0, views: int = 6, size=(320, 240),
        depth_noise: float = 0.0005) -> dict:
    """Run the demo into ``out_dir``; returns the report (also written as report.json)."""
    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    bundle = build_scene("object", seed=seed)
    out = Path(out_dir)
    with atomic_dir(out) as tmp:
        write_scene(bundle, tmp / "scene")
        (tmp / "views").mkdir()
        pts = []
        sensor = Sensor()
        for k in track(range(views), "rendering views", total=views):
            a = 2 * np.pi * k / views
            eye = np.array([0.42 * np.cos(a), 0.42 * np.sin(a), 0.28])
            cam = Camera.look_at(eye, [0, 0, 0.06], width=size[0], height=size[1], fov_deg=40)
            r = render(bundle.render_scene, cam, supersample=2)
            write_image(tmp / "views" / f"view_{k:02d}.png", sensor.apply(r.radiance * 2, rng))
            obj = r.object_id == bundle.render_scene.object("object").object_id
            v, u = np.nonzero(obj)
            z = r.depth[v, u].astype(np.float64)
            z = z + rng.normal(0, depth_noise, z.shape)
            pts.append(cam.unproject(np.stack([u, v], 1).astype(float), z))
        cloud = np.vstack(pts)
        write_points(tmp / "points.ply", cloud)
        res = evaluate(cloud, bundle.object_mesh("object"), tau=0.002,
                       rng=np.random.default_rng(seed))
        report = {"scene": bundle.name, "seed": seed, "views": views, "size": list(size),
                  "depth_noise_m": depth_noise, "points": len(cloud),
                  "evaluation": res.to_dict(), "seconds": round(time.perf_counter() - t0, 2)}
        write_json(tmp / "report.json", report)
    log.info("demo: %d views of %r, %d points; F-score at %.1f mm = %.3f; accuracy %.2f mm "
             "(mean); completeness %.2f mm -> %s", views, bundle.name, len(cloud),
             res.tau * 1e3, res.fscore, res.accuracy_mean * 1e3,
             res.completeness_mean * 1e3, out)
    return report
