"""The pulsed scanner: pulses along a leg, their footprints cast into the world, their
waveforms, echoes and points, yielded in chunks.

For each block of pulses (so that memory does not grow with the survey): the platform
gives the scanner's position and orientation at each pulse's GPS time
(:mod:`acquire.lidar.platforms`), the scan pattern the beam's direction
(:mod:`acquire.lidar.patterns`), the divergence its sub-rays (:mod:`acquire.lidar.beam`);
the sub-rays are cast into the world with Embree (Open3D ``RaycastingScene``, the
render scene's own); each hit returns ``w rho cos(theta) / R^2`` at the laser's
wavelength; the waveform gives the echoes (:mod:`acquire.lidar.waveform`), each placed
on the beam's axis at its range plus the range noise of its SNR. Every point keeps its
truth: the object and part of the sub-ray that made its echo, and where that sub-ray hit.

Points are in the scene's local frame (metres); the caller adds the scene's origin.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from acquire.lidar.beam import subray_pattern
from acquire.lidar.labels import PARTS, VEGETATION_PARTS, asprs_class
from acquire.lidar.patterns import ScanPattern
from acquire.lidar.platforms import Leg
from acquire.lidar.presets import ScannerPreset
from acquire.lidar.waveform import SPEED_OF_LIGHT, Receiver, detect_echoes
from core.validate import InputError

__all__ = ["Scanner", "LidarWorld", "scan_leg", "fire", "reflectance_at", "CHUNK_FIELDS",
           "intensity_counts"]

#: Fields of every chunk :func:`scan_leg` yields (each (k,) over the chunk's points).
CHUNK_FIELDS = ("x", "y", "z", "gps_time", "energy", "snr", "return_number",
                "number_of_returns", "scan_angle", "point_source_id", "object_id", "part",
                "true_x", "true_y", "true_z", "range", "classification", "pulse", "row",
                "column")
_GROUND = PARTS.index("ground")
_VEG = [PARTS.index(p) for p in VEGETATION_PARTS]
_GLASS = PARTS.index("glass")
_VISIBLE_NM = (465.0, 532.0, 620.0)     # blue, green, red of a material's albedo


def reflectance_at(material, wavelength_nm: float) -> float:
    """A material's diffuse reflectance at a laser wavelength: its LiDAR reflectance in
    the near infrared (:meth:`Material.lidar_reflectance_at`), its albedo's colours
    (interpolated between 465, 532 and 620 nm) in the visible (a green laser)."""
    if wavelength_nm < 750.0:
        a = np.asarray(material.albedo, np.float64)
        return float(np.interp(wavelength_nm, _VISIBLE_NM, a[::-1]))
    return float(material.lidar_reflectance_at(wavelength_nm))


def intensity_counts(energy: np.ndarray, reference_range_m: float) -> np.ndarray:
    """LAS intensity (uint16) of echo energies: 65535 is a white Lambertian target at
    normal incidence at ``reference_range_m`` (brighter echoes saturate)."""
    full = 1.0 / float(reference_range_m) ** 2
    return np.clip(np.round(np.asarray(energy) / full * 65535.0), 0, 65535).astype(np.uint16)


@dataclass(frozen=True)
class Scanner:
    """A scanner as simulated: its pattern, rate, beam and receiver.

    Build it with :meth:`from_preset`. ``divergence_rad`` is the full cone angle;
    ``footprint_samples`` the sub-rays per side (``n x n``, odd).
    """

    preset: ScannerPreset
    pattern: ScanPattern
    pulse_rate: float
    divergence_rad: float
    footprint_samples: int
    receiver: Receiver
    wavelength_nm: float
    min_range_m: float

    @classmethod
    def from_preset(cls, preset: ScannerPreset, *, pulse_rate: float | None = None,
                    scan_rate: float | None = None, divergence_mrad: float | None = None,
                    footprint_samples: int = 5, bin_ns: float = 0.5,
                    min_separation_m: float | None = None,
                    max_returns: int | None = None,
                    detection: str | None = None) -> Scanner:
        """The preset's scanner, with any of its settings changed."""
        prr = float(pulse_rate or preset.pulse_rate_hz)
        if prr <= 0:
            raise InputError(f"expected a positive pulse rate, got {prr}", field="pulse_rate")
        rate = float(scan_rate or np.mean(preset.scan_rate_hz))
        pattern = ScanPattern(preset.pattern, fov_deg=tuple(preset.fov_deg), rate_hz=rate,
                              channels_deg=tuple(preset.channels_deg),
                              prism_hz=tuple(preset.prism_hz) or (-77.733, 121.567))
        div = float(divergence_mrad if divergence_mrad is not None else preset.divergence_mrad)
        if div < 0:
            raise InputError(f"expected a divergence >= 0, got {div}", field="divergence")
        sigma = SPEED_OF_LIGHT * preset.pulse_width_ns * 1e-9 / 2.0 / (2 * np.sqrt(2 * np.log(2)))
        snr_ref = (sigma / preset.precision_m) ** 2
        e_ref = preset.reference_reflectance / preset.precision_range_m ** 2
        fwhm_m = SPEED_OF_LIGHT * preset.pulse_width_ns * 1e-9 / 2.0
        if min_separation_m is None:
            min_separation_m = preset.min_separation_m or fwhm_m
        rx = Receiver(pulse_width_ns=preset.pulse_width_ns, bin_ns=float(bin_ns),
                      threshold=preset.reference_reflectance / preset.max_range_m ** 2,
                      noise_energy=e_ref / snr_ref, min_separation_m=float(min_separation_m),
                      max_returns=int(max_returns or preset.max_returns),
                      detection=str(detection or preset.detection))
        return cls(preset, pattern, prr, div * 1e-3, int(footprint_samples), rx,
                   float(preset.wavelength_nm), float(preset.min_range_m))


class LidarWorld:
    """What the scanner needs of a render scene, prepared once: the Embree scene, each
    object's id and reflectance at the wavelength, each triangle's part, and a scene of
    the ground alone (for heights above ground)."""

    def __init__(self, render_scene, wavelength_nm: float):
        import open3d as o3d

        self.rs, parts, self.lut = render_scene.raycasting()
        objs = render_scene.objects
        self.object_ids = np.array([o.object_id for o in objs], np.int32)
        self.reflectance = np.array([reflectance_at(o.material, wavelength_nm) for o in objs])
        self.leaf_area_density = np.array([o.leaf_area_density or 0.0 for o in objs])
        self.has_media = bool(np.any(self.leaf_area_density > 0))
        counts = [len(p[1]) for p in parts]
        self.face_offset = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        self.face_part = np.concatenate([
            o.part_labels if o.part_labels is not None else np.zeros(c, np.uint8)
            for o, c in zip(objs, counts, strict=True)]).astype(np.uint8)
        self.has_glass = bool(np.any(self.face_part == _GLASS))
        self.ground = None
        vs, fs, nv = [], [], 0
        for (vw, f, _), off in zip(parts, self.face_offset[:-1], strict=True):
            sel = self.face_part[off:off + len(f)] == _GROUND
            if sel.any():
                vs.append(vw)
                fs.append(f[sel] + nv)
                nv += len(vw)
        if fs:
            self.ground = o3d.t.geometry.RaycastingScene()
            tm = o3d.t.geometry.TriangleMesh()
            tm.vertex.positions = o3d.core.Tensor(np.vstack(vs).astype(np.float32))
            tm.triangle.indices = o3d.core.Tensor(np.vstack(fs).astype(np.int32))
            self.ground.add_triangles(tm)
        b = render_scene.bounds()
        self.top, self.bottom = float(b[1, 2]) + 10.0, float(b[0, 2])

    def cast_energy(self, rays: np.ndarray, weights: np.ndarray, min_range: float):
        """Cast ``rays (n*s, 6) float32`` (pulse-major, ``s`` sub-rays of weights
        ``weights (s,)`` each); returns ``((R, E), obj, face)``, each ``(n*s,)``: range
        (inf: no return), energy ``w rho cos / R^2``, object index (-1), flat face.
        Sub-rays that reach foliage media go on through them to their leaves
        (:func:`acquire.lidar.medium.through_media`)."""
        import open3d as o3d

        from acquire.lidar import _kernels
        from acquire.lidar.medium import through_media

        ans = self.rs.cast_rays(o3d.core.Tensor.from_numpy(rays))
        m = len(rays)
        R, E = np.empty(m), np.empty(m)
        obj, face = np.empty(m, np.int64), np.empty(m, np.int64)
        _kernels.hits_to_energy(ans["t_hit"].numpy(), ans["geometry_ids"].numpy(),
                                ans["primitive_ids"].numpy(), ans["primitive_normals"].numpy(),
                                rays, weights, self.lut, self.face_offset, self.reflectance,
                                float(min_range), R, E, obj, face)
        if self.has_media:
            through_media(self, rays, weights, R, E, obj, face, float(min_range),
                          normals=ans["primitive_normals"].numpy())
        return (R, E), obj, face

    def through_glass(self, rays, weights, R, E, obj, face, min_range):
        """Sub-rays that hit glass go on through it: the glass returns its own (weak)
        echo and passes ``1 - rho`` of the light each way, so what lies behind returns
        ``(1 - rho)^2`` of its energy. Returns the hits as ``layers`` stacked copies of
        ``(n*s,)`` arrays (1 layer without glass, 2 with) and ``layers``."""
        g = np.flatnonzero(self.face_part[face] == _GLASS) if self.has_glass else []
        g = g[np.isfinite(R[g])] if len(g) else g
        if not len(g):
            return R, E, obj, face, 1
        sub = rays[g].copy()
        sub[:, :3] += sub[:, 3:] * (R[g, None] + 1e-4).astype(np.float32)
        (R2, E2), obj2, face2 = self.cast_energy(sub, weights, 0.0)
        rho_g = self.reflectance[obj[g]]
        Rt = np.where(np.isfinite(R2), R[g] + 1e-4 + R2, np.inf)
        with np.errstate(invalid="ignore", divide="ignore"):
            E2 = np.where(np.isfinite(Rt), E2 * (R2 / Rt) ** 2 * (1 - rho_g) ** 2, 0.0)
        Rb, Eb = np.full(len(R), np.inf), np.zeros(len(R))
        ob, fb = np.full(len(R), -1, np.int64), np.zeros(len(R), np.int64)
        Rb[g], Eb[g], ob[g], fb[g] = Rt, E2, obj2, face2
        Rb[Rb < min_range] = np.inf
        return (np.concatenate([R, Rb]), np.concatenate([E, Eb]), np.concatenate([obj, ob]),
                np.concatenate([face, fb]), 2)

    def ground_z(self, xy: np.ndarray) -> np.ndarray:
        """Height of the ground (the whole scene when it has no ground part) below
        ``xy (n, 2)``; the scene's lowest point where nothing lies below."""
        import open3d as o3d

        rays = np.zeros((len(xy), 6), np.float32)
        rays[:, :2] = xy
        rays[:, 2] = self.top
        rays[:, 5] = -1.0
        scene = self.ground if self.ground is not None else self.rs
        t = scene.cast_rays(o3d.core.Tensor.from_numpy(rays))["t_hit"].numpy()
        z = self.top - t.astype(np.float64)
        return np.where(np.isfinite(z), z, self.bottom)

    def ground_height(self, points: np.ndarray) -> np.ndarray | None:
        """Height of ``points (n, 3)`` above the ground below them (None without ground;
        NaN where no ground lies below)."""
        import open3d as o3d

        if self.ground is None:
            return None
        rays = np.zeros((len(points), 6), np.float32)
        rays[:, :2] = points[:, :2]
        rays[:, 2] = self.top
        rays[:, 5] = -1.0
        t = self.ground.cast_rays(o3d.core.Tensor.from_numpy(rays))["t_hit"].numpy()
        return points[:, 2] - (self.top - t.astype(np.float64))


def _pulse_geometry(scanner: Scanner, leg: Leg, k: np.ndarray):
    """Times, positions, beam axes (world), scan angles and line indices of pulses ``k``."""
    t = k / scanner.pulse_rate
    pos, R = leg.poses(t)
    d_s, ang = scanner.pattern.directions(t, k)
    d = d_s @ R[0].T if len(R) == 1 else np.einsum("nij,nj->ni", R, d_s)
    return t, pos, d, ang


def _grid(scanner: Scanner, t: np.ndarray, k: np.ndarray, line0: int):
    """Row (pulse within its line) and column (line) of each pulse: the scan grid."""
    pat = scanner.pattern
    line = pat.line_index(t)
    per = pat.rate_hz * (2.0 if pat.kind == "oscillating" else 1.0)
    first = np.ceil(line / per * scanner.pulse_rate - 1e-9).astype(np.int64)
    return (k - first).astype(np.int32), (line - line0).astype(np.int32)


def scan_leg(world: LidarWorld, scanner: Scanner, leg: Leg, *,
             rng: np.random.Generator, block: int = 20_000,
             max_pulses: int | None = None) -> Iterator[dict]:
    """Simulate one leg; yield a chunk (dict of :data:`CHUNK_FIELDS` arrays) per block of
    ``block`` pulses that returned echoes. ``max_pulses`` stops early (tests)."""
    n = int(np.floor(leg.duration * scanner.pulse_rate))
    if max_pulses is not None:
        n = min(n, int(max_pulses))
    line0 = int(scanner.pattern.line_index(np.zeros(1))[0])
    for k0 in range(0, n, int(block)):
        k = np.arange(k0, min(k0 + int(block), n), dtype=np.int64)
        chunk = _scan_block(world, scanner, leg, k, rng, line0)
        if chunk is not None:
            yield chunk


def fire(world: LidarWorld, scanner: Scanner, origins: np.ndarray, directions: np.ndarray, *,
         rng: np.random.Generator) -> dict:
    """The echoes of pulses fired from ``origins (n, 3)`` along unit ``directions (n, 3)``
    (world frame): a dict of (k,) arrays, ``pulse`` (index into the n pulses), ``x, y,
    z`` (measured), ``range`` (measured) and ``range_true`` (noise-free), ``energy``,
    ``snr``, ``return_number``, ``number_of_returns``, ``object_id``, ``part``,
    ``true_x, true_y, true_z`` and ``classification``."""
    from acquire.lidar.beam import pack_rays

    pos = np.ascontiguousarray(origins, np.float64)
    d = np.ascontiguousarray(directions, np.float64)
    offsets, weights = subray_pattern(scanner.footprint_samples)
    s = len(weights)
    rays = pack_rays(pos, d, scanner.divergence_rad, offsets)
    (R, E), obj, face = world.cast_energy(rays, weights, scanner.min_range_m)
    R, E, obj, face, layers = world.through_glass(rays, weights, R, E, obj, face,
                                                  scanner.min_range_m)
    # per pulse: its s sub-rays' first hits, then (glass) what they met behind the glass
    ech = detect_echoes(_per_pulse(R, s, layers), _per_pulse(E, s, layers), scanner.receiver)
    p = ech["pulse"]
    q = p * s + ech["subray"] % s                    # the ray
    j = (ech["subray"] // s) * len(rays) + q         # its hit, in the layered arrays
    snr = ech["energy"] / scanner.receiver.noise_energy
    r_meas = ech["range"] + scanner.receiver.range_sigma(snr) * rng.standard_normal(len(p))
    xyz = pos[p] + d[p] * r_meas[:, None]
    true = pos[p] + rays[q, 3:].astype(np.float64) * R[j, None]
    part = world.face_part[face[j]]
    veg = np.isin(part, _VEG)
    hag = world.ground_height(true[veg]) if veg.any() else None
    if hag is not None:
        h = np.full(len(part), 1e9)
        h[veg] = np.nan_to_num(hag, nan=1e9)
        hag = h
    return {"pulse": p, "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], "range": r_meas,
            "range_true": ech["range"], "energy": ech["energy"], "snr": snr.astype(np.float32),
            "return_number": ech["return_number"], "number_of_returns": ech["number_of_returns"],
            "object_id": world.object_ids[np.maximum(obj[j], 0)], "part": part,
            "true_x": true[:, 0], "true_y": true[:, 1], "true_z": true[:, 2],
            "classification": asprs_class(part, hag)}


def _per_pulse(a: np.ndarray, s: int, layers: int) -> np.ndarray:
    """``(layers * n * s,)`` layer-major hits -> ``(n, layers * s)`` per pulse."""
    if layers == 1:
        return a.reshape(-1, s)
    return np.ascontiguousarray(a.reshape(layers, -1, s).transpose(1, 0, 2).reshape(
        -1, layers * s))


def _scan_block(world, scanner, leg, k, rng, line0):
    t, pos, d, ang = _pulse_geometry(scanner, leg, k)
    ech = fire(world, scanner, pos, d, rng=rng)
    p = ech.pop("pulse")
    if len(p) == 0:
        return None
    ech.pop("range_true")
    row, col = _grid(scanner, t[p], k[p], line0)
    return {**ech, "gps_time": leg.gps_start + t[p], "scan_angle": ang[p].astype(np.float32),
            "point_source_id": np.full(len(p), leg.source_id, np.uint16), "pulse": k[p],
            "row": row, "column": col}
