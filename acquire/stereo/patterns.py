"""Projector patterns: random dots (active stereo), Gray code and phase shift.

All patterns are ``(H, W) float32`` images in [0, 1] at the projector's resolution
(pixel centres at integer coordinates, as for cameras).

Gray code comes from ``cv2.structured_light.GrayCodePattern`` (its order: for each
bit, most significant first, the pattern then its inverse; all column bits, then
all row bits). Phase-shift patterns are sinusoids made here:
``I_k(x) = 0.5 + 0.5 cos(2 pi x / period - 2 pi k / n)``.

>>> pats = gray_code_patterns(16, 8)
>>> len(pats), pats[0].shape
(14, (8, 16))
"""

from __future__ import annotations

import numpy as np

from core.validate import check_choice, check_int, check_positive, check_range

__all__ = ["random_dots", "gray_code_patterns", "gray_code_bits", "phase_shift_patterns",
           "white_black"]


def _size(width, height):
    return check_int(width, "width"), check_int(height, "height")


def random_dots(width: int, height: int, *, rng: np.random.Generator, density: float = 0.25,
                dot_sigma_px: float = 0.6) -> np.ndarray:
    """A random-dot (speckle) pattern as projected by active depth cameras.

    Parameters
    ----------
    width, height : int
        Projector resolution.
    rng : numpy.random.Generator
    density : float
        Fraction of projector pixels that carry a dot, in (0, 1].
    dot_sigma_px : float
        Gaussian blur of each dot in projector pixels (0 = hard pixels).

    Returns
    -------
    (height, width) float32 in [0, 1]
    """
    import cv2

    width, height = _size(width, height)
    density = check_range(density, "density", 0, 1, lo_open=True)
    dot_sigma_px = check_positive(dot_sigma_px, "dot_sigma_px", allow_zero=True)
    img = (rng.random((height, width)) < density).astype(np.float32)
    if dot_sigma_px > 0:
        img = cv2.GaussianBlur(img, (0, 0), dot_sigma_px)
        img /= max(float(img.max()), 1e-12)
    return np.clip(img, 0, 1).astype(np.float32)


def gray_code_bits(width: int, height: int) -> tuple[int, int]:
    """Number of column and row bits OpenCV's Gray code uses for a projector."""
    width, height = _size(width, height)
    return int(np.ceil(np.log2(width))), int(np.ceil(np.log2(height)))


def gray_code_patterns(width: int, height: int) -> list[np.ndarray]:
    """OpenCV's Gray-code patterns (pattern and inverse per bit; columns then rows)."""
    import cv2

    width, height = _size(width, height)
    gc = cv2.structured_light.GrayCodePattern.create(width, height)
    ok, pats = gc.generate()
    if not ok:  # pragma: no cover - OpenCV reports no failure for valid sizes
        raise RuntimeError("cv2.structured_light.GrayCodePattern.generate failed")
    return [(np.asarray(p) > 0).astype(np.float32) for p in pats]


def white_black(width: int, height: int) -> list[np.ndarray]:
    """The all-white and all-black images (shadow masks and per-pixel thresholds)."""
    width, height = _size(width, height)
    return [np.ones((height, width), np.float32), np.zeros((height, width), np.float32)]


def phase_shift_patterns(width: int, height: int, *, period_px: float, n_steps: int = 4,
                         axis: str = "x") -> list[np.ndarray]:
    """N-step sinusoidal phase-shift patterns along ``axis``.

    ``I_k = 0.5 + 0.5 cos(2 pi c / period_px - 2 pi k / n_steps)`` with ``c`` the
    projector column (``axis="x"``) or row (``axis="y"``), so the decoded phase
    ``phi = 2 pi c / period_px (mod 2 pi)``.
    """
    width, height = _size(width, height)
    period_px = check_positive(period_px, "period_px")
    check_choice(axis, "axis", {"x", "y"})
    n_steps = check_int(n_steps, "n_steps", 3)
    c = np.arange(width if axis == "x" else height, dtype=np.float64)
    out = []
    for k in range(int(n_steps)):
        line = 0.5 + 0.5 * np.cos(2 * np.pi * c / period_px - 2 * np.pi * k / n_steps)
        img = np.broadcast_to(line[None, :], (height, width)) if axis == "x" else \
            np.broadcast_to(line[:, None], (height, width))
        out.append(np.ascontiguousarray(img, dtype=np.float32))
    return out
