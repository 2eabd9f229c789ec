"""A LiDAR survey of a render scene, leg by leg, into LAS/LAZ (and E57 for stations).

:class:`LidarCaptureConfig` is everything ``scanamp capture lidar`` reads.
:func:`plan_survey` turns it into legs (:mod:`acquire.lidar.planning`);
:func:`scan_leg_to_las` streams one leg's points into a LAZ file (the unit that runs in
parallel); :func:`merge_las` concatenates legs' files into one, chunk by chunk.
Coordinates: the scene is simulated in its local frame; files carry ``local + origin``
(the scene's origin, projected coordinates), with the LAS offset at the origin.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from acquire.lidar.labels import PARTS
from acquire.lidar.planning import SurveyPlan, plan_path, plan_stations, plan_strips
from acquire.lidar.platforms import PLATFORM_DEFAULTS, PLATFORMS, Leg
from acquire.lidar.presets import ScannerPreset, get_preset
from acquire.lidar.simulate import LidarWorld, Scanner, intensity_counts, scan_leg
from core.config import Config, option
from core.io.las import LasWriter, iter_las_chunks
from core.validate import InputError

__all__ = ["LidarCaptureConfig", "plan_survey", "make_scanner", "scan_leg_to_las",
           "merge_las", "LAS_EXTRA", "leg_rng", "station_positions", "nominal_range",
           "strip_name", "e57_scan", "summary_report"]

#: The truth written as LAS extra bytes.
LAS_EXTRA = {"object_id": "int32", "part": "uint8", "true_x": "float64", "true_y": "float64",
             "true_z": "float64", "snr": "float32", "echo_energy": "float32",
             "scan_row": "int32", "scan_column": "int32"}


@dataclass
class LidarCaptureConfig(Config):
    """Everything ``scanamp capture lidar`` reads: scanner, platform, plan, files."""

    preset: str = option("riegl-lms-q560", help="scanner preset: riegl-lms-q560, "
                         "riegl-vq-880g, riegl-vz-400, velodyne-vlp16, livox-avia, "
                         "leica-als50-ii")
    platform: str | None = option(None, help="airplane, multicopter, vehicle or tripod "
                                  "(default: the preset's)")
    density: float | None = option(None, unit="pts/m2", range="(0, inf)",
                                   help="target pulse density: sets the speed and pulse "
                                   "rate of an airborne survey")
    altitude: float | None = option(None, unit="m", range="(0, inf)",
                                    help="flying height above the scene's lowest point "
                                    "(default: the platform's)")
    speed: float | None = option(None, unit="m/s", range="(0, inf)",
                                 help="platform speed (default: the platform's, or planned)")
    overlap: float = option(0.3, range="[0, 1)", help="side overlap of adjacent strips")
    heading: float = option(0.0, unit="deg", help="strip direction, degrees from +x")
    pulse_rate: float | None = option(None, unit="Hz", range="(0, inf)",
                                      help="pulse rate (default: the preset's highest)")
    scan_rate: float | None = option(None, unit="Hz", range="(0, inf)",
                                     help="lines, turns or periods per second "
                                     "(default: planned)")
    divergence: float | None = option(None, unit="mrad", range="[0, inf)",
                                      help="beam divergence, full angle at 1/e2 "
                                      "(default: the preset's)")
    footprint_samples: int = option(5, range="[1, 15]",
                                    help="sub-rays per side of the footprint (n x n, odd)")
    bin_ns: float = option(0.5, unit="ns", range="(0, 10]", help="waveform sampling interval")
    max_returns: int | None = option(None, range="[1, 15]",
                                     help="returns per pulse (default: the preset's)")
    min_separation: float | None = option(None, unit="m", range="[0, inf)",
                                          help="echoes closer than this are one (default: "
                                          "the preset's, else the pulse's width in range)")
    detection: str | None = option(None, help="the receiver's echo detection: waveform "
                                   "(of two close echoes the stronger is kept) or discrete "
                                   "(the earlier, then a dead time) (default: the preset's)")
    stations: int = option(1, range="[1, 1000]", help="terrestrial stations (a grid)")
    angular_step: float = option(0.2, unit="deg", range="(0, 10]",
                                 help="terrestrial angular step between points and lines")
    intensity_range: float | None = option(None, unit="m", range="(0, inf)",
                                           help="range at which a white target saturates "
                                           "the intensity (default: half the nominal range)")
    gps_start: float = option(4.0e8, unit="s", help="adjusted standard GPS time of the first "
                              "pulse (GPS seconds - 1e9)")
    block: int = option(20000, range="[100, 10000000]", help="pulses simulated at a time")
    per_strip: bool = option(False, help="also keep each strip or station as "
                             "strips/NNNN.laz")
    workers: int = option(1, range="[1, 1024]", help="local worker processes for the legs")
    scheduler: str | None = option(None, help="Dask scheduler address (tcp://host:8786): "
                                   "legs run there instead of local processes")
    seed: int = option(0, range="[0, inf)", help="range-noise seed")

    def __post_init__(self):
        if self.platform is not None and self.platform not in PLATFORMS:
            raise InputError(f"expected one of {', '.join(PLATFORMS)}, got {self.platform!r}",
                             field="platform")
        if self.footprint_samples % 2 == 0:
            raise InputError(f"expected an odd number, got {self.footprint_samples}",
                             field="footprint_samples")


def leg_rng(seed: int, leg: Leg, index: int) -> np.random.Generator:
    """The range-noise generator of leg ``index``: the same whatever runs it, and where."""
    return np.random.default_rng([int(seed), int(index), int(leg.source_id)])


def station_positions(bounds: np.ndarray, n: int) -> np.ndarray:
    """``(n, 2)`` station xy on a grid over the middle 60 % of ``bounds`` ((2, 3))."""
    k = int(np.ceil(np.sqrt(n)))
    lo, hi = bounds[0, :2], bounds[1, :2]
    c, half = (lo + hi) / 2, 0.3 * (hi - lo)
    u = np.linspace(-1, 1, k) if k > 1 else np.zeros(1)
    g = np.array([[c[0] + a * half[0], c[1] + b * half[1]] for b in u for a in u])
    return g[:n]


def plan_survey(world: LidarWorld, bounds: np.ndarray, config: LidarCaptureConfig,
                preset: ScannerPreset | None = None) -> SurveyPlan:
    """The legs of the survey of a scene with ``bounds (2, 3)`` (local frame)."""
    preset = preset or get_preset(config.preset)
    platform = config.platform or preset.platform
    if config.density is not None and platform not in ("airplane", "multicopter"):
        raise InputError(f"a target density plans airborne strips; the {platform} of "
                         f"{preset.name} is not flown (give --platform multicopter)",
                         field="density")
    if platform in ("airplane", "multicopter"):
        return plan_strips(bounds[:, :2], float(bounds[0, 2]), preset, platform=platform,
                           altitude=config.altitude, speed=config.speed,
                           overlap=config.overlap, density=config.density,
                           pulse_rate=config.pulse_rate, scan_rate=config.scan_rate,
                           heading_deg=config.heading, gps_start=config.gps_start)
    h = PLATFORM_DEFAULTS[platform].altitude_m
    if platform == "tripod":
        xy = station_positions(bounds, config.stations)
        z = world.ground_z(xy) + h
        return plan_stations(np.column_stack([xy, z]), preset,
                             angular_step_deg=config.angular_step,
                             pulse_rate=config.pulse_rate, gps_start=config.gps_start)
    a = np.radians(config.heading)
    c = bounds.mean(0)[:2]
    half = 0.5 * np.abs(np.array([np.cos(a), np.sin(a)]) @ (bounds[1, :2] - bounds[0, :2]))
    s = np.linspace(-half, half, max(2, int(2 * half / 5.0) + 1))
    xy = c + s[:, None] * np.array([np.cos(a), np.sin(a)])
    z = world.ground_z(xy) + h
    return plan_path(np.column_stack([xy, z]), preset, speed=config.speed,
                     pulse_rate=config.pulse_rate, scan_rate=config.scan_rate,
                     gps_start=config.gps_start, platform=platform)


def make_scanner(config: LidarCaptureConfig, preset: ScannerPreset,
                 plan: SurveyPlan) -> Scanner:
    """The simulated scanner of a planned survey."""
    return Scanner.from_preset(preset, pulse_rate=plan.pulse_rate,
                               scan_rate=config.scan_rate or plan.scan_rate,
                               divergence_mrad=config.divergence,
                               footprint_samples=config.footprint_samples,
                               bin_ns=config.bin_ns, min_separation_m=config.min_separation,
                               max_returns=config.max_returns, detection=config.detection)


def nominal_range(plan: SurveyPlan) -> float:
    """The survey's typical range: the flying height, or 10 m from the ground."""
    return float(plan.altitude) if plan.platform in ("airplane", "multicopter") else 10.0


def _las_chunk(ch: dict, origin: np.ndarray, intensity_range: float) -> dict:
    return {"x": ch["x"] + origin[0], "y": ch["y"] + origin[1], "z": ch["z"] + origin[2],
            "intensity": intensity_counts(ch["energy"], intensity_range),
            "return_number": ch["return_number"], "number_of_returns": ch["number_of_returns"],
            "gps_time": ch["gps_time"], "scan_angle": ch["scan_angle"],
            "point_source_id": ch["point_source_id"], "classification": ch["classification"],
            "object_id": ch["object_id"], "part": ch["part"],
            "true_x": ch["true_x"] + origin[0], "true_y": ch["true_y"] + origin[1],
            "true_z": ch["true_z"] + origin[2], "snr": ch["snr"],
            "echo_energy": ch["energy"].astype(np.float32), "scan_row": ch["row"],
            "scan_column": ch["column"]}


def _summary_add(s: dict, ch: dict, area: np.ndarray | None) -> None:
    first = ch["return_number"] == 1
    s["points"] += len(ch["x"])
    s["pulses_with_echo"] += int(first.sum())
    s["pulses_multiple"] += int((first & (ch["number_of_returns"] > 1)).sum())
    s["by_return"] += np.bincount(ch["return_number"], minlength=16)[:16]
    s["by_class"] += np.bincount(ch["classification"], minlength=256)[:256]
    s["by_part"] += np.bincount(ch["part"], minlength=len(PARTS))[:len(PARTS)]
    if area is not None:
        inside = ((ch["x"] >= area[0, 0]) & (ch["x"] <= area[1, 0])
                  & (ch["y"] >= area[0, 1]) & (ch["y"] <= area[1, 1]))
        s["points_in_area"] += int(inside.sum())
        s["first_in_area"] += int((inside & first).sum())


def _new_summary(leg: Leg, n_pulses: int) -> dict:
    return {"source_id": int(leg.source_id), "pulses": int(n_pulses), "points": 0,
            "pulses_with_echo": 0, "pulses_multiple": 0, "points_in_area": 0,
            "first_in_area": 0, "by_return": np.zeros(16, np.int64),
            "by_class": np.zeros(256, np.int64), "by_part": np.zeros(len(PARTS), np.int64)}


def scan_leg_to_las(world: LidarWorld, scanner: Scanner, leg: Leg, index: int,
                    writer: LasWriter, *, origin: np.ndarray, seed: int, block: int,
                    intensity_range: float, area: np.ndarray | None = None) -> dict:
    """Simulate leg ``index`` into an open :class:`core.io.las.LasWriter`; its summary
    (counts by return, class and part; points and first returns inside ``area``, (2, 2)
    local xy)."""
    n = int(np.floor(leg.duration * scanner.pulse_rate))
    s = _new_summary(leg, n)
    for ch in scan_leg(world, scanner, leg, rng=leg_rng(seed, leg, index), block=block):
        writer.write(_las_chunk(ch, origin, intensity_range))
        _summary_add(s, ch, area)
    return s


def merge_las(paths: list, out: str | os.PathLike, *, origin: np.ndarray,
              crs_wkt: str | None = None, chunk: int = 1_000_000) -> int:
    """Concatenate LAS/LAZ files written by :func:`scan_leg_to_las` into ``out``, chunk
    by chunk (memory bounded by ``chunk``); the number of points."""
    n = 0
    with LasWriter(out, origin=origin, extra=LAS_EXTRA, crs_wkt=crs_wkt) as w:
        for p in paths:
            try:
                for pts, _ in iter_las_chunks(p, chunk):
                    w.write(pts)
                    n += len(pts["x"])
            except InputError as e:
                if e.field != "points":      # a leg with no points is an empty file
                    raise
    return n


def strip_name(source_id: int, index: int) -> str:
    """The file of leg ``index`` under ``strips/``."""
    return f"{index:04d}_source{source_id}.laz"


def e57_scan(path: str | os.PathLike, leg: Leg, origin: np.ndarray):
    """The E57 scan of a station from its LAS file (scan frame: the station, the world's
    axes; its row/column grid from the scan lines)."""
    from core.io.e57 import E57Scan
    from core.io.las import read_las

    pts, _ = read_las(path, fields=("x", "y", "z", "intensity", "scan_row", "scan_column"))
    T = np.eye(4)
    T[:3, 3] = np.asarray(leg.start) + origin
    xyz = np.column_stack([pts["x"], pts["y"], pts["z"]]) - T[:3, 3]
    return E57Scan(f"station {leg.source_id}", xyz, T, row=pts["scan_row"].astype(np.int64),
                   column=pts["scan_column"].astype(np.int64),
                   intensity=pts["intensity"] / 65535.0)


def summary_report(summaries: list, plan: SurveyPlan, area: np.ndarray) -> dict:
    """Totals of the legs' summaries: counts, the multiple-return share and the density
    achieved over ``area`` ((2, 2) local xy)."""
    tot = {k: sum(s[k] for s in summaries) for k in
           ("pulses", "points", "pulses_with_echo", "pulses_multiple", "points_in_area",
            "first_in_area")}
    by_return = np.sum([s["by_return"] for s in summaries], axis=0)
    by_class = np.sum([s["by_class"] for s in summaries], axis=0)
    by_part = np.sum([s["by_part"] for s in summaries], axis=0)
    a = float(np.prod(area[1] - area[0]))
    return {**tot,
            "multiple_return_share": tot["pulses_multiple"] / max(tot["pulses_with_echo"], 1),
            "area_m2": a,
            "density_first_per_m2": tot["first_in_area"] / a if a > 0 else None,
            "density_all_per_m2": tot["points_in_area"] / a if a > 0 else None,
            "density_target_per_m2": plan.density_target,
            "by_return": {str(i): int(c) for i, c in enumerate(by_return) if c},
            "by_class": {str(i): int(c) for i, c in enumerate(by_class) if c},
            "by_part": {PARTS[i]: int(c) for i, c in enumerate(by_part) if c},
            "legs": [{"source_id": s["source_id"], "pulses": s["pulses"], "points": s["points"]}
                     for s in summaries]}
