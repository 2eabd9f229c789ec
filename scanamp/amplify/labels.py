"""Part labels and colours of an amplified mesh.

Every output vertex carries a part label and a colour: the surface is split into ground
and objects (:func:`reconstruct.surface.ground.ground_mask`, up along +z), and each part a step
added keeps its kind (plants, vines, snow). ``mesh.ply`` stores them as ``red green
blue`` and an integer ``label`` vertex property, ``labels.json`` maps each label to its
name; the labels become ground-truth ids when the result is captured again.
"""

from __future__ import annotations

import re

import numpy as np

from core.meshes import mesh_arrays

__all__ = ["LABELS", "COLORS", "PART_MATERIALS", "label_of_part", "part_material",
           "labelled_arrays", "surface_parts"]

# label id -> name; fixed, so a label means the same thing in every output
LABELS = {0: "surface", 1: "ground", 2: "object", 3: "plant", 4: "vine", 5: "snow",
          6: "road", 7: "building", 8: "roof", 9: "bark", 10: "leaf", 11: "shell",
          12: "cloth", 13: "boid", 14: "window"}
_IDS = {name: k for k, name in LABELS.items()}
_PART_KIND = {"plants": "plant", "vines": "vine", "snow": "snow", "cloth": "cloth",
              "boids": "boid"}
COLORS = {"ground": (0.55, 0.5, 0.38), "object": (0.74, 0.7, 0.64),
          "surface": (0.72, 0.68, 0.6)}


# how each kind of part reflects (acquire.render.materials.Material fields besides its colour):
# leaves that let light through, vines and painted walls under a clear coat, snow that a
# laser stripe spreads in (subsurface),
# metal drones; the rest Lambertian
PART_MATERIALS = {"leaf": {"brdf": "translucent", "transmission": 0.3},
                  "vine": {"brdf": "dielectric", "roughness": 0.45},
                  "building": {"brdf": "dielectric", "roughness": 0.6},
                  "roof": {"brdf": "dielectric", "roughness": 0.35},
                  "window": {"brdf": "dielectric", "roughness": 0.05},
                  "snow": {"brdf": "subsurface", "mfp": 2e-3},
                  "boid": {"brdf": "conductor", "roughness": 0.3}}


def part_material(name: str) -> dict:
    """The material fields (no colour) of a part, by its label (:data:`PART_MATERIALS`)."""
    return dict(PART_MATERIALS.get(LABELS[label_of_part(name)], {}))


def label_of_part(name: str) -> int:
    """The label of a part a step added (``plants``, ``plants_2``, ``snow``, ...)."""
    base = re.sub(r"_\d+$", "", name)
    return _IDS.get(_PART_KIND.get(base, base), 0)


def surface_parts(surface) -> tuple[np.ndarray, list]:
    """Per-vertex labels of the surface (ground or object), and the surface as coloured
    render parts ``[(mesh, rgb), ...]``: the ground's triangles and the objects'."""
    from core.meshes import make_mesh
    from reconstruct.surface.ground import ground_mask

    v, f = mesh_arrays(surface)
    ground = ground_mask(v, f)
    labels = np.where(ground, _IDS["ground"], _IDS["object"])
    tri_ground = ground[f].sum(axis=1) >= 2
    parts = [(make_mesh(v, f[sel]), COLORS[kind])
             for sel, kind in ((tri_ground, "ground"), (~tri_ground, "object")) if sel.any()]
    return labels, parts


def labelled_arrays(surface, parts) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(vertices, triangles, colors (n, 3) in [0, 1], labels (n,))`` of the surface and
    the ``parts`` (``(name, mesh, rgb)``) merged, in that order."""
    labels, _ = surface_parts(surface)
    v, f = mesh_arrays(surface)
    names = {_IDS["ground"]: "ground", _IDS["object"]: "object"}
    colors = np.array([COLORS[names[int(k)]] for k in labels]).reshape(-1, 3)
    vs, fs, cs, ls, offset = [v], [f], [colors], [labels], len(v)
    for name, mesh, rgb in parts:
        pv, pf = mesh_arrays(mesh)
        vs.append(pv)
        fs.append(pf + offset)
        cs.append(np.tile(np.asarray(rgb, float), (len(pv), 1)))
        ls.append(np.full(len(pv), label_of_part(name)))
        offset += len(pv)
    return (np.vstack(vs), np.vstack(fs).astype(np.int64), np.vstack(cs),
            np.concatenate(ls).astype(np.int64))
