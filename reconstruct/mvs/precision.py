"""What the views saw, and a precision that needs no truth.

A view saw a surface at the pixels where some fused point falls (:func:`seen_masks`: the
fused points of every view splatted into it, grown by a few pixels to close the gaps
between splats). A mesh vertex that falls on pixels where nothing was seen, in several
views, lies where those views looked through empty space (or through a surface no view
could match): the free-space trim of :func:`reconstruct.mvs.fusion.poisson_surface` only
sees surfaces *behind* a vertex, so it keeps a membrane that Poisson stretches across a
gap against a plain backdrop (fins between columns, skirts below an object).

:func:`seen_precision` draws a mesh into every view and reports the share of its pixels
on what the view saw: the mesh's precision judged by the views alone, to set beside the
coverage wherever coverage is reported.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from acquire.camera import Camera
from core.validate import check_array

__all__ = ["seen_masks", "unseen_votes", "seen_precision"]


def seen_masks(points: np.ndarray, cameras: Sequence[Camera], *, grow: int = 2,
               max_points: int = 1_000_000, seed: int = 0) -> list[np.ndarray]:
    """(H, W) bool per camera: the pixels onto which some point projects (in front of the
    camera, nearest pixel), grown by ``grow`` pixels.

    Parameters
    ----------
    points : (n, 3) float
        Fused points, world frame.
    cameras : sequence of Camera
        Pinhole cameras (distortion is ignored: the working cameras of the depth maps).
    grow : int
        Dilation radius in pixels: fused points of a view seen from another view at a
        similar distance land about a pixel apart.
    max_points : int
        Above this many points a seeded subsample is splatted (bounds the cost on large
        sets; the grown mask closes the gaps it leaves).
    """
    import cv2

    points = check_array(points, "points", shape=(None, 3))
    if len(points) > max_points:
        keep = np.sort(np.random.default_rng(seed).choice(len(points), max_points,
                                                          replace=False))
        points = points[keep]
    k = np.ones((2 * grow + 1, 2 * grow + 1), np.uint8) if grow > 0 else None
    out = []
    for cam in cameras:
        Y = points @ cam.cam_from_world[:3, :3].T + cam.cam_from_world[:3, 3]
        z = Y[:, 2]
        ok = z > 1e-12
        zs = np.where(ok, z, 1.0)
        u = np.rint(cam.fx * Y[:, 0] / zs + cam.cx).astype(np.int64)
        v = np.rint(cam.fy * Y[:, 1] / zs + cam.cy).astype(np.int64)
        ok &= (u >= 0) & (v >= 0) & (u < cam.width) & (v < cam.height)
        m = np.zeros((cam.height, cam.width), np.uint8)
        m[v[ok], u[ok]] = 1
        if k is not None:
            m = cv2.dilate(m, k)
        out.append(m > 0)
    return out


def unseen_votes(vertices: np.ndarray, cameras: Sequence[Camera],
                 seen: Sequence[np.ndarray], *, margin: int = 0) -> np.ndarray:
    """(n,) int32: in how many views each vertex falls inside the image (at least
    ``margin`` pixels from its border), in front of the camera, on a pixel where the view
    saw nothing (``seen`` False)."""
    V = check_array(vertices, "vertices", shape=(None, 3))
    votes = np.zeros(len(V), np.int32)
    for cam, mask in zip(cameras, seen, strict=True):
        Y = V @ cam.cam_from_world[:3, :3].T + cam.cam_from_world[:3, 3]
        z = Y[:, 2]
        ok = z > 1e-12
        zs = np.where(ok, z, 1.0)
        u = np.rint(cam.fx * Y[:, 0] / zs + cam.cx).astype(np.int64)
        v = np.rint(cam.fy * Y[:, 1] / zs + cam.cy).astype(np.int64)
        ok &= (u >= margin) & (v >= margin) & (u < cam.width - margin) & \
            (v < cam.height - margin)
        idx = np.nonzero(ok)[0]
        votes[idx[~mask[v[idx], u[idx]]]] += 1
    return votes


def seen_precision(mesh, cameras: Sequence[Camera], seen: Sequence[np.ndarray], *,
                   tolerance: int = 2):
    """The mesh drawn into every view against what the view saw
    (:func:`reconstruct.evaluation.masks.mask_scores`): ``mean_inside`` is the truth-free
    precision, ``mean_covers`` the share of the seen pixels the mesh covers. ``tolerance``
    pixels of boundary slack, as for silhouettes."""
    from reconstruct.evaluation.masks import mask_scores

    return mask_scores(mesh, cameras, seen, dilate=tolerance)
