"""What the views saw, and a precision that needs no truth.

What a view saw is a mask of its pixels (:func:`seen_masks`): for the truth-free
precision, where it has a depth that another view confirmed and fusion kept; for the
unseen trim, where PatchMatch found a plane at all (a faint surface that no second view
confirms still gets one; a plain backdrop does not). A point or mesh vertex that falls,
in several views, on pixels where they saw nothing lies where those views looked through
empty space (or through a surface none of them could match). The free-space trim of
:func:`reconstruct.mvs.fusion.poisson_surface` only counts surfaces seen *behind* a
vertex, so it keeps what hangs in front of a plain backdrop: depths that a matching
window carried off an object's edge onto the backdrop beside it (and another view's
window carried there too), and the membrane Poisson stretches across a gap (fins between
columns, skirts below an object).

:func:`seen_precision` draws a mesh into every view and reports the share of its pixels
on what the view saw: the mesh's precision judged by the views alone, to set beside the
coverage wherever coverage is reported.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from acquire.camera import Camera
from core.validate import check_array

__all__ = ["seen_masks", "unseen_votes", "seen_precision", "pixel_lookup"]


def pixel_lookup(cam: Camera, X: np.ndarray):
    """The pinhole pixel (nearest) each point falls on: indices of the points in front of
    the camera and inside its image, their pixel columns and rows, and every point's z."""
    Y = cam.to_camera(X)
    z = Y[:, 2]
    ok = z > 1e-12
    zs = np.where(ok, z, 1.0)
    u = np.rint(cam.fx * Y[:, 0] / zs + cam.cx).astype(np.int64)
    v = np.rint(cam.fy * Y[:, 1] / zs + cam.cy).astype(np.int64)
    ok &= (u >= 0) & (v >= 0) & (u < cam.width) & (v < cam.height)
    idx = np.nonzero(ok)[0]
    return idx, u[idx], v[idx], z


def seen_masks(confirmed: Sequence[np.ndarray], *, grow: int = 2) -> list[np.ndarray]:
    """(H, W) bool per view: the pixels where the view itself has a depth (``confirmed``:
    fusion's kept pixels, :attr:`reconstruct.mvs.fusion.FusedPoints.masks`, or every
    pixel with a depth), grown by ``grow`` pixels (fusion erodes its masks at depth
    edges, and a surface seen at grazing angle falls a pixel or two off).

    Only a view's own depths say what it saw: the fused points of all views splatted into
    it would let every fused point vouch for itself."""
    import cv2

    out = []
    k = np.ones((2 * grow + 1, 2 * grow + 1), np.uint8) if grow > 0 else None
    for i, m in enumerate(confirmed):
        m = np.asarray(m)
        if m.ndim != 2:
            raise ValueError(f"confirmed[{i}]: expected an (H, W) mask, got shape {m.shape}")
        m = m.astype(np.uint8)
        out.append((cv2.dilate(m, k) if k is not None else m) > 0)
    return out


def unseen_votes(vertices: np.ndarray, cameras: Sequence[Camera],
                 seen: Sequence[np.ndarray]) -> np.ndarray:
    """(n,) int32: in how many views each vertex falls inside the image, in front of the
    camera, on a pixel (nearest) where the view saw nothing (``seen`` False)."""
    V = check_array(vertices, "vertices", shape=(None, 3))
    votes = np.zeros(len(V), np.int32)
    for cam, mask in zip(cameras, seen, strict=True):
        idx, u, v, _ = pixel_lookup(cam, V)
        votes[idx[~mask[v, u]]] += 1
    return votes


def seen_precision(mesh, cameras: Sequence[Camera], seen: Sequence[np.ndarray], *,
                   tolerance: int = 2):
    """The mesh drawn into every view against what the view saw
    (:func:`reconstruct.evaluation.masks.mask_scores`): ``mean_inside`` is the truth-free
    precision, ``mean_covers`` the share of the seen pixels the mesh covers. ``tolerance``
    pixels of boundary slack, as for silhouettes."""
    from reconstruct.evaluation.masks import mask_scores

    return mask_scores(mesh, cameras, seen, dilate=tolerance)
