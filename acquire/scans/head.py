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
it across. The default sweep crosses the camera's horizontal field at the stand-off.

The firmware (``peak``) has two ways of finding where the sheet meets the surface:

- ``spacetime`` (the default; Curless and Levoy, "Better optical triangulation through
  spacetime analysis", ICCV 1995): each camera pixel follows its own intensity over the
  sweep (:class:`SpacetimePeaks`). The sheet crosses the pixel's surface point when that
  temporal profile peaks: a Gaussian in sweep position (the sheet translates with a fixed
  normal) whose centre does not depend on the point's reflectance, nor, to first order, on
  the surface's slope; the pixel sees one point, so neighbouring texture or a depth edge
  beside it (where the camera sees only part of the stripe) do not enter (the edge of a
  laser shadow, which cuts the profile in time, still does). The peak is refined to a
  sub-step sweep position by a parabola through the logarithms of the maximum and its two
  neighbours (exact for a Gaussian), after the pixel's background (its mean over the sweep
  without those three samples) is taken off; a pixel whose peak does not stand
  ``min_peak`` digital numbers above its background has no sample. The camera ray of the
  pixel meets the sheet at that interpolated sweep position. A scan is a range grid on the
  camera's pixels: **row = image row, column = image column** (like a range camera). The
  profile must be sampled finely enough for its neighbours to stand above the noise: with
  the 1 mm sheet at a 35 degree triangulation angle the default 150 steps put 0.79 steps
  in its standard deviation (100 steps: 0.53, and a peak half a step off has a neighbour
  at 2 % of it).
- ``spatial`` (:func:`stripe_peaks`): each frame's image rows, the brightest column
  refined to the centroid of the light above the row's median within ``window`` pixels
  (a row whose peak does not stand ``min_peak`` above its median has no sample); the
  camera ray through ``(row, sub-pixel column)`` meets the sheet of that step. Texture
  across the stripe, the surface's slope and depth edges pull that centroid off the
  sheet's centre. A scan is a range grid: row ``s`` is sweep step ``s``, column ``v``
  image row ``v``.

Triangulation: :meth:`ScanHead.triangulate`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acquire.camera import Camera
from acquire.render.laser_sheet import LaserSheet
from core.config import Config, option
from core.validate import check_array

__all__ = ["ScanHead", "SpacetimePeaks", "stripe_peaks"]


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
    steps: int = option(150, range="[2, 100000]",
                        help="sweep steps: frames per scan (spacetime wants the sheet at least "
                             "0.6 steps thick along its normal: sheet_steps, 0.79 by default)")
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
    peak: str = option("spacetime", choices=("spacetime", "spatial"),
                       help="firmware: spacetime (each pixel's peak over the sweep, Curless "
                            "and Levoy 1995) or spatial (each image row's centroid per frame)")
    min_peak: float = option(12.0, unit="DN", range="(0, inf)",
                             help="firmware: a peak must stand this far above its background "
                                  "(the pixel's over the sweep, or the row's median)")
    window: int = option(3, unit="px", range="[1, 50]",
                         help="firmware (spatial): half-width of the peak's centroid window")

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

    @property
    def step(self) -> float:
        """Sweep step (m): the laser's travel between two frames."""
        return self.travel / max(self.steps - 1, 1)

    @property
    def sheet_steps(self) -> float:
        """The sheet's thickness (standard deviation) in sweep steps along its normal: the
        temporal profile's standard deviation, in frames, that the spacetime firmware sees
        (0.79 with the defaults; under about 0.6 a peak's neighbours sink into the noise)."""
        n, _ = self.sheet_plane()
        return self.laser_thickness / (self.step * n[0])

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

    def triangulate(self, rows: np.ndarray, cols: np.ndarray, x=0.0) -> np.ndarray:
        """Points ``(k, 3)`` in the scanner frame seen at pixels ``(rows, cols) (k,)`` on the
        sheet at sweep position ``x`` (a float, or one per pixel ``(k,)``; NaN where the ray
        misses it in front of the camera)."""
        rows = check_array(rows, "rows", shape=(None,))
        cols = check_array(cols, "cols", shape=(len(rows),), finite=False)
        cam = self.camera()
        ray = np.stack([(cols - cam.cx) / cam.fx, (rows - cam.cy) / cam.fy,
                        np.ones(len(rows))], -1)
        n, _ = self.sheet_plane()
        d = n[0] * (self.baseline + np.asarray(x, np.float64))
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


class SpacetimePeaks:
    """The spacetime firmware (Curless and Levoy 1995): each pixel's temporal peak over a
    sweep, refined to a fraction of a step.

    Frames are fed one at a time (:meth:`add`); only running per-pixel figures are kept
    (the maximum, its step and its two neighbours, the last frame and the sum), never the
    frames themselves. :meth:`positions` gives the sub-step index of each pixel's peak.

    >>> sigma, centre = 0.8, 16.37                       # a Gaussian in time on a pedestal
    >>> acc = SpacetimePeaks((1, 1))
    >>> for s in range(40):
    ...     acc.add(np.full((1, 1), 5 + 100 * np.exp(-0.5 * ((s - centre) / sigma) ** 2)))
    >>> round(float(acc.positions(min_peak=12)[0, 0]), 3)
    16.37
    """

    def __init__(self, shape: tuple[int, int]):
        self.shape = tuple(shape)
        self.count = 0
        self._sum = np.zeros(self.shape)
        self._best = np.full(self.shape, -np.inf)
        self._at = np.full(self.shape, -1, np.int64)
        self._before = np.full(self.shape, np.nan)
        self._after = np.full(self.shape, np.nan)
        self._last = np.full(self.shape, np.nan)

    def add(self, image: np.ndarray) -> None:
        """Feed the next frame ``(H, W)`` of the sweep."""
        img = np.asarray(image, np.float64)
        if img.shape != self.shape:
            raise ValueError(f"image: expected shape {self.shape}, got {img.shape}")
        follows = self._at == self.count - 1          # the maximum was the previous frame
        self._after[follows] = img[follows]
        new = img > self._best                         # the first of equal maxima stays
        self._best[new] = img[new]
        self._at[new] = self.count
        self._before[new] = self._last[new]
        self._after[new] = np.nan
        self._sum += img
        self._last = img
        self.count += 1

    def positions(self, *, min_peak: float = 12.0) -> np.ndarray:
        """``(H, W)`` sub-step sweep index of each pixel's temporal peak (NaN: none).

        The pixel's background is its mean over the sweep without the peak and its two
        neighbours; the peak must stand ``min_peak`` above it and not be the sweep's first
        or last frame. A parabola through the logarithms of the three background-free
        samples (each floored at half a digital number) gives the centre, exact for a
        Gaussian profile however coarsely it is sampled.
        """
        if self.count < 4:
            raise ValueError(f"frames: expected at least 4 for a temporal peak, got "
                             f"{self.count}")
        a, b, c = self._before, self._best, self._after
        bg = (self._sum - a - b - c) / (self.count - 3)
        with np.errstate(invalid="ignore", divide="ignore"):
            la, lb, lc = (np.log(np.maximum(v - bg, 0.5)) for v in (a, b, c))
            curve = la - 2.0 * lb + lc
            off = np.where(curve < 0, 0.5 * (la - lc) / curve, 0.0)
        ok = np.isfinite(a) & np.isfinite(c) & (b - bg >= min_peak)
        return np.where(ok, self._at + np.clip(off, -0.5, 0.5), np.nan)
