"""Shaded 640x480 frame time against Open3D's bare cast_rays of the same rays (same run):
direct light (target <= 4x the bare cast) and with one bounce of indirect light (target
<= 12x)."""

import numpy as np
from _timing import best_of

from acquire.camera import Camera
from acquire.render import render
from data_synth.scenes import build_scene


def main():
    import open3d as o3d

    bundle = build_scene("primitives")
    scene = bundle.render_scene
    cam = Camera.look_at([0.5, -0.7, 0.5], [0, 0, 0.05], width=640, height=480, fov_deg=50)
    rs, _, _ = scene.raycasting()
    for ss in (1, 2):
        o, d = cam.rays(cam.pixel_grid(supersample=ss))
        rays = o3d.core.Tensor(np.concatenate([o, d], 1).astype(np.float32))
        n = rays.shape[0]
        bare = best_of(lambda rays=rays: rs.cast_rays(rays))
        shaded = best_of(lambda ss=ss: render(scene, cam, supersample=ss), repeat=2)
        print(f"   supersample {ss}: {n / 1e6:.2f} M camera rays; bare cast_rays "
              f"{n / bare / 1e6:.1f} M rays/s; shaded frame {shaded:.2f} s = "
              f"{shaded / bare:.1f}x the bare cast (2 lights with shadow rays, textures, "
              f"float64 refinement{', + centre rays for ground truth' if ss > 1 else ''})")
        bounce = best_of(lambda ss=ss: render(scene, cam, supersample=ss, bounces=1),
                         repeat=2)
        print(f"   supersample {ss}, one bounce: {bounce:.2f} s = {bounce / bare:.1f}x the "
              f"bare cast (target <= 12x); direct only {shaded / bare:.1f}x (target <= 4x)")


if __name__ == "__main__":
    main()
