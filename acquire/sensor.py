"""The image sensor: radiance in, digital numbers out.

Model (per pixel and channel): electrons = Poisson(radiance * exposure * full_well
* vignetting) + Normal(0, read_noise); DN = round(electrons * gain / full_well *
(2^bits - 1)), clipped at full scale (saturation). Radiance 1 at exposure 1 and gain
1 fills the well. Optional Gaussian blur (optics) before sampling noise.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from core.config import Config, option
from core.validate import check_array

__all__ = ["Sensor"]


@dataclass
class Sensor(Config):
    """Sensor settings (all recorded in capture.json; TOML table ``[sensor]``)."""

    exposure: float = option(1.0, range="(0, inf)",
                             help="scales radiance to the fraction of the well filled")
    gain: float = option(1.0, range="(0, inf)", help="analog gain applied to electrons")
    full_well: float = option(20000.0, unit="e-", range="(0, inf)",
                              help="electrons at saturation (shot-noise SNR sqrt(full_well))")
    read_noise: float = option(2.0, unit="e-", range="[0, inf)",
                               help="read noise standard deviation")
    bit_depth: int = option(8, choices=(8, 16), help="digital numbers per pixel")
    blur_sigma: float = option(0.0, unit="px", range="[0, inf)",
                               help="optics blur (Gaussian sigma; 0 = none)")
    vignetting: float = option(0.0, range="[0, 1)",
                               help="relative fall-off at the image corner")
    mono: bool = option(False, help="average the channels (a monochrome sensor)")
    shot_noise: bool = option(True, help="Poisson photon noise")

    @classmethod
    def ideal(cls, **kw) -> Sensor:
        """A noise-free sensor (quantization and saturation only)."""
        return cls(read_noise=0.0, shot_noise=False, **kw)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> Sensor:
        return cls(**d)

    def apply(self, radiance: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Digitize ``radiance (H, W) or (H, W, 3)`` into uint8/uint16 (``(H, W)`` if mono)."""
        import cv2

        rad = check_array(radiance, "radiance", dtype=np.float64)
        if rad.ndim not in (2, 3):
            raise ValueError(f"radiance: expected shape (H, W) or (H, W, 3), got {rad.shape}")
        if self.mono and rad.ndim == 3:
            rad = rad.mean(axis=2)
        if self.blur_sigma > 0:
            rad = cv2.GaussianBlur(rad, (0, 0), self.blur_sigma, borderType=cv2.BORDER_REFLECT)
        if self.vignetting > 0:
            H, W = rad.shape[:2]
            v, u = np.mgrid[0:H, 0:W]
            r2 = ((u - (W - 1) / 2) ** 2 + (v - (H - 1) / 2) ** 2) / (((W - 1) / 2) ** 2
                                                                      + ((H - 1) / 2) ** 2)
            fall = 1.0 - self.vignetting * r2
            rad = rad * (fall if rad.ndim == 2 else fall[:, :, None])
        electrons = np.clip(rad, 0, None) * self.exposure * self.full_well
        if self.shot_noise:
            electrons = rng.poisson(np.minimum(electrons, 1e12)).astype(np.float64)
        if self.read_noise > 0:
            electrons = electrons + rng.normal(0.0, self.read_noise, electrons.shape)
        full = 2 ** self.bit_depth - 1
        dn = np.rint(electrons * self.gain / self.full_well * full)
        dtype = np.uint8 if self.bit_depth == 8 else np.uint16
        return np.clip(dn, 0, full).astype(dtype)
