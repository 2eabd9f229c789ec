"""Every material preset under the laser sheet and under the projector: a sphere of each
reflectance (acquire.render.materials.MATERIAL_PRESETS) on a matte floor, seen by one camera,
lit by a vertical laser sheet (the laser scanner's renderer, acquire.laser.sheet) and by a
projector casting 8-pixel stripes (acquire.render.renderer with one bounce; on the translucent
presets the stripes spread under the surface). Writes docs/img/material_gallery.png.

    python docs/render_materials.py
"""

import os
from pathlib import Path

os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")

import numpy as np  # noqa: E402

OUT = Path(__file__).resolve().parent / "img" / "material_gallery.png"


def _scene(material):
    import open3d as o3d

    from acquire.render.materials import Material
    from acquire.render.scene import RenderScene, SceneObject

    ball = o3d.geometry.TriangleMesh.create_sphere(0.05, 60)
    ball.translate([0.0, 0.0, 0.05])
    floor = o3d.geometry.TriangleMesh.create_box(0.4, 0.4, 0.01)
    floor.translate([-0.2, -0.2, -0.01])
    objs = [SceneObject("ball", ball, material, object_id=1,
                        analytic={"type": "sphere", "center": [0, 0, 0.05], "radius": 0.05}),
            SceneObject("floor", floor, Material(albedo=np.array([0.5, 0.5, 0.5])),
                        object_id=2, analytic={"type": "plane", "point": [0, 0, 0],
                                               "normal": [0, 0, 1]})]
    return RenderScene(objs, [], ambient=0.03)


def main():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from acquire.camera import Camera
    from acquire.laser.sheet import LaserRenderer, LaserSheet
    from acquire.render.materials import MATERIAL_PRESETS, Material
    from acquire.render.projector import PatternProjector
    from acquire.render.renderer import render

    cam = Camera.look_at([0.0, -0.28, 0.16], [0, 0, 0.045], width=320, height=240,
                         fov_deg=28)
    # the laser: a vertical sheet from the camera's right, 30 degrees off its axis
    src = np.array([0.16, -0.25, 0.12])
    d = np.array([0.0, 0.0, 0.05]) - src
    d /= np.linalg.norm(d)
    laser = LaserSheet(origin=src, normal=np.cross(d, [0.0, 0.0, 1.0]), direction=d,
                       fan_angle=np.radians(40.0), thickness=0.4e-3, power=0.25,
                       color=np.array([1.0, 0.0, 0.0]))
    pcam = Camera.look_at([-0.12, -0.26, 0.18], [0, 0, 0.045], width=320, height=240,
                          fov_deg=30)
    stripes = ((np.arange(pcam.width) // 8) % 2).astype(np.float32)
    proj = PatternProjector(pcam, np.tile(stripes, (pcam.height, 1)), 0.05)
    names = list(MATERIAL_PRESETS)
    fig, axes = plt.subplots(2, len(names), figsize=(2.2 * len(names), 3.9))
    for k, name in enumerate(names):
        mat = Material(albedo=np.array([0.85, 0.8, 0.75]), **MATERIAL_PRESETS[name])
        scene = _scene(mat)
        fr = LaserRenderer(scene, cam).frame(cam.cam_from_world, laser)
        lit = render(scene, cam, lights=[proj], supersample=2, bounces=1, seed=0)
        axes[0, k].imshow(np.clip(fr.radiance / 0.6, 0, 1) ** (1 / 2.2), cmap="gray")
        axes[1, k].imshow(np.clip(lit.radiance.mean(axis=2) / 0.6, 0, 1) ** (1 / 2.2),
                          cmap="gray")
        axes[0, k].set_title(name, fontsize=9)
        for a in axes[:, k]:
            a.set_xticks([])
            a.set_yticks([])
    axes[0, 0].set_ylabel("laser sheet")
    axes[1, 0].set_ylabel("projector, 1 bounce")
    fig.tight_layout()
    OUT.parent.mkdir(exist_ok=True)
    fig.savefig(OUT, dpi=110)
    print(f"wrote {OUT}")  # noqa: T201 (a script)


if __name__ == "__main__":
    main()
