"""Cameras from the scene files other multi-view tools write: an OpenMVS ``.mvs`` scene
and Meshroom's (AliceVision's) ``cameras.sfm``.

Both readers return ``[ViewCamera]``: per image its name, size (0 when the file does not
store it), ``K`` (3, 3) with pixel centres at integer coordinates (OpenCV) and
``cam_from_world`` (4, 4) in the OpenCV camera frame (x right, y down, z forward), the
frame both tools use. A malformed file raises :class:`core.validate.InputError` naming
the file and the field (``platforms[0].cameras[1].K``, ``poses[3].pose.transform``).

OpenMVS ``.mvs`` (``libs/MVS/Interface.h``, little-endian binary)
    ``"MVSI"``, ``uint32`` version (1-7 read here), ``uint32`` reserved; then the
    ``Interface``: platforms, images, ... . A ``std::string`` is a ``uint64`` length and
    the bytes; a ``std::vector`` a ``uint64`` count and the items; matrices are row-major
    ``double``. Platform: name, cameras, poses. Camera: name, band name (version > 3),
    ``uint32`` width and height (version > 0; 0 = ``K`` normalised by the larger image
    side), ``K`` (3x3), ``R`` (3x3) and ``C`` (3) relative to the platform. Pose: ``R``
    (3x3, world to platform) and ``C`` (3, the platform's centre in the world). Image:
    name, mask name (version > 4), ``uint32`` platform, camera and pose ids (pose
    ``NO_ID`` = 2^32-1: not calibrated, skipped), global id (version > 2), depths and view
    scores (version > 6). A camera's pose is ``R = R_cam R_pose``, ``C = R_pose^T C_cam +
    C_pose``; ``cam_from_world = [R | -R C]``. Everything after the images (points,
    lines, transform, box) is not read.

Meshroom ``cameras.sfm`` (JSON; numbers are often strings)
    ``version`` [major, minor, revision]; ``views`` [{viewId, poseId, intrinsicId,
    path}]; ``intrinsics`` [{intrinsicId, width, height, principalPoint, and the focal
    length: ``pxFocalLength`` (one value before 1.2.0, [fx, fy] up to 1.2.1), from 1.2.2
    ``focalLength`` in mm with ``sensorWidth`` (fx = focalLength / sensorWidth x width,
    fy = fx x ``pixelRatio``)}]; the principal point is absolute before 1.2.1, an offset
    from the image centre from then on; ``poses`` [{poseId, pose: {transform: {rotation
    (9), center (3)}}}]. AliceVision writes the rotation with Eigen's default
    column-major order: the nine values read **row by row are world_from_cam's
    rotation** (read column by column, cam_from_world's: ``x_cam = R (X - center)``).
    ``center`` is the camera centre in the world. Distortion is not read.
"""

from __future__ import annotations

import json
import os
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from core.validate import InputError

__all__ = ["ViewCamera", "read_openmvs_scene", "read_meshroom_sfm", "OPENMVS_VERSIONS"]

#: the ``.mvs`` versions read here (``MVSI_PROJECT_VER`` of OpenMVS releases so far)
OPENMVS_VERSIONS = range(1, 8)
NO_ID = 2 ** 32 - 1


@dataclass(frozen=True)
class ViewCamera:
    """One image's camera as another tool stored it.

    Attributes
    ----------
    name : str
        The image's file name (no folder).
    width, height : int
        0 when the file does not store the size (an OpenMVS normalised ``K``).
    K : (3, 3) float64
    cam_from_world : (4, 4) float64
    """

    name: str
    width: int
    height: int
    K: np.ndarray
    cam_from_world: np.ndarray


def _pose(R: np.ndarray, C: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, -R @ C
    return T


def _rotation(R: np.ndarray, path, field: str, tol: float = 1e-3) -> np.ndarray:
    """The nearest rotation to ``R``; InputError when ``R`` is not one (to ``tol``)."""
    if not np.all(np.isfinite(R)):
        raise InputError("expected a rotation, got non-finite values", path=path, field=field)
    u, s, vt = np.linalg.svd(R)
    if np.any(np.abs(s - 1.0) > tol) or np.linalg.det(R) < 0:
        raise InputError(f"expected a rotation matrix, got singular values "
                         f"{np.round(s, 4).tolist()} and determinant "
                         f"{np.linalg.det(R):.4f}", path=path, field=field)
    return u @ vt


# -- OpenMVS -----------------------------------------------------------------------------

class _Reader:
    """Little-endian fields from a byte string; a short read names its field."""

    def __init__(self, data: bytes, path):
        self.data, self.pos, self.path = data, 0, path

    def take(self, fmt: str, field: str):
        size = struct.calcsize("<" + fmt)
        if self.pos + size > len(self.data):
            raise InputError(f"the file ends inside this field (byte {self.pos} of "
                             f"{len(self.data)})", path=self.path, field=field)
        out = struct.unpack_from("<" + fmt, self.data, self.pos)
        self.pos += size
        return out

    def u32(self, field):
        return self.take("I", field)[0]

    def count(self, field, limit=10_000_000):
        n = self.take("Q", field)[0]
        if n > limit:
            raise InputError(f"expected a count, got {n}", path=self.path, field=field)
        return n

    def string(self, field):
        n = self.count(field, limit=1 << 20)
        raw = self.take(f"{n}s", field)[0]
        try:
            return raw.decode("utf-8")
        except UnicodeDecodeError:
            raise InputError("expected UTF-8 text", path=self.path, field=field) from None

    def doubles(self, n, field):
        return np.array(self.take(f"{n}d", field), np.float64)


def _openmvs_platforms(r: _Reader, version: int) -> list:
    platforms = []
    for p in range(r.count("platforms")):
        at = f"platforms[{p}]"
        r.string(f"{at}.name")
        cams = []
        for c in range(r.count(f"{at}.cameras")):
            ac = f"{at}.cameras[{c}]"
            name = r.string(f"{ac}.name")
            if version > 3:
                r.string(f"{ac}.bandName")
            w, h = (r.u32(f"{ac}.width"), r.u32(f"{ac}.height")) if version > 0 else (0, 0)
            K = r.doubles(9, f"{ac}.K").reshape(3, 3)
            R = _rotation(r.doubles(9, f"{ac}.R").reshape(3, 3), r.path, f"{ac}.R")
            cams.append({"name": name, "width": w, "height": h, "K": K, "R": R,
                         "C": r.doubles(3, f"{ac}.C")})
        poses = []
        for k in range(r.count(f"{at}.poses")):
            ap = f"{at}.poses[{k}]"
            R = _rotation(r.doubles(9, f"{ap}.R").reshape(3, 3), r.path, f"{ap}.R")
            poses.append((R, r.doubles(3, f"{ap}.C")))
        platforms.append((cams, poses))
    return platforms


def _openmvs_images(r: _Reader, version: int) -> list:
    images = []
    for i in range(r.count("images")):
        at = f"images[{i}]"
        name = r.string(f"{at}.name")
        if version > 4:
            r.string(f"{at}.maskName")
        ids = r.take("III", f"{at}.platformID/cameraID/poseID")
        if version > 2:
            r.u32(f"{at}.ID")
        if version > 6:
            r.take("fff", f"{at}.minDepth/avgDepth/maxDepth")
            for k in range(r.count(f"{at}.viewScores")):
                r.take("IIffff", f"{at}.viewScores[{k}]")
        images.append((name, *ids))
    return images


def read_openmvs_scene(path: str | os.PathLike) -> list[ViewCamera]:
    """The calibrated images of an OpenMVS ``.mvs`` scene (module docstring).

    Raises
    ------
    InputError
        Not an ``MVSI`` file, an unknown version, a truncated or inconsistent field (named).
    """
    path = Path(path)
    data = path.read_bytes()
    if data[:4] != b"MVSI":
        raise InputError(f"expected an OpenMVS scene starting with 'MVSI', got "
                         f"{data[:4]!r}", path=path, field="header")
    r = _Reader(data, path)
    r.pos = 4
    version = r.u32("version")
    if version not in OPENMVS_VERSIONS:
        raise InputError(f"expected an OpenMVS scene version in {OPENMVS_VERSIONS.start}-"
                         f"{OPENMVS_VERSIONS.stop - 1}, got {version}", path=path,
                         field="version")
    r.u32("reserved")
    platforms = _openmvs_platforms(r, version)
    out = []
    for i, (name, pid, cid, pose_id) in enumerate(_openmvs_images(r, version)):
        if pose_id == NO_ID:
            continue  # not calibrated by the tool
        at = f"images[{i}]"
        if pid >= len(platforms) or cid >= len(platforms[pid][0]) \
                or pose_id >= len(platforms[pid][1]):
            raise InputError(f"platform {pid}, camera {cid} or pose {pose_id} does not exist",
                             path=path, field=f"{at}.platformID/cameraID/poseID")
        cam, (Rp, Cp) = platforms[pid][0][cid], platforms[pid][1][pose_id]
        R = cam["R"] @ Rp
        C = Rp.T @ cam["C"] + Cp
        out.append(ViewCamera(Path(name.replace("\\", "/")).name, cam["width"],
                              cam["height"], cam["K"].copy(), _pose(R, C)))
    return out


# -- Meshroom ----------------------------------------------------------------------------

def _numbers(value, n: int, path, field: str) -> np.ndarray:
    try:
        arr = np.array([float(v) for v in (value if isinstance(value, list) else [value])])
    except (TypeError, ValueError):
        raise InputError(f"expected {n} number(s), got {value!r}", path=path,
                         field=field) from None
    if arr.size != n or not np.all(np.isfinite(arr)):
        raise InputError(f"expected {n} finite number(s), got {value!r}", path=path,
                         field=field)
    return arr


def _meshroom_K(intr: dict, version: tuple, path, field: str) -> tuple[np.ndarray, int, int]:
    w = int(_numbers(intr.get("width"), 1, path, f"{field}.width")[0])
    h = int(_numbers(intr.get("height"), 1, path, f"{field}.height")[0])
    pp = _numbers(intr.get("principalPoint"), 2, path, f"{field}.principalPoint")
    if version >= (1, 2, 1):
        pp = pp + np.array([w / 2.0, h / 2.0])
    if version < (1, 2, 0):
        fx = fy = float(_numbers(intr.get("pxFocalLength"), 1, path,
                                 f"{field}.pxFocalLength")[0])
    elif version < (1, 2, 2):
        fx, fy = _numbers(intr.get("pxFocalLength"), 2, path, f"{field}.pxFocalLength")
    else:
        fmm = float(_numbers(intr.get("focalLength"), 1, path, f"{field}.focalLength")[0])
        sw = float(_numbers(intr.get("sensorWidth", 36.0), 1, path,
                            f"{field}.sensorWidth")[0])
        ratio = float(_numbers(intr.get("pixelRatio", 1.0), 1, path,
                               f"{field}.pixelRatio")[0])
        fx = fmm / sw * w
        fy = fx * ratio if version >= (1, 2, 5) else fx / ratio
    if not (fx > 0 and fy > 0):
        raise InputError(f"expected a positive focal length, got {fx}, {fy}", path=path,
                         field=f"{field}.focalLength")
    return np.array([[fx, 0.0, pp[0]], [0.0, fy, pp[1]], [0.0, 0.0, 1.0]]), w, h


def read_meshroom_sfm(path: str | os.PathLike) -> list[ViewCamera]:
    """The posed views of a Meshroom ``cameras.sfm`` (module docstring).

    Raises
    ------
    InputError
        Not JSON, a missing or malformed field (named), a view naming a pose or an
        intrinsic that does not exist.
    """
    path = Path(path)
    try:
        doc = json.loads(path.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise InputError(f"expected JSON ({e})", path=path) from None
    if not isinstance(doc, dict) or not isinstance(doc.get("views"), list):
        raise InputError("expected an object with a 'views' list", path=path, field="views")
    version = tuple(int(v) for v in _numbers(doc.get("version", [1, 2, 5]), 3, path,
                                             "version"))
    intrinsics, poses = {}, {}
    for i, intr in enumerate(doc.get("intrinsics") or []):
        if not isinstance(intr, dict) or "intrinsicId" not in intr:
            raise InputError("expected an object with an intrinsicId", path=path,
                             field=f"intrinsics[{i}]")
        intrinsics[str(intr["intrinsicId"])] = _meshroom_K(intr, version, path,
                                                           f"intrinsics[{i}]")
    for i, p in enumerate(doc.get("poses") or []):
        at = f"poses[{i}].pose.transform"
        try:
            tr = p["pose"]["transform"]
            pid = str(p["poseId"])
        except (KeyError, TypeError):
            raise InputError("expected poseId and pose.transform", path=path,
                             field=f"poses[{i}]") from None
        R_wc = _rotation(_numbers(tr.get("rotation"), 9, path, f"{at}.rotation")
                         .reshape(3, 3), path, f"{at}.rotation")
        poses[pid] = _pose(R_wc.T, _numbers(tr.get("center"), 3, path, f"{at}.center"))
    out = []
    for i, v in enumerate(doc["views"]):
        if not isinstance(v, dict):
            raise InputError("expected an object", path=path, field=f"views[{i}]")
        pid, iid = str(v.get("poseId", "")), str(v.get("intrinsicId", ""))
        if pid not in poses:
            continue  # a view the tool did not reconstruct
        if iid not in intrinsics:
            raise InputError(f"intrinsicId {iid!r} is not in 'intrinsics'", path=path,
                             field=f"views[{i}].intrinsicId")
        K, w, h = intrinsics[iid]
        name = Path(str(v.get("path", f"view_{v.get('viewId', i)}")).replace("\\", "/")).name
        out.append(ViewCamera(name, w, h, K, poses[pid]))
    return out
