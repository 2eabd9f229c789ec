"""Image files: the one place that knows image formats (PNG, JPEG, TIFF; 8 or 16 bit).

Colour images are returned in RGB order. Every writer is atomic.

Photos are read as every viewer shows them: the EXIF orientation tag (which phones set
instead of rotating the pixels) is applied by :func:`read_image`, always, so that one
image has one size wherever it is read. (OpenCV applies the tag for some read flags and
not for others: ``IMREAD_UNCHANGED`` ignores it, ``IMREAD_COLOR`` applies it.)
:func:`photo_info` gives the upright size and the focal length in pixels from the EXIF
block without decoding the pixels.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from core.files import atomic_file
from core.validate import InputError

__all__ = ["read_image", "write_image", "PhotoInfo", "photo_info", "to_uint8",
           "IMAGE_SUFFIXES"]

#: the photo formats we read (any case): JPEG, PNG, TIFF
IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".tif", ".tiff")

_ORIENTATION, _EXIF_IFD = 0x0112, 0x8769
_FOCAL_35MM, _FOCAL_MM = 0xA405, 0x920A
_FOCAL_PLANE_XRES, _FOCAL_PLANE_UNIT = 0xA20E, 0xA210


@dataclass(frozen=True)
class PhotoInfo:
    """What a photo's header says.

    Attributes
    ----------
    width, height : int
        Upright size (after the EXIF orientation), pixels.
    orientation : int
        EXIF orientation tag, 1 (as stored) to 8; 1 without EXIF.
    focal_px : float or None
        Focal length in pixels of the upright image, from ``FocalLengthIn35mmFilm``
        (``f35 * diagonal / 43.27 mm``, the diagonal of 36 x 24 mm film, as COLMAP
        reads it) or from ``FocalLength`` with the focal
        plane resolution; None when the EXIF block gives neither.
    """

    width: int
    height: int
    orientation: int = 1
    focal_px: float | None = None


def _exif(path: Path):
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as im:
            return im.size, im.getexif()
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError) as e:
        raise InputError(f"unreadable image ({e})", path=path) from None


def _orientation(exif) -> int:
    o = exif.get(_ORIENTATION, 1) if exif is not None else 1
    try:
        o = int(o)
    except (TypeError, ValueError):
        return 1
    return o if 1 <= o <= 8 else 1


def _focal_px(exif, stored_size: tuple[int, int], upright: tuple[int, int]) -> float | None:
    if exif is None:
        return None
    sub = exif.get_ifd(_EXIF_IFD)
    try:
        f35 = float(sub.get(_FOCAL_35MM) or 0)
        if f35 > 0:  # equivalent focal length: by the diagonal of 36 x 24 mm film
            return f35 * float(np.hypot(*upright)) / float(np.hypot(36.0, 24.0))
        fmm = float(sub.get(_FOCAL_MM) or 0)
        xres = float(sub.get(_FOCAL_PLANE_XRES) or 0)
        unit = {2: 25.4, 3: 10.0, 4: 1.0}.get(int(sub.get(_FOCAL_PLANE_UNIT) or 2), 25.4)
        if fmm > 0 and xres > 0:
            # the resolution is given for the sensor's full image; ExifImageWidth may be
            # the original's width while the pixels were resized
            full = float(sub.get(0xA002) or stored_size[0])
            return fmm * xres / unit * stored_size[0] / full
    except (TypeError, ValueError, ZeroDivisionError):
        return None
    return None


def photo_info(path: str | os.PathLike) -> PhotoInfo:
    """Upright size, EXIF orientation and focal length (pixels) of an image file.

    Raises
    ------
    InputError
        The file is missing, not an image, or a JPEG that ends early (truncated).
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", path=path)
    size, exif = _exif(path)
    _check_complete(path)
    o = _orientation(exif)
    upright = size[::-1] if o >= 5 else size
    return PhotoInfo(int(upright[0]), int(upright[1]), o, _focal_px(exif, size, upright))


def _check_complete(path: Path) -> None:
    """A JPEG must end with its end-of-image marker: decoders fill a truncated file
    with grey and only warn."""
    if path.suffix.lower() not in (".jpg", ".jpeg"):
        return
    with open(path, "rb") as f:
        f.seek(0, os.SEEK_END)
        n = f.tell()
        f.seek(max(0, n - 4096))
        tail = f.read()
    if b"\xff\xd9" not in tail:
        raise InputError("truncated JPEG (no end-of-image marker)", path=path)


def _apply_orientation(img: np.ndarray, o: int) -> np.ndarray:
    """Pixels as stored -> upright, for EXIF orientation ``o`` (1..8)."""
    if o == 1:
        return img
    ops = {2: lambda a: a[:, ::-1], 3: lambda a: a[::-1, ::-1], 4: lambda a: a[::-1],
           5: lambda a: a.swapaxes(0, 1), 6: lambda a: a.swapaxes(0, 1)[:, ::-1],
           7: lambda a: a.swapaxes(0, 1)[::-1, ::-1], 8: lambda a: a.swapaxes(0, 1)[::-1]}
    return np.ascontiguousarray(ops[o](img))


def to_uint8(img: np.ndarray) -> np.ndarray:
    """8-bit copy of a uint8/uint16/float image (16 bit: the top byte, rounded)."""
    if img.dtype == np.uint8:
        return img
    if img.dtype == np.uint16:
        return ((img.astype(np.uint32) + 128) // 257).astype(np.uint8)
    return np.clip(np.rint(np.asarray(img, float) * 255.0), 0, 255).astype(np.uint8)


def read_image(path: str | os.PathLike, *, grayscale: bool = False) -> np.ndarray:
    """Read an image upright (EXIF orientation applied): uint8 or uint16 as stored, RGB
    order for colour images; ``grayscale`` gives one channel of the stored depth.

    Raises
    ------
    InputError
        Missing, unreadable, or a truncated JPEG.
    """
    import cv2

    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", path=path)
    orientation = 1
    if path.suffix.lower() in IMAGE_SUFFIXES:  # may carry EXIF (JPEG, TIFF, PNG eXIf)
        orientation = _orientation(_exif(path)[1])
        _check_complete(path)
    flag = cv2.IMREAD_UNCHANGED | cv2.IMREAD_IGNORE_ORIENTATION
    img = cv2.imread(str(path), flag)
    if img is None:
        raise InputError("unreadable image (corrupt or unsupported format)", path=path)
    if img.ndim == 3 and img.shape[2] >= 3:
        img = np.ascontiguousarray(img[..., 2::-1] if img.shape[2] == 3 else
                                   img[..., [2, 1, 0, 3]])
    if grayscale and img.ndim == 3:
        img = cv2.cvtColor(np.ascontiguousarray(img[..., :3]), cv2.COLOR_RGB2GRAY)
    return _apply_orientation(img, orientation)


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
