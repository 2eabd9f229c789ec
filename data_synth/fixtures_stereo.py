"""Small scenes and cached captures for the stereo / structured-light tests.

``textured_scene(seed)``: a solid-textured sphere and box on a turntable disc;
``textureless_scene()``: the same shapes in one constant colour. Both ~15 cm tall,
on the turntable axis (world Z through the origin).
"""

from __future__ import annotations

import numpy as np

from acquire.render.lights import PointLight
from acquire.render.materials import Material
from acquire.render.scene import RenderScene, SceneObject
from core.meshes import make_mesh, merge_meshes

__all__ = ["textured_scene", "textureless_scene", "scene_mesh"]


def _shapes():
    import open3d as o3d

    sphere = o3d.geometry.TriangleMesh.create_sphere(0.05, resolution=60)
    sphere.translate([0.0, 0.0, 0.07])
    box = o3d.geometry.TriangleMesh.create_box(0.05, 0.05, 0.08)
    box.translate([0.03, -0.065, 0.02])
    disc = o3d.geometry.TriangleMesh.create_cylinder(0.11, 0.02, resolution=80)
    disc.translate([0.0, 0.0, 0.01])
    for m in (sphere, box, disc):
        m.compute_vertex_normals()
    v, f = (np.asarray(sphere.vertices), np.asarray(sphere.triangles))
    return [("sphere", make_mesh(v, f), {"type": "sphere", "center": [0, 0, 0.07],
                                         "radius": 0.05}),
            ("box", box, None), ("disc", disc, None)]


def _scene(materials) -> RenderScene:
    objs = [SceneObject(name, mesh, materials[i], object_id=i, analytic=ana)
            for i, (name, mesh, ana) in enumerate(_shapes())]
    return RenderScene(objs, [PointLight([0.1, -0.45, 0.35], 0.12)], ambient=0.15)


def textured_scene(seed: int = 0) -> RenderScene:
    mats = [Material("solid", albedo=(0.9, 0.85, 0.8), texture="fbm", scale=60.0, contrast=0.9,
                     seed=seed + i) for i in range(3)]
    return _scene(mats)


def textureless_scene() -> RenderScene:
    return _scene([Material("constant", albedo=(0.7, 0.7, 0.7))] * 3)


def scene_mesh(scene: RenderScene):
    """World-frame ground-truth mesh of a scene (all objects merged)."""
    from core.meshes import transform_mesh

    return merge_meshes([transform_mesh(o.mesh, o.world_from_object) for o in scene.objects])
