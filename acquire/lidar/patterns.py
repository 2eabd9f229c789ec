"""Scan patterns: the beam's direction in the scanner frame at each pulse.

The scanner frame has its boresight along +z. Line scanners sweep the x-z plane (the
scan angle is the rotation about y, positive toward +x):

- ``oscillating``: a mirror swinging back and forth, zig-zag lines on the ground
  (triangle wave of the scan angle; ``rate`` full periods per second, two lines each);
- ``polygon``: a rotating polygon mirror, parallel lines all swept the same way (sawtooth;
  ``rate`` lines per second);
- ``conic`` (Palmer): a nutating mirror, the beam on a cone of half-angle ``fov[1]``
  about the boresight (``rate`` turns per second): ellipses on the ground;
- ``spinning`` (Velodyne-like): beams at fixed elevations (``channels_deg``) about the
  spin axis +z, fired in turn, the head turning ``rate`` times a second;
- ``rosette`` (Livox): two Risley prisms turning at ``prism_hz``, each deflecting the
  beam by half the field of view: a non-repeating rosette that fills the circle.

>>> import numpy as np
>>> p = ScanPattern("polygon", fov_deg=(-20, 20), rate_hz=100)
>>> d, ang = p.directions(np.array([0.0, 0.005]), np.arange(2))
>>> np.round(ang, 3).tolist()
[-20.0, 0.0]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.validate import InputError, check_choice

__all__ = ["ScanPattern", "PATTERNS"]

PATTERNS = ("oscillating", "polygon", "conic", "spinning", "rosette")


@dataclass(frozen=True)
class ScanPattern:
    """A scan pattern.

    Parameters
    ----------
    kind : {'oscillating', 'polygon', 'conic', 'spinning', 'rosette'}
    fov_deg : (float, float)
        Scan angle range, degrees (line scanners); the cone's half-angle is ``fov_deg[1]``
        (conic, rosette); ignored by 'spinning' (see ``channels_deg``).
    rate_hz : float
        Lines (polygon), mirror periods (oscillating), turns (conic, spinning) per second.
    channels_deg : tuple of float
        Beam elevations of a spinning multi-beam scanner, degrees.
    prism_hz : (float, float)
        Risley prism rotation rates of a rosette scanner.
    """

    kind: str
    fov_deg: tuple = (-20.0, 20.0)
    rate_hz: float = 50.0
    channels_deg: tuple = ()
    prism_hz: tuple = (-77.733, 121.567)

    def __post_init__(self):
        check_choice(self.kind, "pattern", PATTERNS)
        lo, hi = (float(a) for a in self.fov_deg)
        if not (-180.0 <= lo < hi <= 180.0):
            raise InputError(f"expected -180 <= low < high <= 180, got {self.fov_deg}",
                             field="fov_deg")
        if not self.rate_hz > 0:
            raise InputError(f"expected a positive rate, got {self.rate_hz}", field="rate_hz")
        if self.kind == "spinning" and not self.channels_deg:
            raise InputError("a spinning scanner needs its beams' elevations",
                             field="channels_deg")

    def line_index(self, t: np.ndarray) -> np.ndarray:
        """The scan line (or turn) each pulse belongs to: ``(n,) int64``."""
        per = 2.0 if self.kind == "oscillating" else 1.0
        return np.floor(np.asarray(t) * self.rate_hz * per).astype(np.int64)

    def directions(self, t: np.ndarray, index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Unit directions ``(n, 3)`` in the scanner frame and scan angles ``(n,)`` degrees
        at pulse times ``t (n,)`` seconds (``index (n,)``: the pulses' numbers, which pick
        the beam of a multi-beam scanner)."""
        t = np.asarray(t, np.float64)
        lo, hi = np.radians(self.fov_deg[0]), np.radians(self.fov_deg[1])
        if self.kind in ("oscillating", "polygon"):
            u = np.mod(t * self.rate_hz, 1.0)
            if self.kind == "oscillating":
                u = 1.0 - np.abs(2.0 * u - 1.0)          # triangle wave 0 -> 1 -> 0
            a = lo + (hi - lo) * u
            d = np.stack([np.sin(a), np.zeros_like(a), np.cos(a)], axis=1)
            return d, np.degrees(a)
        if self.kind == "conic":
            phi = 2 * np.pi * self.rate_hz * t
            d = np.stack([np.sin(hi) * np.cos(phi), np.sin(hi) * np.sin(phi),
                          np.full_like(phi, np.cos(hi))], axis=1)
            return d, np.degrees(np.arctan2(d[:, 0], d[:, 2]))
        if self.kind == "spinning":
            el = np.radians(np.asarray(self.channels_deg, np.float64))
            e = el[np.asarray(index) % len(el)]
            phi = 2 * np.pi * self.rate_hz * t
            d = np.stack([np.cos(e) * np.cos(phi), np.cos(e) * np.sin(phi), np.sin(e)], axis=1)
            return d, np.degrees(np.angle(np.exp(1j * phi)))
        # rosette: two prisms each deflect by half the field (small-angle vector sum)
        h = 0.5 * np.tan(hi)
        p1, p2 = (2 * np.pi * f * t for f in self.prism_hz)
        x = h * (np.cos(p1) + np.cos(p2))
        y = h * (np.sin(p1) + np.sin(p2))
        d = np.stack([x, y, np.ones_like(x)], axis=1)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        return d, np.degrees(np.arctan2(d[:, 0], d[:, 2]))
