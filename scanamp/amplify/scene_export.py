"""An amplified result as a scene that ``scanamp capture`` accepts.

``scene.toml`` beside the result lists one object per part label (ground, object, plant,
snow, ...), each a ``shape = "mesh"`` object reading ``parts/LABEL.ply`` with a constant
material of the part's colour and its kind's reflectance
(:data:`scanamp.amplify.labels.PART_MATERIALS`: glossy leaves and walls, translucent snow).
The meshes are in the upright frame (up +z) moved so the
scene stands on z = 0 centred on the turntable axis, where the scanners' rigs look; the
object order follows the labels, so a capture's ground-truth object ids name the parts
(``scene.toml``'s objects, in order). ``scene_from_mesh`` maps the input mesh's frame
into the scene's.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from core.files import write_toml
from core.io.mesh import write_mesh
from core.meshes import compact, make_mesh
from scanamp.amplify.labels import PART_MATERIALS

__all__ = ["write_scene"]


def write_scene(folder: Path, vertices: np.ndarray, triangles: np.ndarray,
                colors: np.ndarray, labels: np.ndarray, names: dict[int, str]) -> np.ndarray:
    """Write ``scene.toml`` and ``parts/*.ply`` into ``folder``; returns the (4, 4)
    transform from the given (upright) vertices' frame to the scene's."""
    v = np.asarray(vertices, np.float64)
    lo, hi = v.min(axis=0), v.max(axis=0)
    T = np.eye(4)
    T[:3, 3] = [-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]]
    vs = v + T[:3, 3]
    (folder / "parts").mkdir()
    objects = []
    tri_label = labels[triangles[:, 0]]
    for k in sorted(np.unique(tri_label)):
        f = triangles[tri_label == k]
        used, tris = compact(f)
        name = names[int(k)]
        write_mesh(folder / "parts" / f"{name}.ply", make_mesh(vs[used], tris))
        rgb = np.round(colors[used].mean(axis=0), 4).tolist()
        objects.append({"name": name, "shape": "mesh", "path": f"parts/{name}.ply",
                        "material": {"kind": "constant", "albedo": rgb,
                                     **PART_MATERIALS.get(name, {})}})
    extent = float(np.linalg.norm(hi - lo))
    write_toml(folder / "scene.toml", {
        "scene": {"name": "amplified", "seed": 0, "ambient": 0.15},
        "lights": [{"type": "point", "position": [0.6 * extent, -0.8 * extent, 1.2 * extent],
                    "intensity": 0.6}],
        "objects": objects})
    return T
