"""Calibration files: the YAML that ``cv2.FileStorage`` reads and writes.

A stereo pair's keys (OpenCV matrices, as written by ``cv2.FileStorage.write``):

- ``K1``, ``K2``: 3x3 camera matrices of the left and right cameras (``M1``, ``M2``, the
  names OpenCV's ``stereo_calib`` sample writes, are read too);
- ``D1``, ``D2``: distortion ``k1 k2 p1 p2 k3`` (1x5 or 5x1; longer vectors are cut
  to the first five, shorter ones padded with zeros);
- ``R`` (3x3), ``T`` (3x1, metres): ``right_from_left``, as from ``cv2.stereoCalibrate``;
- ``image_size``: ``[width, height]`` (a 1x2 or 2x1 matrix, or a sequence);
- optional ``rms``: reprojection RMS in pixels.

One camera's keys are those of OpenCV's ``calibration`` sample, so other tools read it:
``camera_matrix`` (3x3), ``distortion_coefficients`` (1x5, ``k1 k2 p1 p2 k3``),
``image_width``, ``image_height``, optional ``avg_reprojection_error``.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from acquire.camera import Camera
from core.files import atomic_file
from core.validate import InputError
from reconstruct.calibration.rectify import StereoCalibration

__all__ = ["read_stereo_yaml", "write_stereo_yaml", "read_camera_yaml", "write_camera_yaml"]

_SHAPES = {"K1": (3, 3), "K2": (3, 3), "R": (3, 3), "T": (3,), "D1": (5,), "D2": (5,)}
_ALIASES = {"K1": "M1", "K2": "M2"}  # OpenCV's stereo_calib sample


def write_stereo_yaml(path: str | os.PathLike, calib: StereoCalibration) -> Path:
    """Write ``calib`` with cv2.FileStorage (atomically)."""
    import cv2

    path = Path(path)
    with atomic_file(path) as tmp:
        fs = cv2.FileStorage(str(tmp), cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_FORMAT_YAML)
        for k in ("K1", "D1", "K2", "D2", "R"):
            fs.write(k, np.asarray(getattr(calib, k), np.float64).reshape(
                (1, 5) if k.startswith("D") else (3, 3)))
        fs.write("T", np.asarray(calib.T, np.float64).reshape(3, 1))
        fs.write("image_size", np.array([calib.image_size], np.int32))
        if calib.rms is not None:
            fs.write("rms", float(calib.rms))
        fs.release()
    return path


def _open(path: Path):
    import cv2

    if not path.is_file():
        raise InputError("file not found", path=path)
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except cv2.error as exc:
        raise InputError(f"not a cv2.FileStorage YAML/XML file ({exc.msg.strip()})",
                         path=path) from None
    except SystemError:  # cv2's binding raises this on some malformed files (JSON)
        raise InputError("not a cv2.FileStorage YAML/XML file (unreadable)", path=path) from None
    if not fs.isOpened():
        raise InputError("not a cv2.FileStorage YAML/XML file", path=path)
    return fs


def _has(fs, key: str) -> bool:
    node = fs.getNode(key)
    return not (node.empty() or node.isNone())


def _matrix(fs, path: Path, key: str, shape: tuple, *, vector5: bool = False) -> np.ndarray:
    """The matrix ``key``, reshaped to ``shape`` (a distortion vector cut or padded to 5)."""
    if not _has(fs, key):
        raise InputError("missing", path=path, field=key)
    m = fs.getNode(key).mat()
    if m is None:
        raise InputError("expected a matrix (!!opencv-matrix)", path=path, field=key)
    m = np.asarray(m, np.float64)
    if vector5:
        flat = m.ravel()
        m = np.concatenate([flat, np.zeros(5)])[:5] if flat.size < 5 else flat[:5]
    elif len(shape) == 1:
        m = m.ravel()
    if m.shape != shape:
        raise InputError(f"expected shape {shape}, got {m.shape}", path=path, field=key)
    if not np.all(np.isfinite(m)):
        raise InputError("expected finite values", path=path, field=key)
    return m


def read_stereo_yaml(path: str | os.PathLike) -> StereoCalibration:
    """Read a stereo calibration; InputError naming the file and the key at fault."""
    path = Path(path)
    fs = _open(path)
    out = {}
    try:
        for key, shape in _SHAPES.items():
            alias = _ALIASES.get(key)
            name = alias if alias and not _has(fs, key) and _has(fs, alias) else key
            out[key] = _matrix(fs, path, name, shape, vector5=key.startswith("D"))
        node = fs.getNode("image_size")
        if node.empty() or node.isNone():
            raise InputError("missing", path=path, field="image_size")
        if node.isSeq():
            size = [node.at(i).real() for i in range(node.size())]
        else:
            m = node.mat()
            size = [] if m is None else np.asarray(m).ravel().tolist()
        if len(size) != 2 or min(size) <= 0:
            raise InputError(f"expected [width, height], got {size}", path=path,
                             field="image_size")
        rms_node = fs.getNode("rms")
        rms = None if rms_node.empty() or rms_node.isNone() else float(rms_node.real())
    finally:
        fs.release()
    try:
        return StereoCalibration(out["K1"], out["D1"], out["K2"], out["D2"], out["R"], out["T"],
                                 (int(size[0]), int(size[1])), rms=rms)
    except ValueError as exc:
        raise InputError(str(exc), path=path) from None


def write_camera_yaml(path: str | os.PathLike, camera: Camera, *, rms: float | None = None
                      ) -> Path:
    """Write one camera's intrinsics with cv2.FileStorage (atomically), with the keys of
    OpenCV's calibration sample."""
    import cv2

    path = Path(path)
    with atomic_file(path) as tmp:
        fs = cv2.FileStorage(str(tmp), cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_FORMAT_YAML)
        fs.write("image_width", int(camera.width))
        fs.write("image_height", int(camera.height))
        fs.write("camera_matrix", np.asarray(camera.K, np.float64))
        fs.write("distortion_coefficients", np.asarray(camera.dist, np.float64).reshape(1, 5))
        if rms is not None:
            fs.write("avg_reprojection_error", float(rms))
        fs.release()
    return path


def read_camera_yaml(path: str | os.PathLike) -> Camera:
    """Read one camera's intrinsics (:func:`write_camera_yaml`'s keys) as a Camera."""
    path = Path(path)
    fs = _open(path)
    try:
        K = _matrix(fs, path, "camera_matrix", (3, 3))
        D = _matrix(fs, path, "distortion_coefficients", (5,), vector5=True)
        size = []
        for key in ("image_width", "image_height"):
            if not _has(fs, key):
                raise InputError("missing", path=path, field=key)
            v = fs.getNode(key).real()
            if not v > 0:
                raise InputError(f"expected a positive size, got {v}", path=path, field=key)
            size.append(int(v))
    finally:
        fs.release()
    try:
        return Camera(size[0], size[1], K[0, 0], K[1, 1], K[0, 2], K[1, 2], D)
    except ValueError as exc:
        raise InputError(str(exc), path=path) from None
