"""Known cameras from the files other tools write: a COLMAP model, a nerfstudio
``transforms.json``, a Middlebury ``*_par.txt``, an OpenMVS ``.mvs`` scene, a Meshroom
``cameras.sfm``, Strecha's ``.camera`` files.

:func:`read_cameras` gives ``{image name: Camera}`` in scanamp's (OpenCV) convention,
whatever the source: turntables, robot arms and calibrated rigs know their poses, and
textureless objects that SIFT cannot register need them.

Formats
-------
COLMAP model
    A folder with ``cameras.bin``/``images.bin`` (binary) or ``cameras.txt``/
    ``images.txt`` (text), or one of those files. Models: those of
    :data:`CAMERA_MODELS`.
nerfstudio ``transforms.json``
    Read by :func:`acquire.sfm.nerfstudio.read_transforms` (OpenGL camera axes).
Middlebury ``*_par.txt``
    A count, then one line per image: ``name k11..k33 r11..r33 t1 t2 t3`` with the
    projection ``K [R | t]`` (``x_cam = R X + t``), pixel centres at integers.
Strecha ``*.camera`` (the Strecha et al. 2008 benchmark; a folder of them, or one file)
    Nine lines per file, ``NAME.camera`` being the camera of image ``NAME``: ``K`` (three
    rows), the radial distortion (one row of three, zero for undistorted images), ``R``
    (three rows), the camera centre ``C`` in world coordinates, ``width height``. ``R``
    is ``world_from_cam``: its columns are the camera's x, y, z axes (OpenCV: right,
    down, forward) in the world, so ``cam_from_world = [R^T | -R^T C]``; pixel centres
    at integers. Checked on the benchmark's photos: SIFT matches of two fountain-P11
    views triangulate to 0.15 px under this reading and to 100+ px under the others
    (``tests/test_camera_files_strecha.py`` keeps some of those matches as its oracle).
OpenMVS ``*.mvs`` and Meshroom ``*.sfm``
    Read by :mod:`core.io.scene_cameras` (its docstring gives both layouts). An OpenMVS
    camera stored without its image size (``K`` normalised by the larger side) takes the
    size from ``sizes``, else a nominal 1000 x 1000 (its pose is exact either way).

>>> import tempfile, pathlib
>>> p = pathlib.Path(tempfile.mkdtemp()) / "toy_par.txt"
>>> _ = p.write_text("1\\nimg.png 500 0 319.5 0 500 239.5 0 0 1 1 0 0 0 1 0 0 0 1 0 0 2\\n")
>>> cams = read_cameras(p, sizes={"img.png": (640, 480)})
>>> cams["img.png"].center.round(3).tolist(), cams["img.png"].fx
([0.0, 0.0, -2.0], 500.0)
"""

from __future__ import annotations

import logging
import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from acquire.camera import Camera
from core.validate import InputError, check_choice

__all__ = ["read_cameras", "CAMERA_FILE_FORMATS", "CAMERA_MODELS", "colmap_params_from_camera",
           "camera_from_colmap", "image_cam_from_world", "read_strecha_camera",
           "write_strecha_camera"]

# models we can convert to an OpenCV camera for the dense stage; parameter names in order
CAMERA_MODELS = {
    "SIMPLE_PINHOLE": ("f", "cx", "cy"),
    "PINHOLE": ("fx", "fy", "cx", "cy"),
    "SIMPLE_RADIAL": ("f", "cx", "cy", "k"),
    "RADIAL": ("f", "cx", "cy", "k1", "k2"),
    "OPENCV": ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2"),
}

log = logging.getLogger(__name__)

CAMERA_FILE_FORMATS = ("COLMAP model (folder, cameras.txt/.bin)", "transforms.json",
                       "Middlebury *_par.txt", "OpenMVS *.mvs", "Meshroom cameras.sfm",
                       "Strecha *.camera (a folder of them or one)")


def read_cameras(path: str | os.PathLike, *, sizes: Mapping[str, tuple[int, int]]
                 | None = None) -> dict[str, Camera]:
    """``{image name: Camera}`` from a COLMAP model, transforms.json or ``*_par.txt``.

    Parameters
    ----------
    path : path
    sizes : mapping name -> (width, height), optional
        The images' sizes, for formats that do not store them (Middlebury); a camera
        whose stored size differs from its image is an error.

    Raises
    ------
    InputError
        Unknown format, a malformed line or field (named), or a size disagreement.
    """
    path = Path(path)
    if not path.exists():
        raise InputError("cameras file not found", path=path)
    if path.suffix.lower() == ".camera" and path.is_file():
        cams = {path.name[:-len(".camera")]: read_strecha_camera(path)}
    elif path.is_dir() and not any((path / f).is_file() for f in ("cameras.bin", "cameras.txt")) \
            and any(path.glob("*.camera")):
        cams = {f.name[:-len(".camera")]: read_strecha_camera(f)
                for f in sorted(path.glob("*.camera"))}
    elif path.is_dir() or path.name in ("cameras.txt", "cameras.bin", "images.txt",
                                        "images.bin"):
        cams = _read_colmap(path if path.is_dir() else path.parent)
    elif path.suffix.lower() == ".json":
        from acquire.sfm.nerfstudio import read_transforms

        cameras, files = read_transforms(path)
        cams = {Path(f).name: c for c, f in zip(cameras, files, strict=True)}
    elif path.suffix.lower() == ".txt":
        cams = _read_middlebury(path, sizes or {})
    elif path.suffix.lower() in (".mvs", ".sfm"):
        from core.io.scene_cameras import read_meshroom_sfm, read_openmvs_scene

        read = read_openmvs_scene if path.suffix.lower() == ".mvs" else read_meshroom_sfm
        cams = {v.name: _view_camera(v, (sizes or {}).get(v.name), path) for v in read(path)}
    else:
        raise InputError("unknown cameras format: expected " + ", ".join(CAMERA_FILE_FORMATS),
                         path=path)
    if not cams:
        raise InputError("no cameras in the file", path=path)
    for name, cam in cams.items():
        size = (sizes or {}).get(name)
        if size is not None and (cam.width, cam.height) != tuple(size):
            raise InputError(f"camera of {name} is {cam.width}x{cam.height}, the image is "
                             f"{size[0]}x{size[1]}", path=path, field=name)
    return cams


def _view_camera(view, size, path: Path) -> Camera:
    """A :class:`~acquire.camera.Camera` from a :class:`core.io.scene_cameras.ViewCamera`;
    a normalised ``K`` (no stored size) scaled by the larger side of ``size`` (else 1000)."""
    K, (w, h) = view.K, (view.width, view.height)
    if w == 0 or h == 0:
        w, h = size if size is not None else (1000, 1000)
        K = K * np.array([[1.0], [1.0], [0.0]]) * max(w, h) + np.diag([0.0, 0.0, 1.0])
    try:
        return Camera(int(w), int(h), K[0, 0], K[1, 1], K[0, 2], K[1, 2], np.zeros(5),
                      view.cam_from_world)
    except ValueError as e:
        raise InputError(str(e), path=path, field=view.name) from None


def _read_colmap(folder: Path) -> dict[str, Camera]:
    import cv2  # noqa: F401  (before pycolmap)
    import pycolmap

    if not any((folder / f).is_file() for f in ("cameras.bin", "cameras.txt")):
        raise InputError("expected a COLMAP model (cameras.bin or cameras.txt)", path=folder)
    try:
        rec = pycolmap.Reconstruction(str(folder))
    except Exception as e:  # pycolmap raises its own types for unreadable models
        raise InputError(f"unreadable COLMAP model ({str(e).splitlines()[0]})",
                         path=folder) from None
    out = {}
    for im in rec.images.values():
        if not im.has_pose:
            continue
        try:
            out[im.name] = camera_from_colmap(im.camera, image_cam_from_world(im))
        except ValueError as e:
            raise InputError(str(e), path=folder, field=im.name) from None
    return out


def _read_middlebury(path: Path, sizes: Mapping[str, tuple[int, int]]) -> dict[str, Camera]:
    lines = [ln.split() for ln in path.read_text().splitlines() if ln.strip()]
    if lines and len(lines[0]) == 1:  # the count
        lines = lines[1:]
    out = {}
    for i, parts in enumerate(lines, start=1):
        if len(parts) != 22:
            raise InputError(f"expected 'name' and 21 numbers (K, R, t), got {len(parts)} "
                             f"fields", path=path, field=f"line {i + 1}")
        name = parts[0]
        try:
            v = np.array([float(x) for x in parts[1:]])
        except ValueError:
            raise InputError("expected numbers after the name", path=path,
                             field=f"line {i + 1}") from None
        K, R, t = v[:9].reshape(3, 3), v[9:18].reshape(3, 3), v[18:]
        if name not in sizes:
            raise InputError(f"image {name} is not in the photo folder", path=path,
                             field=f"line {i + 1}")
        w, h = sizes[name]
        U, S, Vt = np.linalg.svd(R)
        if np.any(np.abs(S - 1.0) > 1e-3) or np.linalg.det(R) < 0:
            raise InputError("R is not a rotation", path=path, field=f"line {i + 1}")
        R = U @ Vt  # the file's rounding, removed
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, t
        try:
            out[name] = Camera(int(w), int(h), K[0, 0], K[1, 1], K[0, 2], K[1, 2],
                               np.zeros(5), T)
        except ValueError as e:
            raise InputError(str(e), path=path, field=f"line {i + 1}") from None
    return out


_STRECHA_ROWS = (("K row 1", 3), ("K row 2", 3), ("K row 3", 3), ("distortion", 3),
                 ("R row 1", 3), ("R row 2", 3), ("R row 3", 3), ("centre C", 3),
                 ("image size", 2))


def read_strecha_camera(path: str | os.PathLike) -> Camera:
    """The :class:`~acquire.camera.Camera` of one Strecha ``.camera`` file (the layout
    and convention are in the module docstring).

    Raises
    ------
    InputError
        A missing or extra row, a row of the wrong length, a value that is not a number,
        ``K`` whose last row is not ``0 0 1``, a non-zero distortion (its model is not
        documented: undistort the images), ``R`` that is not a rotation, a size that is
        not two positive integers; the message names the row.
    """
    path = Path(path)
    try:
        lines = [ln.split() for ln in path.read_text().splitlines() if ln.strip()]
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"unreadable ({e.__class__.__name__})", path=path) from None
    if len(lines) != len(_STRECHA_ROWS):
        raise InputError(f"expected {len(_STRECHA_ROWS)} rows (K 3, distortion, R 3, "
                         f"centre, size), got {len(lines)}", path=path, field="rows")
    rows = []
    for parts, (what, n) in zip(lines, _STRECHA_ROWS, strict=True):
        if len(parts) != n:
            raise InputError(f"expected {n} numbers, got {len(parts)}", path=path, field=what)
        try:
            v = np.array([float(x) for x in parts])
        except ValueError:
            raise InputError(f"expected numbers, got {' '.join(parts)!r}", path=path,
                             field=what) from None
        if not np.all(np.isfinite(v)):
            raise InputError("expected finite numbers", path=path, field=what)
        rows.append(v)
    K, dist, R, C, size = (np.array(rows[:3]), rows[3], np.array(rows[4:7]), rows[7],
                           rows[8])
    for r, want in ((2, "0 0 1"), (1, "0 fy cy"), (0, "fx 0 cx (no skew)")):
        bad = (not np.allclose(K[2], [0.0, 0.0, 1.0]) if r == 2
               else K[1, 0] != 0.0 if r == 1 else K[0, 1] != 0.0)
        if bad:
            raise InputError(f"expected {want}, got {' '.join(lines[r])}", path=path,
                             field=f"K row {r + 1}")
    if np.any(dist != 0.0):
        raise InputError("non-zero distortion: the format does not say its model; give "
                         "undistorted images and a zero row", path=path, field="distortion")
    U, S, Vt = np.linalg.svd(R)
    if np.any(np.abs(S - 1.0) > 1e-3) or np.linalg.det(R) < 0:
        raise InputError(f"R is not a rotation (singular values {np.round(S, 4).tolist()}, "
                         f"det {np.linalg.det(R):.4f})", path=path, field="R")
    world_from_cam = U @ Vt  # the file's six digits of rounding, removed
    if np.any(size != np.round(size)) or np.any(size <= 0):
        raise InputError(f"expected two positive integers, got {size.tolist()}", path=path,
                         field="image size")
    T = np.eye(4)
    T[:3, :3] = world_from_cam.T
    T[:3, 3] = -world_from_cam.T @ C
    try:
        return Camera(int(size[0]), int(size[1]), K[0, 0], K[1, 1], K[0, 2], K[1, 2],
                      np.zeros(5), T)
    except ValueError as e:
        raise InputError(str(e), path=path, field="K") from None


def write_strecha_camera(path: str | os.PathLike, camera: Camera) -> None:
    """Write ``camera`` as a Strecha ``.camera`` file (the inverse of
    :func:`read_strecha_camera`; a camera with distortion is refused)."""
    if np.any(np.asarray(camera.dist) != 0.0):
        raise ValueError("camera: the .camera format holds no distortion model; expected "
                         "an undistorted camera")
    R = camera.cam_from_world[:3, :3].T  # world_from_cam

    def row(v):
        return " ".join(f"{float(x):.17g}" for x in v)

    K = [[camera.fx, 0.0, camera.cx], [0.0, camera.fy, camera.cy], [0.0, 0.0, 1.0]]
    text = "\n".join([*map(row, K), row([0, 0, 0]), *map(row, R), row(camera.center),
                      f"{camera.width} {camera.height}"]) + "\n"
    Path(path).write_text(text)


# -- camera conversions ---------------------------------------------------------------

def colmap_params_from_camera(camera: Camera, model: str | None = None) -> tuple[str, str]:
    """COLMAP ``(model, params string)`` for an OpenCV-convention camera.

    The principal point moves by +0.5 px (COLMAP puts pixel centres at half integers).
    Without ``model``: ``SIMPLE_RADIAL`` when fx = fy and the distortion is at most a
    k1, ``PINHOLE`` for fx != fy without distortion, else ``OPENCV``.
    """
    k1, k2, p1, p2, k3 = camera.dist
    cx, cy = camera.cx + 0.5, camera.cy + 0.5
    if model is None:
        if camera.fx == camera.fy and k2 == p1 == p2 == k3 == 0:
            model = "SIMPLE_RADIAL"
        elif not np.any(camera.dist):
            model = "PINHOLE"
        else:
            model = "OPENCV"
    check_choice(model, "model", CAMERA_MODELS)
    f = 0.5 * (camera.fx + camera.fy)
    values = {"SIMPLE_PINHOLE": (f, cx, cy), "PINHOLE": (camera.fx, camera.fy, cx, cy),
              "SIMPLE_RADIAL": (f, cx, cy, k1), "RADIAL": (f, cx, cy, k1, k2),
              "OPENCV": (camera.fx, camera.fy, cx, cy, k1, k2, p1, p2)}[model]
    return model, ", ".join(repr(float(v)) for v in values)


def camera_from_colmap(cam, cam_from_world: np.ndarray | None = None) -> Camera:
    """An OpenCV-convention :class:`~acquire.camera.Camera` from a ``pycolmap.Camera``."""
    name = cam.model_name if hasattr(cam, "model_name") else cam.model.name
    if name not in CAMERA_MODELS:
        raise ValueError(f"camera model: expected one of {', '.join(CAMERA_MODELS)}, "
                         f"got {name}")
    p = dict(zip(CAMERA_MODELS[name], np.asarray(cam.params, float), strict=False))
    fx = p.get("fx", p.get("f"))
    fy = p.get("fy", p.get("f"))
    dist = np.array([p.get("k1", p.get("k", 0.0)), p.get("k2", 0.0), p.get("p1", 0.0),
                     p.get("p2", 0.0), 0.0])
    return Camera(int(cam.width), int(cam.height), fx, fy, p["cx"] - 0.5, p["cy"] - 0.5, dist,
                  np.eye(4) if cam_from_world is None else cam_from_world)


def image_cam_from_world(image) -> np.ndarray:
    """``cam_from_world`` (4, 4) of a registered ``pycolmap.Image``."""
    T = np.eye(4)
    T[:3, :4] = image.cam_from_world().matrix()
    return T
