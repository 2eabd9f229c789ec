"""Camera paths for structure-from-motion captures.

Every path returns ``cam_from_world`` poses (k, 4, 4) of OpenCV cameras looking at
a target, world Z up:

- :func:`orbit_rings`: rings of evenly spaced views at several elevations,
- :func:`hemisphere`: a Fibonacci spiral over the upper hemisphere (near-uniform),
- :func:`handheld_walk`: a walk around the target with positional jitter, a wobbling
  aim and roll, as a person with a camera would take,
- :func:`subframe_poses`: poses inside the exposure between two frames, for motion
  blur by averaging sub-frame renders.
"""

from __future__ import annotations

import numpy as np

from acquire.camera import look_at_cam_from_world
from core.frames import axis_angle_matrix
from core.validate import check_array, check_int, check_positive, check_range

__all__ = ["orbit_rings", "hemisphere", "handheld_walk", "subframe_poses", "interpolate_pose"]


def _centre(target, radius):
    target = check_array(target, "target", shape=(3,))
    check_positive(radius, "radius")
    return target


def orbit_rings(target, radius: float, *, elevations_deg=(20.0, 40.0),
                views_per_ring: int = 12, phase_deg: float = 0.0) -> np.ndarray:
    """Rings of views around ``target`` at ``radius``, one ring per elevation.

    Alternate rings are offset by half a step in azimuth so neighbouring rings
    interleave. Views are ordered ring by ring, azimuth increasing.

    Parameters
    ----------
    target : (3,) float64
    radius : float
        Distance from the target in metres.
    elevations_deg : sequence of float
        Elevation of each ring above the target's horizontal plane, in (-90, 90).
    views_per_ring : int
    phase_deg : float
        Azimuth of the first view of the first ring.

    Returns
    -------
    cam_from_world : (k, 4, 4) float64
    """
    target = _centre(target, radius)
    views_per_ring = check_int(views_per_ring, "views_per_ring")
    elevations = [check_range(e, "elevations_deg", -90, 90, lo_open=True, hi_open=True)
                  for e in np.atleast_1d(elevations_deg)]
    if not elevations:
        raise ValueError("elevations_deg: expected at least one elevation, got none")
    poses = []
    step = 360.0 / views_per_ring
    for ring, elev in enumerate(elevations):
        for i in range(int(views_per_ring)):
            az = np.radians(phase_deg + step * (i + 0.5 * (ring % 2)))
            el = np.radians(elev)
            eye = target + radius * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az),
                                              np.sin(el)])
            poses.append(look_at_cam_from_world(eye, target))
    return np.array(poses)


def hemisphere(target, radius: float, n: int, *, min_elevation_deg: float = 10.0,
               max_elevation_deg: float = 75.0) -> np.ndarray:
    """``n`` views on a Fibonacci spiral over a band of the upper hemisphere.

    Equal-area: the sine of the elevation is spread uniformly between the bounds and
    the azimuth advances by the golden angle.

    Returns
    -------
    cam_from_world : (n, 4, 4) float64
    """
    target = _centre(target, radius)
    n = check_int(n, "n")
    lo = check_range(min_elevation_deg, "min_elevation_deg", -90, 90)
    hi = check_range(max_elevation_deg, "max_elevation_deg", lo, 90)
    golden = np.pi * (3.0 - np.sqrt(5.0))
    k = np.arange(int(n))
    s = np.sin(np.radians(lo)) + (k + 0.5) / n * (np.sin(np.radians(hi)) - np.sin(np.radians(lo)))
    el = np.arcsin(s)
    az = golden * k
    poses = []
    for e, a in zip(el, az, strict=False):
        eye = target + radius * np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
        poses.append(look_at_cam_from_world(eye, target))
    return np.array(poses)


def handheld_walk(target, radius: float, n: int, *, rng: np.random.Generator,
                  elevation_deg: float = 25.0, arc_deg: float = 360.0,
                  position_jitter: float = 0.03, aim_jitter: float = 0.03,
                  roll_jitter_deg: float = 3.0, height_wobble: float = 0.05) -> np.ndarray:
    """A hand-held walk around ``target``: an arc with jitter, wobble and roll.

    Parameters
    ----------
    target : (3,) float64
    radius : float
        Mean distance in metres.
    n : int
        Number of frames along the arc (in walking order).
    rng : numpy.random.Generator
    elevation_deg : float
        Mean elevation of the camera above the target.
    arc_deg : float
        Azimuth covered by the walk (360 closes the loop without repeating a view).
    position_jitter, aim_jitter, height_wobble : float
        Standard deviations as fractions of ``radius``: random offsets of the eye,
        of the aim point, and a slow sinusoidal change of height.
    roll_jitter_deg : float
        Standard deviation of the roll about the viewing axis.

    Returns
    -------
    cam_from_world : (n, 4, 4) float64
    """
    target = _centre(target, radius)
    n = check_int(n, "n")
    for name, v in (("position_jitter", position_jitter), ("aim_jitter", aim_jitter),
                    ("height_wobble", height_wobble), ("roll_jitter_deg", roll_jitter_deg)):
        check_positive(v, name, allow_zero=True)
    check_range(arc_deg, "arc_deg", 0, 360, lo_open=True)
    n = int(n)
    step = np.radians(arc_deg) / (n if arc_deg >= 360 else max(n - 1, 1))
    el = np.radians(elevation_deg)
    phase = rng.uniform(0, 2 * np.pi)
    poses = []
    for i in range(n):
        az = i * step
        h = radius * (np.sin(el) + height_wobble * np.sin(2 * np.pi * i / max(n, 2) * 2 + phase))
        eye = target + np.array([radius * np.cos(el) * np.cos(az),
                                 radius * np.cos(el) * np.sin(az), h])
        eye = eye + rng.normal(0.0, position_jitter * radius, 3)
        aim = target + rng.normal(0.0, aim_jitter * radius, 3)
        T = look_at_cam_from_world(eye, aim)
        roll = np.radians(rng.normal(0.0, roll_jitter_deg))
        Rr = axis_angle_matrix([0, 0, 1], roll)  # about the camera's z (viewing) axis
        T[:3, :3] = Rr @ T[:3, :3]
        T[:3, 3] = -T[:3, :3] @ eye
        poses.append(T)
    return np.array(poses)


def interpolate_pose(T0: np.ndarray, T1: np.ndarray, s: float) -> np.ndarray:
    """``cam_from_world`` a fraction ``s`` of the way from ``T0`` to ``T1``.

    The centre moves on a straight line; the rotation on the geodesic (slerp).
    """
    T0 = check_array(T0, "T0", shape=(4, 4))
    T1 = check_array(T1, "T1", shape=(4, 4))
    R0, R1 = T0[:3, :3], T1[:3, :3]
    c0, c1 = -R0.T @ T0[:3, 3], -R1.T @ T1[:3, 3]
    dR = R1 @ R0.T
    angle = np.arccos(np.clip((np.trace(dR) - 1) / 2, -1, 1))
    if angle < 1e-12:
        R = R0.copy()
    else:
        axis = np.array([dR[2, 1] - dR[1, 2], dR[0, 2] - dR[2, 0], dR[1, 0] - dR[0, 1]])
        if np.linalg.norm(axis) < 1e-9:  # 180 degrees: any perpendicular axis of dR
            w, v = np.linalg.eigh(dR + np.eye(3))
            axis = v[:, -1]
        R = axis_angle_matrix(axis, s * angle) @ R0
    c = (1 - s) * c0 + s * c1
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = -R @ c
    return T


def subframe_poses(T0: np.ndarray, T1: np.ndarray, n: int, *, shutter: float = 0.5) -> np.ndarray:
    """Poses during the exposure of the frame at ``T0`` while moving toward ``T1``.

    The shutter stays open for the fraction ``shutter`` of the time between the
    frames, centred on ``T0``; averaging renders at these poses gives motion blur.

    Returns
    -------
    cam_from_world : (n, 4, 4) float64
    """
    n = check_int(n, "n")
    check_range(shutter, "shutter", 0, 1)
    offs = (np.arange(int(n)) + 0.5) / n - 0.5 if n > 1 else np.zeros(1)
    return np.array([interpolate_pose(T0, T1, float(o * shutter)) for o in offs])
