"""Procedural stand-ins for a scanned collider when no mesh is given.

``"scan"`` is a closed, bumpy, scan-like blob: an icosphere displaced along its
normals by fixed-seed Perlin fBm, so it has the concavities of a real scan.
"""

from __future__ import annotations

import numpy as np

from procgen.meshes import make_mesh, mesh_arrays
from procgen.noise import perlin
from procgen.validate import check_choice, check_positive

__all__ = ["stand_in_mesh", "STAND_INS"]

STAND_INS = ("sphere", "torus", "scan")


def stand_in_mesh(kind: str, size: float = 5.0, *, centre=(0.0, 0.0, 0.0)):
    """A closed obstacle mesh of radius about ``size`` (m) centred on ``centre``.

    Parameters
    ----------
    kind : {"sphere", "torus", "scan"}
    size : float
        Sphere radius; torus major radius (tube radius ``size / 3``); blob radius.
    """
    import open3d as o3d

    check_choice(kind, "kind", STAND_INS)
    r = check_positive(size, "size")
    if kind == "sphere":
        mesh = o3d.geometry.TriangleMesh.create_sphere(radius=r, resolution=40)
    elif kind == "torus":
        mesh = o3d.geometry.TriangleMesh.create_torus(torus_radius=r, tube_radius=r / 3,
                                                      radial_resolution=60,
                                                      tubular_resolution=30)
    else:
        mesh = o3d.geometry.TriangleMesh.create_sphere(radius=1.0, resolution=60)
        v, f = mesh_arrays(mesh)
        u = v / np.linalg.norm(v, axis=1, keepdims=True)
        bump = np.zeros(len(u))
        for octave in range(3):
            freq = 1.2 * 2 ** octave
            bump += 0.5 ** octave * perlin(*(freq * u + 10.0).T, seed=3)
        v = u * (r * (1.0 + 0.3 * bump))[:, None]
        mesh = make_mesh(v, f)
        return _moved(mesh, centre)
    mesh.compute_vertex_normals()
    return _moved(mesh, centre)


def _moved(mesh, centre):
    c = np.asarray(centre, float)
    if np.any(c != 0):
        mesh.translate(c)
    return mesh
