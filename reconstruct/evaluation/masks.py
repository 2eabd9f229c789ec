"""A mesh drawn into every view against a mask per view: how much of the mesh falls inside
the masks (precision) and how much of the masks it covers (recall).

With silhouettes as the masks it is the classic score of a ring of an object on a plain
backdrop (the mesh must lie inside every silhouette, and fill it). With the pixels where
the view itself saw a surface (a confirmed depth) it is a precision that needs no truth:
surface drawn where the view saw nothing was not seen there
(:func:`reconstruct.mvs.precision.seen_precision`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from acquire.camera import Camera

__all__ = ["MaskScores", "mask_scores", "mesh_hits"]


@dataclass
class MaskScores:
    """Per view: the mesh's pixels inside the mask over its pixels (``inside``), and the
    mask's pixels the mesh covers over the mask's pixels (``covers``); their means."""

    inside: list[float]
    covers: list[float]

    @property
    def mean_inside(self) -> float:
        return float(np.mean(self.inside)) if self.inside else 0.0

    @property
    def mean_covers(self) -> float:
        return float(np.mean(self.covers)) if self.covers else 0.0


def mesh_hits(mesh, cameras: Sequence[Camera]) -> list[np.ndarray]:
    """(H, W) bool per camera: the pixels whose ray meets the mesh (an open3d
    TriangleMesh, legacy), cast through the pinhole model (no distortion)."""
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    if len(mesh.triangles):
        scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(mesh))
    out = []
    for cam in cameras:
        if not len(mesh.triangles):
            out.append(np.zeros((cam.height, cam.width), bool))
            continue
        rays = o3d.t.geometry.RaycastingScene.create_rays_pinhole(
            o3d.core.Tensor(np.asarray(cam.K, np.float64)),
            o3d.core.Tensor(np.asarray(cam.cam_from_world, np.float64)), cam.width, cam.height)
        out.append(np.isfinite(scene.cast_rays(rays)["t_hit"].numpy()))
    return out


def mask_scores(mesh, cameras: Sequence[Camera], masks: Sequence[np.ndarray], *,
                dilate: int = 0) -> MaskScores:
    """The mesh drawn into each camera against that camera's mask.

    Parameters
    ----------
    mesh : open3d TriangleMesh
        In the cameras' world frame.
    cameras : sequence of Camera
    masks : sequence of (H, W) bool
        One per camera, at its size.
    dilate : int
        Pixels the masks are grown by first (a square of side ``2 dilate + 1``): the
        tolerance of a boundary drawn from a threshold or a depth map.

    Returns
    -------
    MaskScores
        A view whose mesh draws no pixel counts 1 inside (nothing outside), a view with
        an empty mask 1 covered.
    """
    import cv2

    if len(masks) != len(cameras):
        raise ValueError(f"masks: expected one per camera ({len(cameras)}), got {len(masks)}")
    inside, covers = [], []
    for cam, hit, mask in zip(cameras, mesh_hits(mesh, cameras), masks, strict=True):
        mask = np.asarray(mask, bool)
        if mask.shape != hit.shape:
            raise ValueError(f"masks: expected ({cam.height}, {cam.width}) for a camera of "
                             f"that size, got {mask.shape}")
        if dilate > 0:
            k = np.ones((2 * dilate + 1, 2 * dilate + 1), np.uint8)
            mask = cv2.dilate(mask.astype(np.uint8), k) > 0
        both = int((hit & mask).sum())
        inside.append(both / hit.sum() if hit.any() else 1.0)
        covers.append(both / mask.sum() if mask.any() else 1.0)
    return MaskScores([float(x) for x in inside], [float(x) for x in covers])
