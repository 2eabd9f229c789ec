"""A folder of photos as cameras write them, made ready for COLMAP.

Phones store a portrait photo as landscape pixels plus an EXIF orientation tag, mix
landscape and portrait shots in one folder, and record the focal length in the EXIF
block. COLMAP's reader ignores the tag, so the same photo would have two sizes in one
pipeline (the sparse stage's and the dense stage's). Here every photo is read upright
(:func:`core.io.image.read_image`), and:

- :func:`scan_photos` reads each header (size, orientation, EXIF focal length) and
  refuses a missing, unreadable or truncated file by name;
- :func:`camera_groups` gives one COLMAP camera per distinct size and focal length
  (``auto``), one for all (``single``) or one per photo (``per-image``);
- :func:`upright_folder` fills a folder with what COLMAP reads: a link to each photo that
  is already upright and 8-bit, an upright 8-bit copy (same name and format) of the
  others.

>>> groups = camera_groups({"a.jpg": PhotoInfo(40, 30, 1, 33.0),
...                         "b.jpg": PhotoInfo(30, 40, 6, 33.0),
...                         "c.jpg": PhotoInfo(40, 30, 1, 33.0)}, "auto")
>>> [(g.names, g.width, g.height) for g in groups]
[(['a.jpg', 'c.jpg'], 40, 30), (['b.jpg'], 30, 40)]
"""

from __future__ import annotations

import logging
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from core.io.image import IMAGE_SUFFIXES, PhotoInfo, photo_info, read_image, to_uint8
from core.progress import track
from core.validate import check_choice

__all__ = ["CAMERA_MODES", "CameraGroup", "list_photos", "scan_photos", "camera_groups",
           "upright_folder"]

log = logging.getLogger(__name__)

CAMERA_MODES = ("auto", "single", "per-image")


@dataclass(frozen=True)
class CameraGroup:
    """Photos that share one camera: their names, upright size and EXIF focal length
    (pixels; None when the EXIF block has none)."""

    names: list
    width: int
    height: int
    focal_px: float | None


def list_photos(folder: str | os.PathLike) -> list[str]:
    """Names of the photos (JPEG, PNG, TIFF; any case) directly in ``folder``, sorted."""
    folder = Path(folder)
    return sorted(p.name for p in folder.iterdir()
                  if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES)


def scan_photos(folder: str | os.PathLike, names: Sequence[str]) -> dict[str, PhotoInfo]:
    """Header of every photo (upright size, orientation, EXIF focal length).

    Raises
    ------
    InputError
        Naming the first photo that is missing, unreadable or truncated.
    """
    folder = Path(folder)
    return {n: photo_info(folder / n) for n in names}


def camera_groups(infos: Mapping[str, PhotoInfo], mode: str = "auto") -> list[CameraGroup]:
    """Photos grouped into cameras: per distinct (size, focal length) for ``auto``, all
    in one for ``single`` (they must share a size), one per photo for ``per-image``.
    Groups come in the order of their first photo."""
    check_choice(mode, "camera_mode", CAMERA_MODES)
    groups: dict = {}
    for name, info in infos.items():
        focal = None if info.focal_px is None else round(info.focal_px, 1)
        key = {"auto": (info.width, info.height, focal), "single": 0,
               "per-image": name}[mode]
        groups.setdefault(key, []).append(name)
    out = []
    for names in groups.values():
        first = infos[names[0]]
        if mode == "single":
            odd = [f"{n} ({infos[n].width}x{infos[n].height})" for n in names
                   if (infos[n].width, infos[n].height) != (first.width, first.height)]
            if odd:
                raise ValueError(f"camera_mode: 'single' needs one image size, but "
                                 f"{names[0]} is {first.width}x{first.height} and "
                                 f"{', '.join(odd[:3])}{' ...' if len(odd) > 3 else ''}; "
                                 f"use 'auto'")
        out.append(CameraGroup(list(names), first.width, first.height, first.focal_px))
    return out


def upright_folder(folder: str | os.PathLike, names: Sequence[str],
                   infos: Mapping[str, PhotoInfo], dest: str | os.PathLike) -> Path:
    """Fill ``dest`` (existing, empty) with what COLMAP reads for each photo: a link when
    it is stored upright in 8 bits, else an upright 8-bit copy under the same name."""
    import cv2

    folder, dest = Path(folder), Path(dest)
    for name in track(names, "photos read upright", total=len(names)):
        src, out = folder / name, dest / name
        out.parent.mkdir(parents=True, exist_ok=True)  # capture frames sit in images/
        if infos[name].orientation == 1 and _is_8bit(src):
            try:
                os.symlink(src.resolve(), out)
                continue
            except OSError:  # no symlinks here (some file systems): copy below
                pass
        img = to_uint8(read_image(src))
        if img.ndim == 3:
            img = cv2.cvtColor(img, cv2.COLOR_RGBA2BGR if img.shape[2] == 4
                               else cv2.COLOR_RGB2BGR)
        params = [cv2.IMWRITE_JPEG_QUALITY, 95] if out.suffix.lower() in (".jpg", ".jpeg") \
            else []
        if not cv2.imwrite(str(out), img, params):
            raise RuntimeError(f"OpenCV failed to write {out}")
    return dest


def _is_8bit(path: Path) -> bool:
    if path.suffix.lower() in (".jpg", ".jpeg"):
        return True
    from PIL import Image

    with Image.open(path) as im:
        return im.mode in ("L", "RGB", "P")
