"""Shaded 640x480 frame time against Open3D's bare cast_rays of the same rays (same run):
direct light (target <= 4x the bare cast) and with one bounce of indirect light (target
<= 12x), at 1 and at 2 x 2 rays per pixel. Each time is the best of 15 runs, the three
timed in turn (the bare cast of 0.3 M rays varies by a third from run to run on a shared
machine, and a frame's time from one process to the next)."""

import numpy as np
from _timing import best_of_interleaved, report

from acquire.camera import Camera
from acquire.render.renderer import render
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
        # the bare cast twice per round: the second finds Embree's tree in cache again
        # after a frame has flushed it, as it is in back-to-back casts
        bare_cold, bare, shaded, bounce = best_of_interleaved(
            [lambda rays=rays: rs.cast_rays(rays), lambda rays=rays: rs.cast_rays(rays),
             lambda ss=ss: render(scene, cam, supersample=ss),
             lambda ss=ss: render(scene, cam, supersample=ss, bounces=1)], repeat=15)
        bare = min(bare, bare_cold)
        print(f"   supersample {ss}: {n / 1e6:.2f} M camera rays; bare cast_rays "
              f"{bare * 1e3:.1f} ms ({n / bare / 1e6:.1f} M rays/s); shaded frame "
              f"{shaded * 1e3:.0f} ms, with one bounce {bounce * 1e3:.0f} ms (2 lights with "
              f"shadow rays, fBm textures, float64 refinement"
              f"{', + centre rays for ground truth' if ss > 1 else ''})")
        report(f"supersample {ss}, direct light / bare cast", shaded, bare, 4.0,
               higher_is_better=False)
        report(f"supersample {ss}, one bounce / bare cast", bounce, bare, 12.0,
               higher_is_better=False)


if __name__ == "__main__":
    main()
