"""Procedural stand-ins for a scanned collider when no mesh is given.

``"scan"`` is a closed, bumpy, scan-like blob: an icosphere displaced along its
normals by fixed-seed Perlin fBm, so it has the concavities of a real scan.
"""

from __future__ import annotations

import numpy as np

from core.meshes import make_mesh, mesh_arrays
from core.validate import check_choice, check_positive
from procgen.noise import perlin

__all__ = ["stand_in_mesh", "lumpy_sphere", "STAND_INS"]

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
        return _moved(lumpy_sphere(r), centre)
    mesh.compute_vertex_normals()
    return _moved(mesh, centre)


def lumpy_sphere(radius: float, *, resolution: int = 60, amplitude: float = 0.3,
                 seed: int = 3):
    """A closed, scan-like blob: a sphere of ``radius`` (m) displaced along its normals
    by three octaves of Perlin fBm, ``r (1 + amplitude * fbm(unit normal))``."""
    import open3d as o3d

    mesh = o3d.geometry.TriangleMesh.create_sphere(radius=1.0, resolution=int(resolution))
    v, f = mesh_arrays(mesh)
    u = v / np.linalg.norm(v, axis=1, keepdims=True)
    bump = np.zeros(len(u))
    for octave in range(3):
        freq = 1.2 * 2 ** octave
        bump += 0.5 ** octave * perlin(*(freq * u + 10.0).T, seed=seed)
    return make_mesh(u * (radius * (1.0 + amplitude * bump))[:, None], f)


def _moved(mesh, centre):
    c = np.asarray(centre, float)
    if np.any(c != 0):
        mesh.translate(c)
    return mesh
