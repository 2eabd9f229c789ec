"""Simulated multi-view range scanning: the sheet-of-light head of :mod:`acquire.scans.head`
placed at ``views`` viewpoints around and above a scene, each sweeping once.

The viewpoints are spread evenly over a band of elevations (a Fibonacci lattice: equal
area per view on the sphere's band, successive azimuths a golden angle apart), each at
the head's stand-off from the centre of the scene's bounding box and looking at it; a
head may also be turned about its axis by a random roll. No turntable, and no pose goes
to the reconstruction: the true placements are written for evaluation only.

Each frame of a sweep is rendered with the laser capture's renderer (the scene's
materials, shadows, speckle) and digitised by the sensor model (shot and read noise,
quantisation); the head's firmware finds where the sheet meets the surface and
triangulates it with the head's factory geometry: by default each camera pixel's peak in
time over the sweep (spacetime analysis, Curless and Levoy 1995: free of the bias that
texture, slope and depth edges give a peak found across the stripe in each frame), so
the range grid is the camera's pixel grid; ``--head.peak spatial`` finds the stripe in
each frame's image rows instead (one profile per sweep step). See
:mod:`acquire.scans.head`. Output folder::

    scans/scan_00.ply ...  PLY range grids in each scanner's frame (core.io.range); the
                           camera at the origin saw every point
    poses.json, poses.conf the true model_from_scan of each scan (evaluation only)
    gt/mesh.ply            the scene's surface in the model (world) frame
    capture.json           kind "scans": head, sensor, views, scene reference, seed
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from acquire.camera import look_at_cam_from_world
from acquire.capture_io import write_capture
from acquire.render.laser_sheet import LaserRenderer, camera_directions
from acquire.scans.head import ScanHead, SpacetimePeaks, stripe_peaks
from acquire.sensor import Sensor
from core.config import Config, option, to_dict
from core.files import atomic_dir
from core.frames import axis_angle_matrix, rigid
from core.io.range import RangeGrid, ScanPose, write_conf, write_poses_json, write_range_grid
from core.progress import track
from core.validate import check_rng

log = logging.getLogger(__name__)

__all__ = ["ScansCaptureConfig", "view_poses", "scan_view", "grid_layout", "capture_scans"]


@dataclass
class ScansCaptureConfig(Config):
    """Everything ``scanamp capture scans`` reads: the head (``[head]``), its sensor
    (``[sensor]``), the viewpoints and the seed."""

    head: ScanHead = option(default_factory=ScanHead,
                            help="the scanner head: stand-off, resolution, sweep, laser")
    sensor: Sensor = option(default_factory=Sensor, help="the head camera's sensor (noise)")
    views: int = option(12, range="[1, 999]", help="scanner placements (one scan each)")
    elevation_min_deg: float = option(10.0, unit="deg", range="[-89, 89]",
                                      help="lowest viewpoint above the scene's centre")
    elevation_max_deg: float = option(55.0, unit="deg", range="[-89, 89]",
                                      help="highest viewpoint above the scene's centre")
    roll_deg: float = option(0.0, unit="deg", range="[0, 180]",
                             help="each head turned about its axis by a random angle up to "
                                  "this (the sweep's direction varies)")
    seed: int = option(0, range="[0, inf)", help="sensor noise, speckle and roll seed")

    def __post_init__(self):
        super().__post_init__()
        if self.elevation_min_deg > self.elevation_max_deg:
            raise ValueError(f"elevation_min_deg: expected at most elevation_max_deg "
                             f"({self.elevation_max_deg}), got {self.elevation_min_deg}")


def view_poses(n: int, aim, *, standoff: float, elevation_min_deg: float,
               elevation_max_deg: float, roll_deg: float = 0.0,
               rng: np.random.Generator | None = None) -> list[np.ndarray]:
    """``model_from_scan (4, 4)`` of ``n`` heads looking at ``aim (3,)`` from ``standoff``,
    spread over the elevation band (Fibonacci lattice), rolled up to ``roll_deg`` at random.

    >>> T = view_poses(3, [0, 0, 0], standoff=0.4, elevation_min_deg=0, elevation_max_deg=0)
    >>> [round(float(np.linalg.norm(t[:3, 3])), 9) for t in T]       # at the stand-off
    [0.4, 0.4, 0.4]
    >>> bool(np.allclose(T[0][:3, 2], -T[0][:3, 3] / 0.4))           # looking at the aim
    True
    """
    aim = np.asarray(aim, np.float64)
    lo, hi = np.sin(np.radians([elevation_min_deg, elevation_max_deg]))
    golden = np.pi * (3.0 - np.sqrt(5.0))
    if roll_deg > 0:
        rng = check_rng(rng)
    out = []
    for i in range(n):
        el = np.arcsin(lo + (i + 0.5) / n * (hi - lo))
        az = i * golden
        eye = aim + standoff * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az),
                                         np.sin(el)])
        cam_from_world = look_at_cam_from_world(eye, aim)
        if roll_deg > 0:
            roll = np.radians(rng.uniform(-roll_deg, roll_deg))
            cam_from_world = rigid(axis_angle_matrix([0, 0, 1], roll)) @ cam_from_world
        out.append(np.linalg.inv(cam_from_world))
    return out


def scan_view(renderer: LaserRenderer, head: ScanHead, model_from_scan: np.ndarray,
              sensor: Sensor, rng: np.random.Generator) -> RangeGrid:
    """One sweep of the head placed at ``model_from_scan``: the range grid it measures, in
    its own frame (:func:`grid_layout`)."""
    cam_from_world = np.linalg.inv(model_from_scan)
    sweep = head.sweep()
    frames = (sensor.apply(renderer.frame(cam_from_world,
                                          head.laser(x).transformed(model_from_scan),
                                          ambient=head.ambient, rng=rng).radiance, rng)
              for x in sweep)
    if head.peak == "spacetime":
        acc = SpacetimePeaks((head.height, head.width))
        for image in frames:
            acc.add(image)
        at = acc.positions(min_peak=head.min_peak)
        v, u = np.nonzero(np.isfinite(at))                 # row-major: the grid's order
        P = head.triangulate(v.astype(np.float64), u.astype(np.float64),
                             sweep[0] + at[v, u] * head.step)
        good = np.isfinite(P).all(axis=1)
        v, u, P = v[good], u[good], P[good]
        index = np.full((head.height, head.width), -1, np.int64)
        index[v, u] = np.arange(len(P))
        return RangeGrid(P, index, obj_info={"scanner": "scanamp_sheet_of_light"})
    rows = np.arange(head.height, dtype=np.float64)
    index = np.full((head.steps, head.height), -1, np.int64)
    points = []
    count = 0
    for s, (x, image) in enumerate(zip(sweep, frames, strict=True)):
        cols = stripe_peaks(image, min_peak=head.min_peak, window=head.window)
        ok = np.flatnonzero(np.isfinite(cols))
        P = head.triangulate(rows[ok], cols[ok], x)
        good = np.isfinite(P).all(axis=1)
        ok, P = ok[good], P[good]
        index[s, ok] = count + np.arange(len(ok))
        count += len(ok)
        points.append(P)
    return RangeGrid(np.concatenate(points) if points else np.empty((0, 3)), index,
                     obj_info={"scanner": "scanamp_sheet_of_light"})


def grid_layout(head: ScanHead) -> str:
    """What a scan's grid rows and columns are under the head's firmware."""
    if head.peak == "spacetime":
        return "row = image row, column = image column"
    return "row = sweep step, column = image row"


def capture_scans(scene, config: ScansCaptureConfig, out_dir, rng: np.random.Generator, *,
            scene_info: dict | None = None, seed: int | None = None, gt_mesh=None) -> Path:
    """Scan ``scene`` from ``config.views`` viewpoints into ``out_dir`` (module docstring).

    Parameters
    ----------
    scene : acquire.render.scene.RenderScene
        World frame (Z up); its lights are ignored (laser plus the head's ambient).
    config : ScansCaptureConfig
    out_dir : path
        Written atomically (new, or a folder scanamp wrote).
    rng : numpy.random.Generator
        Sensor noise, speckle, rolls.
    scene_info : dict, optional
        ``{"path", "name", "seed"}`` recorded in capture.json.
    gt_mesh : open3d.geometry.TriangleMesh, optional
        The scene's surface for ``gt/mesh.ply`` (default: its objects merged).
    """
    from core.io.mesh import write_mesh
    from core.meshes import merge_meshes, transform_mesh

    rng = check_rng(rng)
    head, out_dir = config.head, Path(out_dir)
    if head.peak == "spacetime" and head.sheet_steps < 0.6:
        log.warning("range scans: the sheet is %.2f sweep steps thick: too few frames "
                    "sample each pixel's temporal peak (raise --head.steps or "
                    "--head.laser-thickness)", head.sheet_steps)
    aim = scene.bounds().mean(axis=0)
    poses = view_poses(config.views, aim, standoff=head.standoff,
                       elevation_min_deg=config.elevation_min_deg,
                       elevation_max_deg=config.elevation_max_deg, roll_deg=config.roll_deg,
                       rng=rng)
    camera = head.camera()
    renderer = LaserRenderer(scene, camera, dirs_cam=camera_directions(camera))
    digits = max(2, len(str(config.views - 1)))
    names = [f"scans/scan_{i:0{digits}d}.ply" for i in range(config.views)]
    with atomic_dir(out_dir) as tmp:
        (tmp / "scans").mkdir()
        (tmp / "gt").mkdir()
        frames = []
        for name, T in zip(track(names, "range scans"), poses, strict=True):
            grid = scan_view(renderer, head, T, config.sensor, rng)
            write_range_grid(tmp / name, grid)
            frames.append({"scan": name, "points": len(grid.points)})
        write_poses_json(tmp / "poses.json", [ScanPose(n, T) for n, T in
                                              zip(names, poses, strict=True)])
        write_conf(tmp / "poses.conf", list(zip(names, poses, strict=True)))
        if gt_mesh is None:
            gt_mesh = merge_meshes([transform_mesh(o.mesh, o.world_from_object)
                                    for o in scene.objects])
        write_mesh(tmp / "gt" / "mesh.ply", gt_mesh)
        write_capture(tmp, {
            "kind": "scans", "seed": seed, "scene": scene_info or {},
            "sensor": config.sensor.to_dict(),
            "cameras": {"head": {"width": head.width, "height": head.height}},
            "rig": {"head": to_dict(head), "views": config.views,
                    "grid": grid_layout(head)},
            "frames": frames,
            "ground_truth": {"poses": "poses.json", "conf": "poses.conf",
                             "mesh": "gt/mesh.ply", "aim": aim.tolist(),
                             "view_config": to_dict(config)},
        })
    log.debug("range scans: %d views, %d points -> %s", config.views,
             sum(f["points"] for f in frames), out_dir)
    return out_dir
