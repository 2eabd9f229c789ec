"""Platforms and their trajectories: where the scanner is, and how it is turned, at each
pulse.

A survey is a list of :class:`Leg`: an airborne strip (a straight line flown at constant
speed and altitude), a stretch of a vehicle's path, or a terrestrial station (the scanner
standing still while its head pans about the vertical). Each leg is scanned on its own
(legs run in parallel); a leg's ``source_id`` becomes the points' ``point_source_id``.

Frames: the world is Z up (metres, the scene's local frame). The platform frame has x
forward (the heading), y left, z up. The scanner frame (:mod:`acquire.lidar.patterns`)
is mounted in it by ``platform_from_scanner`` (:func:`mount_for`): looking down with its
lines across the track on aircraft, its spin axis up on a vehicle, its line sweeping
elevation on a tripod.

>>> leg = Leg(source_id=1, start=np.zeros(3), end=np.array([100.0, 0, 0]), speed=50.0,
...           gps_start=0.0, mount=mount_for("airplane", "polygon"))
>>> leg.duration
2.0
>>> pos, R = leg.poses(np.array([1.0]))
>>> pos.tolist(), np.round(R[0] @ [0, 0, 1], 6).tolist()
([[50.0, 0.0, 0.0]], [0.0, 0.0, -1.0])
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from core.validate import InputError, check_choice

__all__ = ["Leg", "mount_for", "PLATFORMS", "PlatformDefaults", "PLATFORM_DEFAULTS"]

PLATFORMS = ("airplane", "multicopter", "vehicle", "tripod")


@dataclass(frozen=True)
class PlatformDefaults:
    """A platform's usual figures (used when the survey gives none)."""

    altitude_m: float          # above the scene's lowest point (air); sensor height (ground)
    speed_m_s: float
    speed_range_m_s: tuple     # what it can fly or drive
    turn_s: float              # time between strips (GPS time gap)


PLATFORM_DEFAULTS = {
    "airplane": PlatformDefaults(300.0, 60.0, (30.0, 90.0), 60.0),
    "multicopter": PlatformDefaults(60.0, 6.0, (1.0, 20.0), 10.0),
    "vehicle": PlatformDefaults(2.0, 10.0, (1.0, 30.0), 0.0),
    "tripod": PlatformDefaults(1.5, 0.0, (0.0, 0.0), 30.0),
}


def mount_for(platform: str, pattern: str) -> np.ndarray:
    """``platform_from_scanner`` (3, 3) for a pattern on a platform.

    Aircraft: boresight down, lines across the track (scan angle positive to the right).
    Vehicle with a spinning scanner (any platform): spin axis up. Tripod with a line
    scanner: boresight horizontal forward, the line sweeping elevation (up positive).
    """
    check_choice(platform, "platform", PLATFORMS)
    if pattern == "spinning":
        return np.eye(3)
    if platform in ("airplane", "multicopter"):
        return np.array([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]]).T
    if platform == "tripod":
        return np.array([[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]]).T
    # vehicle with a line scanner: looking right, lines sweeping a vertical plane
    return np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]).T


def _rz(angle: np.ndarray) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    R = np.zeros(np.shape(angle) + (3, 3))
    R[..., 0, 0], R[..., 0, 1], R[..., 1, 0], R[..., 1, 1] = c, -s, s, c
    R[..., 2, 2] = 1.0
    return R


@dataclass(frozen=True)
class Leg:
    """One strip, path stretch or station.

    Parameters
    ----------
    source_id : int
        The strip or station number (``point_source_id``).
    start, end : (3,) float64
        Scanner positions at the start and end (equal for a station), world frame.
    speed : float
        m/s along the line (0 for a station).
    gps_start : float
        GPS time at the start, seconds.
    mount : (3, 3) float64
        ``platform_from_scanner``.
    pan_deg : (float, float)
        A station's head pan from and to, degrees about Z (0 = +x); a moving leg heads
        from ``start`` to ``end``.
    pan_rate_deg_s : float
        A station's head pan rate.
    """

    source_id: int
    start: np.ndarray
    end: np.ndarray
    speed: float
    gps_start: float
    mount: np.ndarray = field(default_factory=lambda: np.eye(3))
    pan_deg: tuple = (0.0, 360.0)
    pan_rate_deg_s: float = 0.0

    def __post_init__(self):
        if self.is_station and self.pan_rate_deg_s <= 0:
            raise InputError("a station needs a positive pan rate", field="pan_rate_deg_s")
        if not self.is_station and self.speed <= 0:
            raise InputError("a moving leg needs a positive speed", field="speed")

    @property
    def is_station(self) -> bool:
        return bool(np.allclose(self.start, self.end))

    @property
    def duration(self) -> float:
        """Seconds the leg takes."""
        if self.is_station:
            return abs(self.pan_deg[1] - self.pan_deg[0]) / self.pan_rate_deg_s
        return float(np.linalg.norm(np.asarray(self.end) - self.start) / self.speed)

    @property
    def heading(self) -> float:
        """Radians about Z of the direction of travel (0 for a station)."""
        if self.is_station:
            return 0.0
        d = np.asarray(self.end) - self.start
        return float(np.arctan2(d[1], d[0]))

    def poses(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Scanner positions ``(n, 3)`` and ``world_from_scanner`` rotations, ``(1, 3, 3)``
        for a moving leg (constant heading) or ``(n, 3, 3)`` for a panning station, at
        times ``t (n,)`` seconds from the leg's start."""
        t = np.asarray(t, np.float64)
        if self.is_station:
            ang = np.radians(self.pan_deg[0]) + np.sign(self.pan_deg[1] - self.pan_deg[0]) \
                * np.radians(self.pan_rate_deg_s) * t
            return (np.broadcast_to(np.asarray(self.start, np.float64), (len(t), 3)),
                    _rz(ang) @ self.mount)
        f = (t / self.duration)[:, None]
        pos = (1 - f) * np.asarray(self.start, np.float64) + f * np.asarray(self.end, np.float64)
        return pos, (_rz(np.array(self.heading)) @ self.mount)[None]
