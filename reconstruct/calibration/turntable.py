"""The turntable axis from a board's poses at known readings: one linear fit, shared by
the laser scanner's and the stereo rig's calibrations (each then refines it against its
own reprojection errors).

A board fixed on the turntable, seen at readings ``a_i``, has poses ``(R_i, t_i)`` in the
camera frame. Each relative rotation ``R_i R_0^T`` turns about the axis by ``a_i - a_0``:
its rotation vector lies along ``+/- axis``; summed with the sign of the turn (larger
turns weigh more, being better determined) they give the direction. A point ``c`` on the
axis satisfies ``(I - R_rel) c = t_i - R_rel t_0`` for every view, which fixes it up to a
slide along the axis; the slide is pinned at the axis point nearest ``near``.

>>> import numpy as np
>>> from core.frames import rotation_about
>>> axis, c = np.array([0.1, -0.2, 1.0]) / np.linalg.norm([0.1, -0.2, 1.0]), [0.3, 0.1, 0.5]
>>> board = np.eye(4); board[:3, 3] = [0.2, 0.0, 0.6]
>>> poses = [rotation_about(axis, a, c) @ board for a in np.radians([0, 20, 45, 90])]
>>> d, p = fit_axis([T[:3, :3] for T in poses], [T[:3, 3] for T in poses],
...                 np.radians([0, 20, 45, 90]), near=c)
>>> bool(np.allclose(d, axis) and np.allclose(p, c))
True
"""

from __future__ import annotations

import numpy as np

__all__ = ["fit_axis"]


def fit_axis(rotations, translations, angles_rad, *, near=None) -> tuple[np.ndarray, np.ndarray]:
    """Axis direction (unit, turning the readings counter-clockwise) and the axis point
    nearest ``near`` (default: the mean board position), from board poses.

    Raises
    ------
    RuntimeError
        The board did not turn between views.
    """
    import cv2

    rs = [np.asarray(r, np.float64) for r in rotations]
    ts = [np.asarray(t, np.float64).ravel() for t in translations]
    ang = np.asarray(angles_rad, np.float64)
    acc = np.zeros(3)
    rows, rhs = [], []
    for r, t, a in zip(rs[1:], ts[1:], ang[1:], strict=True):
        rel = r @ rs[0].T
        rv = cv2.Rodrigues(rel)[0].ravel()
        if abs(a - ang[0]) > 1e-9:
            acc += rv * np.sign(a - ang[0])
        rows.append(np.eye(3) - rel)
        rhs.append(t - rel @ ts[0])
    if np.linalg.norm(acc) < 1e-9:
        raise RuntimeError("turntable axis: the board did not turn between views")
    axis = acc / np.linalg.norm(acc)
    near = np.mean(ts, axis=0) if near is None else np.asarray(near, np.float64)
    a = np.vstack([*rows, axis[None, :]])
    b = np.concatenate([*rhs, [axis @ near]])
    point = np.linalg.lstsq(a, b, rcond=None)[0]
    return axis, point
