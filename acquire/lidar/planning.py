"""Survey planning: strips over an area for a target point density, vehicle paths and
terrestrial stations, as :class:`acquire.lidar.platforms.Leg` lists.

Airborne (the planner's arithmetic): at altitude ``h`` a line scanner covering scan
angles ``lo .. hi`` sweeps a swath ``W = h (tan hi - tan lo)``; strips ``W (1 - overlap)``
apart flown at speed ``v`` with pulse rate ``PRR`` put, on average over the area,

    density = PRR / (v * spacing)      pulses per square metre

(over an area narrower than the strips' total, ``spacing`` is the swath over the mean
number of swaths covering a point), so a target density sets
``v = PRR / (density * spacing)``. When that speed is beyond what the platform flies,
the next selectable pulse rate of the scanner is tried; a
density no (rate, speed) pair reaches is an InputError saying the reachable range. The
line rate makes the spacing along the track equal to the one across it,
``rate = sqrt(PRR v / W)``, within the scanner's range.

>>> from acquire.lidar.presets import get_preset
>>> p = plan_strips(np.array([[0, 0], [1000, 600]]), 0.0, get_preset("riegl-lms-q560"),
...                 platform="airplane", altitude=500.0, overlap=0.3, density=4.0)
>>> round(p.speed, 1), p.pulse_rate, len(p.legs)
(73.6, 100000.0, 2)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from acquire.lidar.platforms import PLATFORM_DEFAULTS, Leg, mount_for
from acquire.lidar.presets import ScannerPreset
from core.validate import InputError

__all__ = ["SurveyPlan", "plan_strips", "plan_path", "plan_stations", "swath_width"]


@dataclass
class SurveyPlan:
    """The legs of a survey and the figures they were planned from (for report.json)."""

    legs: list
    platform: str
    pulse_rate: float
    scan_rate: float
    altitude: float = 0.0
    speed: float = 0.0
    swath: float = 0.0
    spacing: float = 0.0
    overlap: float = 0.0
    density_target: float | None = None
    density_planned: float | None = None
    area: np.ndarray | None = None          # (2, 2) xy bounds surveyed
    notes: list = field(default_factory=list)

    def to_dict(self) -> dict:
        return {"platform": self.platform, "pulse_rate_hz": self.pulse_rate,
                "scan_rate_hz": self.scan_rate, "altitude_m": self.altitude,
                "speed_m_s": self.speed, "swath_m": self.swath, "strip_spacing_m": self.spacing,
                "overlap": self.overlap, "density_target_per_m2": self.density_target,
                "density_planned_per_m2": self.density_planned, "legs": len(self.legs),
                "duration_s": float(sum(leg.duration for leg in self.legs)),
                "area_xy": None if self.area is None else np.asarray(self.area).tolist(),
                "notes": list(self.notes)}


def swath_width(preset: ScannerPreset, altitude: float) -> float:
    """Ground width swept at ``altitude`` over flat ground, metres."""
    lo, hi = np.radians(preset.fov_deg)
    if preset.pattern in ("conic", "rosette"):
        return float(2 * altitude * np.tan(hi))
    if preset.pattern == "spinning":
        return float(2 * altitude * np.tan(np.radians(max(np.abs(preset.channels_deg)))))
    return float(altitude * (np.tan(hi) - np.tan(lo)))


def _line_rate(preset: ScannerPreset, prr: float, speed: float, swath: float) -> float:
    lo, hi = preset.scan_rate_hz
    if preset.pattern in ("spinning", "rosette"):
        return float(np.clip(10.0, lo, hi))
    rate = np.sqrt(prr * speed / max(swath, 1e-9))
    if preset.pattern == "oscillating":
        rate /= 2.0
    return float(np.clip(rate, lo, hi))


def _speed_for(preset: ScannerPreset, platform: str, density: float, spacing: float):
    """Pulse rate and speed giving ``density`` with strips ``spacing`` apart (effective)."""
    vmin, vmax = PLATFORM_DEFAULTS[platform].speed_range_m_s
    for prr in sorted(preset.pulse_rates_hz, reverse=True):
        v = prr / (density * spacing)
        if vmin <= v <= vmax:
            return float(prr), float(v)
    hi = max(preset.pulse_rates_hz) / (vmin * spacing)
    lo = min(preset.pulse_rates_hz) / (vmax * spacing)
    raise InputError(f"{density:g} pts/m2 cannot be reached by a {platform} "
                     f"({vmin:g}-{vmax:g} m/s) with {preset.name} at this altitude and "
                     f"overlap: reachable {lo:.3g} to {hi:.3g} pts/m2", field="density")


def _cover(preset: ScannerPreset, h: float, W: float, offs: np.ndarray,
           width: float) -> float:
    """The area's mean pulse density over a single swath's mean ``PRR / (v W)``.

    A line scanner (polygon, oscillating mirror) sweeps its scan angle uniformly, so the
    pulses fall on flat ground ``h / cos^2(angle)`` apart across the track: its density
    at angle ``a`` is ``W cos^2(a) / (h (hi - lo))`` times the swath's mean, 5 % above it
    at nadir for +/-22.5 deg and 17 % for +/-37.5 deg. An area under the middle of one
    strip gets the nadir's density, not the swath's mean. Other patterns: the swaths'
    share of the area, as if uniform."""
    x = np.linspace(-width / 2, width / 2, 2001) if width > 0 else np.zeros(1)
    lo, hi = np.radians(preset.fov_deg)
    total = np.zeros_like(x)
    for o in offs:
        u = x - o
        if preset.pattern in ("polygon", "oscillating"):
            a = np.arctan2(u, h)
            inside = (a >= lo) & (a <= hi)
            total += np.where(inside, W * np.cos(a) ** 2 / (h * (hi - lo)), 0.0)
        else:
            total += (np.abs(u) <= W / 2).astype(np.float64)
    return float(total.mean())


def plan_strips(area_xy: np.ndarray, ground_z: float, preset: ScannerPreset, *,
                platform: str = "airplane", altitude: float | None = None,
                speed: float | None = None, overlap: float = 0.3,
                density: float | None = None, pulse_rate: float | None = None,
                scan_rate: float | None = None, heading_deg: float = 0.0,
                gps_start: float = 0.0) -> SurveyPlan:
    """Parallel strips covering ``area_xy`` ((2, 2): min and max corner) from the air.

    ``altitude`` is above ``ground_z``; ``density`` (pulses per square metre) sets the
    speed (and, if need be, the pulse rate); otherwise ``speed`` or the platform's usual.
    Strips run along ``heading_deg`` (0: along +x), alternating direction.
    """
    d = PLATFORM_DEFAULTS[platform]
    h = float(altitude if altitude is not None else d.altitude_m)
    if h <= 0:
        raise InputError(f"expected a positive altitude, got {h}", field="altitude")
    if not 0 <= overlap < 1:
        raise InputError(f"expected an overlap in [0, 1), got {overlap}", field="overlap")
    W = swath_width(preset, h)
    spacing = W * (1 - overlap)
    a = np.radians(heading_deg)
    ax, ay = np.array([np.cos(a), np.sin(a)]), np.array([-np.sin(a), np.cos(a)])
    area = np.asarray(area_xy, np.float64)
    corners = np.array([[x, y] for x in area[:, 0] for y in area[:, 1]])
    c = corners.mean(0)
    along, across = (corners - c) @ ax, (corners - c) @ ay
    width = across.max() - across.min()
    n = 1 if width <= W else int(np.ceil((width - W) / spacing)) + 1
    offs = (np.arange(n) - (n - 1) / 2) * spacing
    # mean number of swaths over a point of the area: density = PRR * cover / (v * W)
    cover = _cover(preset, h, W, offs, width)
    prr = float(pulse_rate or preset.pulse_rate_hz)
    if density is not None:
        if density <= 0:
            raise InputError(f"expected a positive density, got {density}", field="density")
        prr, v = _speed_for(preset, platform, float(density), W / cover)
    else:
        v = float(speed if speed is not None else d.speed_m_s)
    rate = float(scan_rate) if scan_rate else _line_rate(preset, prr, v, W)
    run_in = 0.5 * W if preset.pattern in ("conic", "rosette") else 0.05 * W
    legs, t = [], float(gps_start)
    for k, off in enumerate(offs):
        p0 = c + ay * off + ax * (along.min() - run_in)
        p1 = c + ay * off + ax * (along.max() + run_in)
        if k % 2:
            p0, p1 = p1, p0
        z = ground_z + h
        leg = Leg(source_id=k + 1, start=np.array([*p0, z]), end=np.array([*p1, z]),
                  speed=v, gps_start=t, mount=mount_for(platform, preset.pattern))
        legs.append(leg)
        t += leg.duration + d.turn_s
    return SurveyPlan(legs=legs, platform=platform, pulse_rate=prr, scan_rate=rate,
                      altitude=h, speed=v, swath=W, spacing=spacing, overlap=overlap,
                      density_target=density, density_planned=prr * cover / (v * W),
                      area=area)


def plan_path(waypoints: np.ndarray, preset: ScannerPreset, *, speed: float | None = None,
              pulse_rate: float | None = None, scan_rate: float | None = None,
              gps_start: float = 0.0, platform: str = "vehicle") -> SurveyPlan:
    """A vehicle driving through ``waypoints (k, 3)`` (scanner positions) at ``speed``;
    each stretch is a leg of the same source id 1."""
    w = np.asarray(waypoints, np.float64)
    if w.ndim != 2 or w.shape[1] != 3 or len(w) < 2:
        raise InputError(f"expected (k >= 2, 3) waypoints, got shape {w.shape}", field="path")
    v = float(speed if speed is not None else PLATFORM_DEFAULTS[platform].speed_m_s)
    prr = float(pulse_rate or preset.pulse_rate_hz)
    rate = float(scan_rate) if scan_rate else _line_rate(preset, prr, v, 10.0)
    legs, t = [], float(gps_start)
    for a, b in zip(w[:-1], w[1:], strict=True):
        if np.linalg.norm(b - a) < 1e-6:
            continue
        leg = Leg(source_id=1, start=a, end=b, speed=v, gps_start=t,
                  mount=mount_for(platform, preset.pattern))
        legs.append(leg)
        t += leg.duration
    return SurveyPlan(legs=legs, platform=platform, pulse_rate=prr, scan_rate=rate,
                      altitude=float(PLATFORM_DEFAULTS[platform].altitude_m), speed=v)


def plan_stations(positions: np.ndarray, preset: ScannerPreset, *,
                  angular_step_deg: float = 0.2, pulse_rate: float | None = None,
                  gps_start: float = 0.0) -> SurveyPlan:
    """Terrestrial stations at ``positions (k, 3)`` (the scanner's optical centre), each a
    full 360 degree pan. ``angular_step_deg`` sets the line rate (points ``step`` apart
    along a line) and the pan rate (lines ``step`` apart), within the scanner's limits;
    the pulse rate (unless given) is the fastest selectable one whose lines the mirror
    can sweep that fast (else points along a line are closer than ``step``)."""
    pos = np.asarray(positions, np.float64).reshape(-1, 3)
    step = float(angular_step_deg)
    if step <= 0:
        raise InputError(f"expected a positive angular step, got {step}",
                         field="angular_step")
    span = preset.fov_deg[1] - preset.fov_deg[0]
    lo, hi = preset.scan_rate_hz
    if pulse_rate:
        prr = float(pulse_rate)
    else:   # the fastest selectable rate whose lines can be swept at that step
        fits = [r for r in preset.pulse_rates_hz if r * step / span <= hi]
        prr = float(max(fits) if fits else min(preset.pulse_rates_hz))
    rate = float(np.clip(prr * step / span, lo, hi))
    pan = min(rate * step, preset.head_rate_deg_s or rate * step)
    legs, t = [], float(gps_start)
    for k, p in enumerate(pos):
        leg = Leg(source_id=k + 1, start=p, end=p, speed=0.0, gps_start=t,
                  mount=mount_for("tripod", preset.pattern), pan_deg=(0.0, 360.0),
                  pan_rate_deg_s=pan)
        legs.append(leg)
        t += leg.duration + PLATFORM_DEFAULTS["tripod"].turn_s
    return SurveyPlan(legs=legs, platform="tripod", pulse_rate=prr, scan_rate=rate,
                      altitude=float(PLATFORM_DEFAULTS["tripod"].altitude_m),
                      notes=[f"pan {pan:.3g} deg/s, {rate:.3g} lines/s"])
