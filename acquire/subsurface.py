"""Subsurface scattering (marble, wax, skin, plastics): the dipole diffusion profile and
a laser stripe spread by it.

Light entering a translucent material at ``x_i`` leaves at ``x_o`` with the diffuse
reflectance profile ``Rd(|x_o - x_i|)`` of the classical dipole (Jensen et al. 2001):

    Rd(r) = a'/(4 pi) [ z_r (1 + s_tr d_r) e^(-s_tr d_r) / d_r^3
                       + z_v (1 + s_tr d_v) e^(-s_tr d_v) / d_v^3 ]

with ``d_r = sqrt(r^2 + z_r^2)``, ``d_v = sqrt(r^2 + z_v^2)``, the real source one mean
free path deep (``z_r = mfp = 1 / s_t'``), the virtual one above the surface at
``z_v = z_r (1 + 4 A / 3)``, ``A = (1 + F_dr) / (1 - F_dr)`` from the diffuse Fresnel
reflectance ``F_dr`` of the refractive index, and ``s_tr = sqrt(3 (1 - a')) / mfp``.
The material is given as a user would measure it: its **diffuse albedo** (the total
reflectance ``int Rd dA``) and its **mean free path**; the reduced scattering albedo
``a'`` is found from the albedo by inverting the dipole's total reflectance (Jensen and
Buhler 2002), so a plane lit evenly looks exactly as bright as a Lambertian plane of the
same albedo: scattering moves light, it does not make or lose it.

A laser enters along its ray, so the diffusion starts on the refracted ray rather than
straight under the entry point: as in photon beam diffusion (Habel et al. 2013) and the
directional dipole (Frisvad et al. 2014), the source sits one mean free path along the
refracted ray, which shifts the exit profile by ``mfp sin(theta_t)`` along the ray's
direction in the surface. That shift is what biases a laser scanner on marble: the peak
moves with the mean free path and with the incidence (Godin et al. 2001).

For a sheet of light the entry is a line (Gaussian across, even along), so the exit
radiance at a point is the profile integrated along the stripe (:func:`line_profile`)
convolved with the sheet's Gaussian across it (:func:`stripe_radiance`).

Under a projector or any light that varies over the surface, the exit radiance is the
irradiance convolved with ``Rd`` over the surface. ``Rd`` is written as a sum of
Gaussians (:func:`gaussian_mixture`, fitted to the dipole as d'Eon and Luebke 2007 do
for skin), so the convolution is a few separable blurs of the view's irradiance
(:func:`spread_irradiance`): fine patterns lose contrast on marble and wax, and a
structured-light code's finest bits are the first to fail (Gupta et al. 2011).

References
----------
H. W. Jensen, S. R. Marschner, M. Levoy, P. Hanrahan, "A practical model for subsurface
light transport", SIGGRAPH 2001. doi:10.1145/383259.383319
H. W. Jensen, J. Buhler, "A rapid hierarchical rendering technique for translucent
materials", SIGGRAPH 2002. doi:10.1145/566570.566619
R. Habel, P. H. Christensen, W. Jarosz, "Photon beam diffusion", EGSR 2013.
J. R. Frisvad, T. Hachisuka, T. K. Kjeldsen, "Directional dipole model for subsurface
scattering", ACM TOG 34(1), 2014. doi:10.1145/2682629
G. Godin, J.-A. Beraldin, M. Rioux, M. Levoy, L. Cournoyer, F. Blais, "An assessment of
laser range measurement of marble surfaces", Optical 3-D Measurement Techniques 2001.
E. d'Eon, D. Luebke, "Advanced techniques for realistic real-time skin rendering", GPU
Gems 3, ch. 14, 2007.
M. Gupta, A. Agrawal, A. Veeraraghavan, S. G. Narasimhan, "Structured light 3D scanning
in the presence of global illumination", CVPR 2011. doi:10.1109/CVPR.2011.5995321
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from core.validate import check_range

__all__ = ["diffuse_fresnel", "total_reflectance", "reduced_albedo", "Dipole",
           "line_profile", "stripe_radiance", "gaussian_mixture", "spread_irradiance"]


def diffuse_fresnel(eta: float) -> float:
    """Diffuse Fresnel reflectance ``F_dr`` inside a medium of relative index ``eta``
    (the polynomial fit of Egan and Hilgeman used by Jensen et al.)."""
    return -1.440 / eta ** 2 + 0.710 / eta + 0.668 + 0.0636 * eta


def total_reflectance(a: np.ndarray, eta: float) -> np.ndarray:
    """The dipole's total diffuse reflectance ``int Rd dA`` for reduced albedo ``a'``."""
    A = (1.0 + diffuse_fresnel(eta)) / (1.0 - diffuse_fresnel(eta))
    s = np.sqrt(3.0 * (1.0 - np.asarray(a, np.float64)))
    return 0.5 * a * (1.0 + np.exp(-4.0 / 3.0 * A * s)) * np.exp(-s)


def reduced_albedo(albedo: float, eta: float) -> float:
    """The reduced scattering albedo ``a'`` whose total reflectance is ``albedo``
    (bisection: the total reflectance grows with ``a'``)."""
    albedo = check_range(albedo, "albedo", 0.0, float(total_reflectance(1.0, eta)))
    lo, hi = 0.0, 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if total_reflectance(mid, eta) < albedo:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@dataclass(frozen=True)
class Dipole:
    """The dipole of a material: diffuse ``albedo``, mean free path ``mfp`` (metres),
    relative refractive index ``eta``."""

    albedo: float
    mfp: float
    eta: float = 1.5

    @property
    def a(self) -> float:
        return reduced_albedo(self.albedo, self.eta)

    @property
    def sigma_tr(self) -> float:
        """Effective transport coefficient, 1/m."""
        return float(np.sqrt(3.0 * (1.0 - self.a)) / self.mfp)

    def rd(self, r: np.ndarray) -> np.ndarray:
        """``Rd(r)`` in 1/m^2 at distances ``r`` (metres) from the entry point."""
        a, s = self.a, self.sigma_tr
        A = (1.0 + diffuse_fresnel(self.eta)) / (1.0 - diffuse_fresnel(self.eta))
        zr = self.mfp
        zv = zr * (1.0 + 4.0 / 3.0 * A)
        r2 = np.asarray(r, np.float64) ** 2
        dr, dv = np.sqrt(r2 + zr * zr), np.sqrt(r2 + zv * zv)
        return a / (4.0 * np.pi) * (zr * (1.0 + s * dr) * np.exp(-s * dr) / dr ** 3
                                    + zv * (1.0 + s * dv) * np.exp(-s * dv) / dv ** 3)

    def reach(self, fraction: float = 1e-3) -> float:
        """Distance (m) beyond which the line profile keeps less than ``fraction`` of the
        light."""
        u, p = line_profile(self)
        c = np.cumsum(p) * (u[1] - u[0])
        return float(u[np.searchsorted(c, (1.0 - fraction) * c[-1])])


@lru_cache(maxsize=64)
def _line_table(albedo: float, mfp: float, eta: float, n: int) -> tuple[np.ndarray,
                                                                       np.ndarray]:
    d = Dipole(albedo, mfp, eta)
    # beyond 40 diffusion lengths (or 60 mean free paths) nothing is left
    umax = max(40.0 / d.sigma_tr if d.sigma_tr > 0 else 0.0, 60.0 * mfp)
    umax = min(umax, 400.0 * mfp)
    u = np.linspace(0.0, umax, n)
    # int Rd(sqrt(u^2 + v^2)) dv over v in (-inf, inf): substitute v = z tan(t), which
    # concentrates the nodes where the integrand varies, and integrate over t in [0, pi/2)
    t = np.linspace(0.0, 0.5 * np.pi, 2049)[:-1]
    z = np.sqrt(u * u + mfp * mfp)[:, None]
    v = z * np.tan(t)[None, :]
    f = d.rd(np.sqrt(u[:, None] ** 2 + v * v)) * z / np.cos(t)[None, :] ** 2
    p = 2.0 * np.trapezoid(f, t, axis=1)
    return u, p


def line_profile(dipole: Dipole, *, n: int = 4001) -> tuple[np.ndarray, np.ndarray]:
    """The exit profile of a line of entry points, ``P(u) = int Rd(sqrt(u^2 + v^2)) dv``
    (1/m), on ``u >= 0`` (it is even): ``(u (n,), P (n,))``; ``2 int_0^inf P du`` is the
    albedo."""
    return _line_table(float(dipole.albedo), float(dipole.mfp), float(dipole.eta), int(n))


def stripe_radiance(dipole: Dipole, s: np.ndarray, across: np.ndarray, shift: np.ndarray,
                    sigma: float, *, nodes: int = 48) -> np.ndarray:
    """Exit radiance factor of a laser sheet on a translucent surface, per point.

    Parameters
    ----------
    dipole : Dipole
    s : (n,) float
        Signed distance of each exit point to the sheet's plane, metres.
    across : (n,) float
        ``|m_t|``, the length of the sheet normal's projection on the surface: moving
        ``u`` across the stripe on the surface moves ``u |m_t|`` off the plane.
    shift : (n,) float
        Offset of the exit profile across the stripe (metres on the surface, toward +s).
    sigma : float
        The sheet's Gaussian standard deviation, metres.

    Returns
    -------
    (n,) float
        ``int P(u_o - u_i - shift) g(s_i) du_i`` over the entry line, where ``g`` is the
        unit-peak Gaussian of the sheet: multiplied by the laser's unshadowed peak
        irradiance (no Gaussian) it is the exit radiance. A Lambertian surface of the same
        albedo gives ``albedo g(s)``; this tends to it as the mean free path goes to 0.
    """
    sigma = check_range(sigma, "sigma", 0.0, None, lo_open=True)
    u_tab, p_tab = line_profile(dipole)
    s = np.asarray(s, np.float64)
    m = np.maximum(np.asarray(across, np.float64), 1e-6)
    shift = np.broadcast_to(np.asarray(shift, np.float64), s.shape)
    # entry points across the sheet: w = signed distance to the plane, from -5 to 5 sigma,
    # fine enough for both the Gaussian and the profile's core
    step = min(sigma / 4.0, 0.5 * dipole.mfp * float(np.min(m)) + 1e-300)
    k = int(min(max(np.ceil(10.0 * sigma / step), nodes), 4096))
    w = np.linspace(-5.0 * sigma, 5.0 * sigma, k + 1)
    g = np.exp(-0.5 * (w / sigma) ** 2) * (w[1] - w[0])
    out = np.empty(len(s))
    for lo in range(0, len(s), 4096):       # bounded memory: (chunk, k) at a time
        sl = slice(lo, lo + 4096)
        u = np.abs((s[sl, None] - w[None, :]) / m[sl, None] - shift[sl, None])
        p = np.interp(u, u_tab, p_tab, right=0.0)
        out[sl] = (p * g[None, :]).sum(axis=1) / m[sl]
    return out


@lru_cache(maxsize=64)
def _mixture(albedo: float, mfp: float, eta: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    from scipy.optimize import nnls

    d = Dipole(albedo, mfp, eta)
    far = max(8.0 / d.sigma_tr if d.sigma_tr > 0 else 0.0, 20.0 * mfp)
    sig = np.geomspace(0.25 * mfp, 0.5 * far, n)
    r = np.concatenate([np.linspace(0.0, 2.0 * mfp, 200), np.geomspace(2.0 * mfp, far, 400)])
    area = 2.0 * np.pi * r          # match Rd where the light is: weighted by the ring area
    g = np.exp(-0.5 * (r[:, None] / sig) ** 2) / (2.0 * np.pi * sig ** 2)
    w, _ = nnls(g * area[:, None], d.rd(r) * area)
    keep = w > 0
    sig, w = sig[keep], w[keep]
    return sig, w * (albedo / w.sum())    # the mixture reflects exactly the albedo


def gaussian_mixture(dipole: Dipole, n: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """``Rd(r) ~ sum_k w_k exp(-r^2 / 2 s_k^2) / (2 pi s_k^2)``: standard deviations
    ``s_k`` (metres, from a quarter of the mean free path to a few diffusion lengths) and
    weights ``w_k`` (non-negative least squares on the profile weighted by the ring area
    ``2 pi r``), scaled so that ``sum w_k`` is the albedo exactly."""
    return _mixture(float(dipole.albedo), float(dipole.mfp), float(dipole.eta), int(n))


def spread_irradiance(E: np.ndarray, mask: np.ndarray, sigmas_px, weights) -> np.ndarray:
    """Irradiance ``E (h, w[, c])`` on the pixels of ``mask`` carried under the surface by
    the mixture (``sigmas_px``, the standard deviations in pixels; ``weights``, any
    scale): each Gaussian blurs ``E`` within the mask, normalised by the blurred mask so
    that light neither leaks out of nor is lost at the mask's edges (a uniform ``E``
    comes back unchanged). Outside the mask ``E`` is returned as is."""

    E = np.asarray(E, np.float64)
    m = np.asarray(mask, bool)
    w = np.asarray(weights, np.float64)
    w = w / w.sum()
    Em = np.where(m if E.ndim == 2 else m[..., None], E, 0.0)
    mf = m.astype(np.float64)
    acc = np.zeros_like(E)
    for s, wk in zip(np.asarray(sigmas_px, np.float64), w, strict=True):
        if s < 0.3:          # narrower than a third of a pixel: the pixel keeps its light
            acc += wk * Em
            continue
        num, den = _blur(Em, s), _blur(mf, s)
        den = np.maximum(den, 1e-12)
        acc += wk * (num / (den if E.ndim == 2 else den[..., None]))
    return np.where(m if E.ndim == 2 else m[..., None], acc, E)


def _blur(img: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian blur (zero outside the image); a wide one on an image shrunk so that the
    Gaussian spans about 4 of its pixels per sigma, then brought back (the shrinking's
    box and the bilinear return add well under a pixel of blur to tens)."""
    import cv2

    f = int(sigma // 4.0)
    if f < 2:
        k = int(2 * np.ceil(4.0 * sigma) + 1)
        return cv2.GaussianBlur(img, (k, k), sigma, borderType=cv2.BORDER_CONSTANT)
    h, w = img.shape[:2]
    small = cv2.resize(img, (max(w // f, 1), max(h // f, 1)), interpolation=cv2.INTER_AREA)
    s = float(np.sqrt(max(sigma * sigma - f * f / 12.0, 0.25))) / f
    k = int(2 * np.ceil(4.0 * s) + 1)
    small = cv2.GaussianBlur(small, (k, k), s, borderType=cv2.BORDER_CONSTANT)
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)
