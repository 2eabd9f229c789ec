"""Which way is up in a reconstruction that arrives in its own frame.

A reconstruction from photographs (COLMAP, Meshroom, a phone app) or a scan from another
tool comes in the frame its software chose: up may be -y, +z or anything between. What
is built on it (plants, snow, a city) needs gravity. Two sources, in order of trust:

1. **The cameras beside the mesh.** People hold cameras upright (give or take a roll of
   a few degrees, which averages out), so the image's up, ``-y`` of an OpenCV camera, in
   the world, averaged over the views, is up. A COLMAP model (``sparse/0``) or a
   nerfstudio ``transforms.json`` next to the mesh is read for it.
2. **The mesh itself.** The largest part of a scene that faces one way is its ground,
   and walls stand perpendicular to it: ``up`` maximises the area whose normal lies
   within ``ground_deg`` of it plus half the area within ``wall_deg`` of perpendicular,
   over a dense set of directions, refined by the ground faces' mean normal. The sign
   follows the ground faces' normals when they agree (a reconstruction's normals face
   the cameras, above the ground); otherwise the side toward which the heights are
   skewed (objects stand up from the ground, nothing hangs below it).

:func:`estimate_up` tries them in that order unless ``up`` is given.

>>> import numpy as np
>>> from core.meshes import mesh_arrays
>>> import open3d as o3d
>>> box = o3d.geometry.TriangleMesh.create_box(4.0, 4.0, 0.2)   # a slab: its top is ground
>>> v, f = mesh_arrays(box)
>>> est = up_from_mesh(v @ np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]]).T, f)  # z -> -y
>>> (np.round(est.up, 6) + 0.0).tolist(), est.source
([0.0, -1.0, 0.0], 'mesh')
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from core.validate import check_unit_vector

__all__ = ["UpEstimate", "estimate_up", "up_from_cameras", "up_from_mesh", "find_camera_model"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class UpEstimate:
    """A unit ``up`` vector, where it came from (``given``, ``cameras``, ``mesh``), and how
    well it is supported: for cameras the length of the mean of their unit up vectors (1:
    all agree), for the mesh the fraction of the area that is ground or wall."""

    up: np.ndarray
    source: str
    support: float
    detail: str = ""

    def to_dict(self) -> dict:
        return {"up": [float(x) for x in self.up], "source": self.source,
                "support": float(self.support), "detail": self.detail}


def up_from_cameras(world_from_cams) -> UpEstimate:
    """Up as the mean image-up (``-y`` of each OpenCV camera) in the world."""
    ups = np.array([-np.asarray(T, np.float64)[:3, 1] for T in world_from_cams])
    if len(ups) == 0:
        raise ValueError("cameras: expected at least one camera")
    mean = ups.mean(axis=0)
    return UpEstimate(check_unit_vector(mean, "up"), "cameras", float(np.linalg.norm(mean)),
                      f"{len(ups)} cameras")


def _fibonacci(n: int) -> np.ndarray:
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    r = np.sqrt(1.0 - z * z)
    phi = np.pi * (3.0 - np.sqrt(5.0)) * k
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def up_from_mesh(vertices: np.ndarray, triangles: np.ndarray, *, ground_deg: float = 20.0,
                 wall_deg: float = 10.0, directions: int = 4000) -> UpEstimate:
    """Up from the mesh alone: its ground and walls (see the module docstring)."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(triangles, np.int64)
    if len(f) == 0:
        raise ValueError("mesh: expected triangles, got none")
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    keep = area > 0
    n, a = cross[keep] / (2.0 * area[keep, None]), area[keep]
    total = float(a.sum())
    cos_g, sin_w = np.cos(np.radians(ground_deg)), np.sin(np.radians(wall_deg))
    cand = _fibonacci(directions)
    cand = cand[cand[:, 2] >= 0]  # an axis; the sign is decided below
    # score on at most 20 000 faces drawn by area (a fixed draw: the same mesh, the same
    # answer); the refinement below uses every face
    ns, ws = n, a
    if len(n) > 20_000:
        pick = np.random.default_rng(0).choice(len(n), 20_000, p=a / total)
        ns, ws = n[pick], np.full(20_000, total / 20_000)
    score = np.zeros(len(cand))
    for i in range(0, len(cand), 256):  # (faces x 256) dot products at a time
        d = np.abs(ns @ cand[i:i + 256].T)
        score[i:i + 256] = ws @ (d > cos_g) + 0.5 * (ws @ (d < sin_w))
    axis = cand[int(np.argmax(score))]
    for _ in range(3):  # refine: the principal direction of the ground faces' normals
        ground = np.abs(n @ axis) > cos_g
        if not ground.any():
            break
        m = (n[ground] * a[ground, None]).T @ n[ground]
        w, vec = np.linalg.eigh(m)
        axis = vec[:, -1] * np.sign(vec[:, -1] @ axis or 1.0)
    dots = n @ axis
    ground = np.abs(dots) > cos_g
    walls = np.abs(dots) < sin_w
    support = float((a[ground].sum() + a[walls].sum()) / total)
    agree = float((a[ground] * np.sign(dots[ground])).sum() / max(a[ground].sum(), 1e-300))
    if abs(agree) >= 0.6:
        sign, how = np.sign(agree), f"ground normals agree ({abs(agree):.2f})"
    else:
        h = v[np.unique(f[keep])] @ axis
        skew = float(np.mean((h - h.mean()) ** 3))
        sign, how = (1.0 if skew >= 0 else -1.0), "heights skewed up from the ground"
    up = sign * axis
    return UpEstimate(up, "mesh", support,
                      f"ground {a[ground].sum() / total:.2f} and walls "
                      f"{a[walls].sum() / total:.2f} of the area; sign: {how}")


def find_camera_model(mesh_path: str | os.PathLike) -> Path | None:
    """A camera model beside the mesh: ``transforms.json``, ``sparse/0`` (COLMAP) or
    ``sparse`` in the mesh's folder or its parent; None when there is none.

    ``transforms.json`` comes first: ``scanamp reconstruct sfm`` writes it in the mesh's
    frame, while ``sparse/`` stays in COLMAP's own frame when the mesh was aligned to a
    capture's ground truth."""
    here = Path(mesh_path).resolve().parent
    for folder in (here, here.parent):
        for cand in (folder / "transforms.json", folder / "sparse" / "0", folder / "sparse"):
            if cand.is_file() or (cand.is_dir() and any(
                    (cand / n).is_file() for n in ("cameras.bin", "cameras.txt"))):
                return cand
    return None


def estimate_up(vertices: np.ndarray, triangles: np.ndarray, *, up=None,
                cameras: str | os.PathLike | None = None) -> UpEstimate:
    """Up of a mesh: ``up`` when given, else from the camera model at ``cameras`` (a COLMAP
    model or transforms.json, :func:`reconstruct.camera_files.read_cameras`), else from
    the mesh. A camera model that cannot be read is logged and the mesh used."""
    if up is not None:
        return UpEstimate(check_unit_vector(up, "up"), "given", 1.0)
    if cameras is not None:
        from core.validate import InputError
        from reconstruct.camera_files import read_cameras

        try:
            cams = read_cameras(cameras)
            est = up_from_cameras([c.world_from_cam for c in cams.values()])
            return UpEstimate(est.up, est.source, est.support, f"{est.detail} in {cameras}")
        except (InputError, ValueError) as exc:
            log.warning("up: the cameras in %s cannot be read (%s); using the mesh",
                        cameras, exc)
    return up_from_mesh(vertices, triangles)
