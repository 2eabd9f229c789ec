"""The image sensor: radiance in, digital numbers out.

Model (per pixel and channel): electrons = Poisson(radiance * exposure * full_well
* vignetting) + Normal(0, read_noise); DN = round(electrons * gain / full_well *
(2^bits - 1)), clipped at full scale (saturation). Radiance 1 at exposure 1 and gain
1 fills the well. Optional Gaussian blur (optics) before sampling noise.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from core.validate import check_array, check_choice, check_positive, check_range

__all__ = ["Sensor"]


@dataclass
class Sensor:
    """Sensor settings (all recorded in capture.json).

    Parameters
    ----------
    exposure : float      scales radiance to the fraction of the well filled
    gain : float          analog gain applied to electrons
    full_well : float     electrons at saturation (shot noise SNR = sqrt(full_well))
    read_noise : float    read noise standard deviation in electrons
    bit_depth : {8, 16}
    blur_sigma : float    optics blur in pixels (0 = none)
    vignetting : float    relative fall-off at the image corner, in [0, 1)
    mono : bool           average the channels (a monochrome sensor)
    shot_noise : bool     Poisson photon noise on/off
    """

    exposure: float = 1.0
    gain: float = 1.0
    full_well: float = 20000.0
    read_noise: float = 2.0
    bit_depth: int = 8
    blur_sigma: float = 0.0
    vignetting: float = 0.0
    mono: bool = False
    shot_noise: bool = True

    def __post_init__(self):
        self.exposure = check_positive(self.exposure, "exposure")
        self.gain = check_positive(self.gain, "gain")
        self.full_well = check_positive(self.full_well, "full_well")
        self.read_noise = check_positive(self.read_noise, "read_noise", allow_zero=True)
        check_choice(self.bit_depth, "bit_depth", (8, 16))
        self.blur_sigma = check_positive(self.blur_sigma, "blur_sigma", allow_zero=True)
        self.vignetting = check_range(self.vignetting, "vignetting", 0, 1, hi_open=True)

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
