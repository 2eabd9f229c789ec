"""Image files: the one place that knows image formats (PNG, JPEG, TIFF; 8 or 16 bit).

Colour images are returned in RGB order. Every writer is atomic.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from core.files import atomic_file
from core.validate import InputError

__all__ = ["read_image", "write_image"]


def read_image(path: str | os.PathLike, *, grayscale: bool = False) -> np.ndarray:
    """Read an image as stored (uint8 or uint16; RGB order for colour images)."""
    import cv2

    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", path=path)
    flag = cv2.IMREAD_GRAYSCALE if grayscale else cv2.IMREAD_UNCHANGED
    img = cv2.imread(str(path), flag | (cv2.IMREAD_ANYDEPTH if not grayscale else 0))
    if img is None:
        raise InputError("unreadable image (corrupt or unsupported format)", path=path)
    if img.ndim == 3 and img.shape[2] >= 3:
        img = np.ascontiguousarray(img[..., 2::-1] if img.shape[2] == 3 else
                                   img[..., [2, 1, 0, 3]])
    return img


def write_image(path: str | os.PathLike, image: np.ndarray) -> Path:
    """Write a uint8/uint16 image (RGB order for colour) atomically; PNG is lossless."""
    import cv2

    img = np.asarray(image)
    if img.dtype not in (np.uint8, np.uint16):
        raise ValueError(f"image: expected uint8 or uint16, got {img.dtype}")
    if img.ndim == 3 and img.shape[2] == 3:
        img = np.ascontiguousarray(img[..., ::-1])
    with atomic_file(path) as tmp:
        if not cv2.imwrite(str(tmp), img):
            raise RuntimeError(f"OpenCV failed to write {path}")
    return Path(path)
