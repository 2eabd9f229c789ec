"""nerfstudio ``transforms.json``: export and import of cameras.

nerfstudio (and instant-ngp, gsplat, 3DGS tools) use the OpenGL camera convention:
``transform_matrix`` is ``world_from_cam`` of a camera whose x points right, y up
and z backwards. Ours is OpenCV's (x right, y down, z forward), so the camera's y and
z axes flip: ``c2w_gl = world_from_cam @ diag(1, -1, -1, 1)``. Intrinsics follow
nerfstudio's OPENCV model; its pixel centres sit at half integers like COLMAP's, so
``cx`` and ``cy`` move by +0.5 px on export. The world frame is kept (Z up).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from acquire.camera import Camera
from core.files import read_json, require, write_json
from core.validate import InputError

__all__ = ["transforms_dict", "write_transforms", "read_transforms", "GL_FROM_CV"]

GL_FROM_CV = np.diag([1.0, -1.0, -1.0, 1.0])  # flips the camera's y and z axes (involution)


def _intrinsics(cam: Camera) -> dict:
    k1, k2, p1, p2, k3 = cam.dist.tolist()
    out = {"w": cam.width, "h": cam.height, "fl_x": cam.fx, "fl_y": cam.fy,
           "cx": cam.cx + 0.5, "cy": cam.cy + 0.5, "k1": k1, "k2": k2, "p1": p1, "p2": p2}
    if k3:
        out["k3"] = k3
    return out


def transforms_dict(cameras: Sequence[Camera], image_paths: Sequence[str]) -> dict:
    """nerfstudio ``transforms.json`` content for posed cameras.

    Intrinsics shared by every camera go to the top level, others into each frame.

    Parameters
    ----------
    cameras : sequence of Camera
    image_paths : sequence of str
        Paths relative to the folder that will hold transforms.json.
    """
    if len(cameras) != len(image_paths):
        raise ValueError(f"image_paths: expected {len(cameras)} paths (one per camera), "
                         f"got {len(image_paths)}")
    if not cameras:
        raise ValueError("cameras: expected at least one camera, got none")
    intr = [_intrinsics(c) for c in cameras]
    shared = {k: v for k, v in intr[0].items() if all(i.get(k) == v for i in intr)}
    out = {"camera_model": "OPENCV", **shared, "frames": []}
    for cam, path, i in zip(cameras, image_paths, intr, strict=False):
        frame = {"file_path": str(path),
                 "transform_matrix": (cam.world_from_cam @ GL_FROM_CV).tolist()}
        frame.update({k: v for k, v in i.items() if k not in shared})
        out["frames"].append(frame)
    return out


def write_transforms(path: str | os.PathLike, cameras: Sequence[Camera],
                     image_paths: Sequence[str]) -> Path:
    """Write ``transforms.json`` atomically (see :func:`transforms_dict`)."""
    return write_json(path, transforms_dict(cameras, image_paths))


def read_transforms(path: str | os.PathLike) -> tuple[list[Camera], list[str]]:
    """Read a ``transforms.json`` into OpenCV cameras and their image paths.

    Raises InputError naming the file and field when something is missing.
    """
    data = read_json(path)
    if not isinstance(data, dict):
        raise InputError("expected a JSON object", path=path)
    model = data.get("camera_model", "OPENCV")
    if model not in ("OPENCV", "PINHOLE", "SIMPLE_PINHOLE"):
        raise InputError(f"expected OPENCV, PINHOLE or SIMPLE_PINHOLE, got {model!r}",
                         path=path, field="camera_model")
    frames = require(data, "frames", list, path=path)
    cameras, paths = [], []
    for i, frame in enumerate(frames):
        pre = f"frames[{i}]"
        if not isinstance(frame, dict):
            raise InputError("expected an object", path=path, field=pre)

        def get(key, default=..., frame=frame, pre=pre):
            if key in frame:
                return require(frame, key, (int, float), path=path, prefix=pre)
            return require(data, key, (int, float), path=path, default=default)

        fp = require(frame, "file_path", str, path=path, prefix=pre)
        M = np.asarray(require(frame, "transform_matrix", list, path=path, prefix=pre), float)
        if M.shape != (4, 4):
            raise InputError(f"expected a 4x4 matrix, got shape {M.shape}", path=path,
                             field=f"{pre}.transform_matrix")
        world_from_cam = M @ GL_FROM_CV
        R, c = world_from_cam[:3, :3], world_from_cam[:3, 3]
        T = np.eye(4)
        T[:3, :3] = R.T
        T[:3, 3] = -R.T @ c
        dist = [get(k, 0.0) for k in ("k1", "k2", "p1", "p2", "k3")]
        fx = get("fl_x")
        try:
            cam = Camera(int(get("w")), int(get("h")), fx, get("fl_y", fx), get("cx") - 0.5,
                         get("cy") - 0.5, np.array(dist), T)
        except ValueError as exc:
            raise InputError(str(exc), path=path, field=pre) from None
        cameras.append(cam)
        paths.append(fp)
    return cameras, paths
