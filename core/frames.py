"""Frames and rotations: the one place that builds rotation matrices and rigid transforms.

Angles are radians here (degrees only where a name says so: ``euler_xyz_deg``). Rigid
transforms are ``(4, 4)`` float64 and named by frames at the call site
(``world_from_object``).

>>> import numpy as np
>>> R = axis_angle_matrix([0, 0, 1], np.pi / 2)
>>> np.round(R @ [1.0, 0.0, 0.0], 12) + 0.0
array([0., 1., 0.])
>>> round(rotation_angle_deg(R), 9)
90.0
"""

from __future__ import annotations

import numpy as np

__all__ = ["axis_angle_matrix", "rotation_about", "euler_xyz_deg", "rotation_to",
           "rotation_between", "rotation_angle_deg", "rigid", "transform_points", "unit"]


def transform_points(T, points) -> np.ndarray:
    """``points`` ``(..., 3)`` moved by the ``(4, 4)`` transform ``T``: ``R p + t`` for each
    point (``T``'s last row is not read, so an affine ``T`` works too).

    >>> transform_points(rigid(np.eye(3), [1.0, 2.0, 3.0]), np.zeros((2, 3)))
    array([[1., 2., 3.],
           [1., 2., 3.]])
    """
    T = np.asarray(T, float)
    return np.asarray(points, float) @ T[:3, :3].T + T[:3, 3]


def unit(v, *, axis: int = -1, tiny: float = 0.0, fill: float = 0.0) -> np.ndarray:
    """``v`` scaled to unit length along ``axis``; a vector of length ``<= tiny`` becomes
    ``fill`` (0 by default; NaN marks it as having no direction).

    >>> unit([[3.0, 4.0, 0.0], [0.0, 0.0, 0.0]])
    array([[0.6, 0.8, 0. ],
           [0. , 0. , 0. ]])
    """
    v = np.asarray(v, float)
    n = np.linalg.norm(v, axis=axis, keepdims=True)
    return np.divide(v, n, out=np.full(v.shape, fill), where=n > tiny)


def axis_angle_matrix(axis, angle: float) -> np.ndarray:
    """Rotation ``(3, 3)`` by ``angle`` radians about ``axis`` (right-handed, Rodrigues)."""
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * (K @ K)


def rigid(R, t=(0.0, 0.0, 0.0)) -> np.ndarray:
    """The ``(4, 4)`` transform ``x -> R x + t``."""
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    return T


def rotation_about(axis, angle: float, center=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Rigid transform ``(4, 4)``: rotation by ``angle`` radians about the line through
    ``center`` along ``axis`` (right-handed).

    >>> T = rotation_about([0, 0, 1], np.pi, center=[1.0, 0.0, 0.0])
    >>> np.round(T @ [0.0, 0.0, 0.0, 1.0], 12)[:3] + 0.0
    array([2., 0., 0.])
    """
    R = axis_angle_matrix(axis, angle)
    c = np.asarray(center, float)
    return rigid(R, c - R @ c)


def euler_xyz_deg(angles) -> np.ndarray:
    """Rotation ``(3, 3)`` of extrinsic rotations about X, then Y, then Z (degrees)."""
    rx, ry, rz = np.radians(np.asarray(angles, float))
    cx, sx, cy, sy, cz, sz = np.cos(rx), np.sin(rx), np.cos(ry), np.sin(ry), np.cos(rz), np.sin(rz)
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def rotation_to(z_axis) -> np.ndarray:
    """A rotation ``(3, 3)`` taking +z to the unit vector along ``z_axis`` (columns x, y, z)."""
    z = np.asarray(z_axis, float)
    z = z / np.linalg.norm(z)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=1)


def rotation_between(a, b) -> np.ndarray:
    """The smallest rotation ``(3, 3)`` taking the direction of ``a`` to that of ``b``
    (identity when they agree; a half turn about an axis perpendicular to ``a`` when they
    are opposite).

    >>> np.round(rotation_between([0, 0, 1], [0, 1, 0]) @ [0, 0, 1], 12) + 0.0
    array([0., 1., 0.])
    """
    a = np.asarray(a, float) / np.linalg.norm(a)
    b = np.asarray(b, float) / np.linalg.norm(b)
    axis = np.cross(a, b)
    s, c = float(np.linalg.norm(axis)), float(np.clip(a @ b, -1.0, 1.0))
    if s < 1e-12:
        if c > 0:
            return np.eye(3)
        helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        return axis_angle_matrix(np.cross(a, helper), np.pi)
    return axis_angle_matrix(axis / s, float(np.arctan2(s, c)))


def rotation_angle_deg(R) -> float:
    """Rotation angle in degrees of a ``(3, 3)`` rotation matrix (robust near 0 and 180)."""
    R = np.asarray(R, float)
    c = (np.trace(R) - 1.0) / 2.0
    s = np.linalg.norm([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / 2.0
    return float(np.degrees(np.arctan2(s, np.clip(c, -1.0, 1.0))))
