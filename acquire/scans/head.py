"""The range scanner's head: a camera and a line laser on a linear sweep, with its factory
geometry and its on-board peak detection.

Like a Cyberware or Minolta head, the scanner knows its own geometry: its camera and the
laser's sweep are built and calibrated at the factory, so every profile it measures comes
out in the scanner's own frame without any calibration by the user. Here that geometry is
the design itself (the camera is distortion-free, the sheet is where it was designed). The
scanner's frame is its camera's (OpenCV: x right, y down, z forward) and the camera stays
put: the laser alone rides the linear sweep, so every line of sight passes through the
origin (a range image seen from the origin, as :mod:`reconstruct.scans` assumes).

Geometry (scanner frame, metres)::

    camera at the origin looking along +z
    laser at (x_s + B, 0, 0), B = standoff * tan(triangulation angle), x_s the sweep
          position of step s; its sheet holds the y axis and, at x_s = 0, crosses the
          optical axis at z = standoff (the sheet translates: its normal is fixed)

so the stripe runs down the image (one peak per image row, the profile) and the sweep moves
it across. A scan is a range grid: row ``s`` is sweep step ``s``, column ``v`` image row
``v``. The default sweep crosses the camera's horizontal field at the stand-off.

The firmware (:func:`stripe_peaks`) finds in each image row the brightest column and refines
it to the centroid of the light above the row's median within ``window`` pixels; a row whose
peak does not stand ``min_peak`` digital numbers above its median has no sample. The camera
ray through ``(row, sub-pixel column)`` meets the sheet of that step
(:meth:`ScanHead.triangulate`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acquire.camera import Camera
from acquire.render.laser_sheet import LaserSheet
from core.config import Config, option
from core.validate import check_array

__all__ = ["ScanHead", "stripe_peaks"]


@dataclass
class ScanHead(Config):
    """The scanner head (TOML table ``[head]``): camera, laser, sweep and firmware.
    Angles in degrees, lengths in metres."""

    standoff: float = option(0.40, unit="m", range="(0, inf)",
                             help="working distance: where the sheet crosses the optical axis "
                                  "mid-sweep")
    height: int = option(160, unit="px", range="[8, 8192]",
                         help="image rows: samples along each profile")
    width: int = option(160, unit="px", range="[8, 8192]", help="image columns")
    fov_deg: float = option(32.0, unit="deg", range="[1, 120]",
                            help="field of view along the image rows (vertical)")
    triangulation_angle_deg: float = option(35.0, unit="deg", range="[1, 80]",
                                            help="angle between the camera axis and the sheet")
    steps: int = option(100, range="[2, 100000]", help="sweep steps: profiles per scan")
    sweep_length: float | None = option(None, unit="m", range="(0, inf)",
                                        help="travel of the laser (none: the camera's "
                                             "horizontal field at the stand-off)")
    fan_angle_deg: float = option(60.0, unit="deg", range="[1, 170]", help="laser fan angle")
    laser_thickness: float = option(0.001, unit="m", range="(0, inf)",
                                    help="sheet thickness (Gaussian standard deviation; "
                                         "about a pixel at the stand-off, for sub-pixel peaks)")
    laser_power: float = option(0.35, range="[0, inf)", help="peak irradiance of the sheet")
    speckle: float = option(0.0, range="[0, 2]", help="speckle contrast of the stripe "
                                                      "(independent pixels)")
    ambient: float = option(0.05, range="[0, inf)", help="room light while scanning")
    min_peak: float = option(12.0, unit="DN", range="(0, inf)",
                             help="firmware: a row's peak must stand this far above its median")
    window: int = option(3, unit="px", range="[1, 50]",
                         help="firmware: half-width of the peak's centroid window")

    def __post_init__(self):
        super().__post_init__()
        if self.travel / 2 >= self.baseline:
            raise ValueError(f"sweep_length: expected less than twice the baseline "
                             f"({2 * self.baseline:.4g} m; the laser would pass the camera), "
                             f"got {self.travel:.4g}")

    @property
    def baseline(self) -> float:
        """Camera to laser distance B (m) at mid-sweep."""
        return self.standoff * float(np.tan(np.radians(self.triangulation_angle_deg)))

    @property
    def focal(self) -> float:
        return 0.5 * self.height / float(np.tan(np.radians(self.fov_deg) / 2))

    @property
    def travel(self) -> float:
        """The sweep's length (m): ``sweep_length`` or the field at the stand-off."""
        if self.sweep_length is not None:
            return float(self.sweep_length)
        return self.standoff * self.width / self.focal

    def camera(self) -> Camera:
        """The head's camera: at the scanner frame's origin, no distortion."""
        f = self.focal
        return Camera(self.width, self.height, f, f, (self.width - 1) / 2,
                      (self.height - 1) / 2, np.zeros(5), np.eye(4))

    def sweep(self) -> np.ndarray:
        """Sweep positions ``(steps,)`` of the laser (m along the scanner's x), centred."""
        return np.linspace(-self.travel / 2, self.travel / 2, self.steps)

    def sheet_plane(self, x: float = 0.0) -> tuple[np.ndarray, float]:
        """``(n (3,), d)``: the sheet's plane ``n . X = d`` at sweep position ``x``."""
        B, D = self.baseline, self.standoff
        n = np.array([D, 0.0, B]) / np.hypot(D, B)
        return n, float(n[0] * (B + x))

    def laser(self, x: float = 0.0) -> LaserSheet:
        """The head's laser at sweep position ``x``, in the scanner frame."""
        n, _ = self.sheet_plane(x)
        return LaserSheet(np.array([self.baseline + x, 0.0, 0.0]), n,
                          np.array([-self.baseline, 0.0, self.standoff]),
                          np.radians(self.fan_angle_deg), self.laser_thickness,
                          self.laser_power, None, self.speckle, 0.0)

    def triangulate(self, rows: np.ndarray, cols: np.ndarray, x: float = 0.0) -> np.ndarray:
        """Points ``(k, 3)`` in the scanner frame seen at pixels ``(rows, cols) (k,)`` on the
        sheet at sweep position ``x`` (NaN where the ray misses it in front of the camera)."""
        rows = check_array(rows, "rows", shape=(None,))
        cols = check_array(cols, "cols", shape=(len(rows),), finite=False)
        cam = self.camera()
        ray = np.stack([(cols - cam.cx) / cam.fx, (rows - cam.cy) / cam.fy,
                        np.ones(len(rows))], -1)
        n, d = self.sheet_plane(x)
        denom = ray @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(np.abs(denom) > 1e-12, d / denom, np.nan)
        t[~(t > 0)] = np.nan
        return ray * t[:, None]


def stripe_peaks(image: np.ndarray, *, min_peak: float = 12.0, window: int = 3) -> np.ndarray:
    """The scanner's firmware: the stripe's sub-pixel column in each image row.

    Parameters
    ----------
    image : (H, W) uint8 or uint16 or float
    min_peak : float
        Digital numbers the row's brightest pixel must stand above the row's median.
    window : int
        Half-width (px) of the centroid window about the brightest pixel.

    Returns
    -------
    (H,) float64
        Column of the stripe's centre per row, NaN where the row has none.

    >>> img = np.zeros((2, 9)); img[0, 3:6] = [50, 100, 50]
    >>> stripe_peaks(img).tolist()[0], bool(np.isnan(stripe_peaks(img)[1]))
    (4.0, True)
    """
    img = np.asarray(image, np.float64)
    if img.ndim != 2:
        raise ValueError(f"image: expected shape (H, W), got {img.shape}")
    H, W = img.shape
    background = np.median(img, axis=1)
    peak = np.argmax(img, axis=1)
    rows = np.arange(H)
    height = img[rows, peak] - background
    offsets = np.arange(-window, window + 1)
    cols = np.clip(peak[:, None] + offsets, 0, W - 1)
    inside = (peak[:, None] + offsets >= 0) & (peak[:, None] + offsets < W)
    w = np.where(inside, np.clip(img[rows[:, None], cols] - background[:, None], 0, None), 0.0)
    total = w.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        centre = (w * cols).sum(axis=1) / total
    return np.where((height >= min_peak) & (total > 0), centre, np.nan)
