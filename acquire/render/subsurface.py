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
Light scattered only once under the surface is not in the diffusion; as Jensen et al.
do, it is added as its own term. For a smooth boundary of relative index ``eta`` over a
deep medium it is local (within a few mean free paths of the entry) and its BRDF is
closed-form (Hanrahan and Krueger 1993):

    f1(wi, wo) = alpha p(cos theta) T(mu_i) T(mu_o) / (eta^2 (mu_i' + mu_o'))

with ``alpha = s_s / s_t`` the single-scattering albedo, ``p`` the Henyey-Greenstein phase
function of anisotropy ``g`` at the angle ``theta`` between the refracted rays, ``T`` the
Fresnel transmittance of the boundary and ``mu'`` the cosines of the refracted rays
(:func:`single_scattering`). With ``eta = 1`` and ``g = 0`` it is the Lommel-Seeliger
law: brighter toward grazing view and light, as a translucent sphere's rim is. The
mean free path is reduced (``1 / s_t'``, ``s_s' = s_s (1 - g)``), so a forward-scattering
material (``g`` near 1) sends little light straight back: its single term is small.

Energy: the light scattered once leaves, and the diffusion cannot take more than the
rest. Where the dipole's ``M`` plus the single term's share of a beam would exceed 1
(toward grazing incidence behind an index-matched boundary, where half of a grazing
beam comes back at once), the diffusion's entry and exit are weighted down by
``w(mu) = min(1, (1 - s(mu)) / M)`` (:meth:`Dipole.diffusion_entry`; the exit by
``w / <w>``, so the transport stays reciprocal), so a beam at any incidence sends back
at most all of its light.

The material is given as a user would measure it: its **diffuse albedo** (the total
reflectance under broad light: the dipole's ``int Rd dA`` plus the single term's share)
and its **mean free path**; the reduced scattering albedo ``a'`` is found from the
albedo by inverting that total (Jensen and Buhler 2002), so a plane lit evenly looks
exactly as bright as a Lambertian plane of the same albedo: scattering moves light, it
does not make or lose it.

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
P. Hanrahan, W. Krueger, "Reflection from layered surfaces due to subsurface scattering",
SIGGRAPH 1993. doi:10.1145/166117.166139
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

__all__ = ["diffuse_fresnel", "fresnel_transmittance", "hg_phase", "single_scattering",
           "single_scattering_share", "single_scattering_directional",
           "DEFAULT_ANISOTROPY", "total_reflectance",
           "reduced_albedo", "Dipole",
           "line_profile", "stripe_radiance", "gaussian_mixture", "spread_irradiance"]


def diffuse_fresnel(eta: float) -> float:
    """Diffuse Fresnel reflectance ``F_dr`` inside a medium of relative index ``eta``
    (the polynomial fit of Egan and Hilgeman used by Jensen et al.)."""
    return -1.440 / eta ** 2 + 0.710 / eta + 0.668 + 0.0636 * eta


DEFAULT_ANISOTROPY = 0.8
"""Henyey-Greenstein anisotropy ``g`` of a subsurface material unless given: translucent
materials scatter forward (biological tissue 0.8-0.95, Jacques 2013)."""


def fresnel_transmittance(cos_i: np.ndarray, eta: float) -> np.ndarray:
    """``1 - F``: the unpolarised Fresnel transmittance of a smooth boundary into a
    medium of relative index ``eta >= 1`` for light arriving at ``cos_i`` (the same for
    the light leaving along that direction)."""
    c = np.clip(np.asarray(cos_i, np.float64), 0.0, 1.0)
    ct = np.sqrt(np.maximum(1.0 - (1.0 - c * c) / (eta * eta), 0.0))
    rs = (c - eta * ct) / np.maximum(c + eta * ct, 1e-300)
    rp = (eta * c - ct) / np.maximum(eta * c + ct, 1e-300)
    return 1.0 - 0.5 * (rs * rs + rp * rp)


def hg_phase(cos_theta: np.ndarray, g: float) -> np.ndarray:
    """The Henyey-Greenstein phase function (1/sr) at the scattering angle's cosine."""
    return (1.0 - g * g) / (4.0 * np.pi * (1.0 + g * g - 2.0 * g * np.asarray(cos_theta))
                            ** 1.5)


def single_scattering(wi: np.ndarray, wo: np.ndarray, n: np.ndarray, *, g: float,
                      eta: float) -> np.ndarray:
    """``pi f1 / alpha`` (Hanrahan and Krueger 1993): ``pi`` times the BRDF of light
    scattered once in a deep medium behind a smooth boundary, per unit single-scattering
    albedo, for unit directions ``wi`` (toward the light) and ``wo`` (toward the viewer)
    at normals ``n``, all ``(k, 3)``; zero below the horizon. The renderer's
    convention: multiplied by the irradiance it is the radiance, as an albedo is."""
    wi, wo, n = (np.asarray(x, np.float64) for x in (wi, wo, n))
    mi, mo = np.einsum("ij,ij->i", wi, n), np.einsum("ij,ij->i", wo, n)
    up = (mi > 0) & (mo > 0)
    mi, mo = np.clip(mi, 0.0, 1.0), np.clip(mo, 0.0, 1.0)
    ti = wi - mi[:, None] * n            # the directions' parts along the surface
    to = wo - mo[:, None] * n
    mip = np.sqrt(np.maximum(1.0 - (1.0 - mi * mi) / eta ** 2, 0.0))   # refracted cosines
    mop = np.sqrt(np.maximum(1.0 - (1.0 - mo * mo) / eta ** 2, 0.0))
    # the refracted rays: in along -ti / eta and down, out along to / eta and up
    cos_theta = -np.einsum("ij,ij->i", ti, to) / eta ** 2 - mip * mop
    f = (hg_phase(cos_theta, g) * fresnel_transmittance(mi, eta)
         * fresnel_transmittance(mo, eta) / (eta ** 2 * np.maximum(mip + mop, 1e-12)))
    return np.where(up, np.pi * f, 0.0)


@lru_cache(maxsize=4)
def _exit_quadrature(n: int = 48) -> tuple[np.ndarray, np.ndarray]:
    """Unit exit directions over the upper hemisphere (Gauss-Legendre in the cosine, even
    steps in azimuth) and their weights ``d mu d phi``."""
    x, w = np.polynomial.legendre.leggauss(n)
    mu, wm = 0.5 * (x + 1.0), 0.5 * w
    phi = np.linspace(0.0, 2.0 * np.pi, 2 * n, endpoint=False)
    mo, ph = (a.ravel() for a in np.meshgrid(mu, phi, indexing="ij"))
    so = np.sqrt(1.0 - mo * mo)
    weight = np.einsum("i,j->ij", wm, np.full(len(phi), 2.0 * np.pi / len(phi))).ravel()
    return np.stack([so * np.cos(ph), so * np.sin(ph), mo], axis=1), weight


def _beam_single(mu_i: float, g: float, eta: float) -> float:
    """``int f1 mu_o dw_o / alpha`` for a beam at incidence cosine ``mu_i``."""
    wo, weight = _exit_quadrature()
    m = max(float(mu_i), 1e-6)                          # grazing: the limit from above
    wi = np.broadcast_to([np.sqrt(1.0 - m * m), 0.0, m], wo.shape)
    f = single_scattering(wi, wo, np.broadcast_to([0.0, 0.0, 1.0], wo.shape),
                          g=g, eta=eta) / np.pi
    return float(np.sum(f * wo[:, 2] * weight))


@lru_cache(maxsize=64)
def single_scattering_share(g: float, eta: float) -> float:
    """The albedo of :func:`single_scattering` under broad light, per unit
    single-scattering albedo: ``(1/pi) int int f1 mu_i mu_o dw_i dw_o / alpha``, the
    cosine-weighted mean of :func:`single_scattering_directional`. 0.2046 for
    ``eta = 1``, ``g = 0`` (Lommel-Seeliger); 0.0039 for marble-like ``eta = 1.5``,
    ``g = 0.8``."""
    x, w = np.polynomial.legendre.leggauss(48)
    mu, wm = 0.5 * (x + 1.0), 0.5 * w
    return float(2.0 * sum(wk * m * _beam_single(m, g, eta) for m, wk in zip(mu, wm,
                                                                            strict=True)))


@lru_cache(maxsize=64)
def _directional_single(g: float, eta: float) -> tuple[np.ndarray, np.ndarray]:
    grid = np.linspace(0.0, 1.0, 129) ** 2     # dense toward grazing, where it turns fast
    out = np.array([_beam_single(m, g, eta) for m in grid])
    grid.setflags(write=False)
    out.setflags(write=False)
    return grid, out


def single_scattering_directional(mu_i: np.ndarray, g: float, eta: float) -> np.ndarray:
    """The share of a beam at incidence cosine ``mu_i`` that is scattered once and
    leaves, per unit single-scattering albedo: ``int f1 mu_o dw_o / alpha`` (tabulated
    over ``mu_i``). For ``eta = 1``, ``g = 0`` it is ``(1 - mu ln(1 + 1/mu)) / 2``: half
    of a grazing beam comes straight back; its cosine-weighted mean over the incidences
    is :func:`single_scattering_share`."""
    grid, tab = _directional_single(float(g), float(eta))
    return np.interp(np.clip(np.asarray(mu_i, np.float64), 0.0, 1.0), grid, tab)


def _alpha(a: np.ndarray, g: float) -> np.ndarray:
    """The single-scattering albedo ``s_s / s_t`` of reduced albedo ``a'`` and
    anisotropy ``g`` (``s_s = s_s' / (1 - g)``, the absorption unchanged)."""
    a = np.asarray(a, np.float64)
    ss = a / (1.0 - g)
    return ss / (ss + (1.0 - a))


def total_reflectance(a: np.ndarray, eta: float) -> np.ndarray:
    """The dipole's total diffuse reflectance ``int Rd dA`` for reduced albedo ``a'`` (the
    light scattered more than once)."""
    A = (1.0 + diffuse_fresnel(eta)) / (1.0 - diffuse_fresnel(eta))
    s = np.sqrt(3.0 * (1.0 - np.asarray(a, np.float64)))
    return 0.5 * a * (1.0 + np.exp(-4.0 / 3.0 * A * s)) * np.exp(-s)


_X, _XW = np.polynomial.legendre.leggauss(64)
_MU, _MU_W = 0.5 * (_X + 1.0), 0.5 * _XW      # Gauss-Legendre on [0, 1]


def _entry(mu, a: float, eta: float, g: float) -> np.ndarray:
    """``min(1, (1 - alpha s(mu)) / M)`` of reduced albedo ``a``: see
    :meth:`Dipole.diffusion_entry`."""
    m = float(total_reflectance(a, eta))
    s1 = float(_alpha(a, g)) * single_scattering_directional(mu, g, eta)
    return np.minimum(1.0, (1.0 - s1) / max(m, 1e-300))


def _broad_light(a: float, eta: float, g: float) -> tuple[float, float, float]:
    """Under broad light, for reduced albedo ``a``: the diffusion's reflectance
    ``M <w>``, the single scattering's ``alpha K``, and ``<w>``, the cosine-weighted
    mean of the diffusion's entry weight."""
    e = _entry(_MU, a, eta, g)
    w = 1.0 if np.all(e >= 1.0) else float(2.0 * np.sum(e * _MU * _MU_W))
    return (float(total_reflectance(a, eta)) * w,
            float(_alpha(a, g)) * single_scattering_share(float(g), float(eta)), w)


def reduced_albedo(albedo: float, eta: float, g: float = DEFAULT_ANISOTROPY) -> float:
    """The reduced scattering albedo ``a'`` whose reflectance under broad light, the
    diffusion's plus the single term's, is ``albedo`` (bisection: both grow with ``a'``)."""
    return _reduced_albedo(float(albedo), float(eta), float(g))


@lru_cache(maxsize=256)
def _reduced_albedo(albedo: float, eta: float, g: float) -> float:
    def total(a):
        m, s1, _ = _broad_light(a, eta, g)
        return m + s1

    albedo = check_range(albedo, "albedo", 0.0, total(1.0))
    lo, hi = 0.0, 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if total(mid) < albedo:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@dataclass(frozen=True)
class Dipole:
    """The dipole of a material: diffuse ``albedo`` (under broad light, single
    scattering included), mean free path ``mfp`` (metres, reduced), relative refractive
    index ``eta``, Henyey-Greenstein anisotropy ``g`` of the single term."""

    albedo: float
    mfp: float
    eta: float = 1.5
    g: float = DEFAULT_ANISOTROPY

    @property
    def a(self) -> float:
        return reduced_albedo(self.albedo, self.eta, self.g)

    @property
    def single_albedo(self) -> float:
        """``alpha = s_s / s_t``, the factor of :func:`single_scattering`."""
        return float(_alpha(self.a, self.g))

    @property
    def single(self) -> float:
        """The share of the albedo scattered once (local, angular), under broad light."""
        return self.single_albedo * single_scattering_share(float(self.g), float(self.eta))

    @property
    def multiple(self) -> float:
        """``M``, the dipole profile's own reflectance ``int Rd dA``, before the entry
        weight of :meth:`diffusion_entry` (:attr:`diffusion` is what reaches the eye
        under broad light)."""
        return float(total_reflectance(self.a, self.eta))

    @property
    def diffusion(self) -> float:
        """The share of the albedo carried by the diffusion under broad light,
        ``M <w>`` (:meth:`diffusion_entry`); with :attr:`single` it is the albedo."""
        return _broad_light(self.a, self.eta, self.g)[0]

    @property
    def entry_mean(self) -> float:
        """``<w>``, the cosine-weighted mean of :meth:`diffusion_entry`."""
        return _broad_light(self.a, self.eta, self.g)[2]

    def diffusion_entry(self, mu: np.ndarray) -> np.ndarray:
        """The share of a beam at cosine ``mu`` that the diffusion takes, relative to the
        dipole's ``M``: ``min(1, (1 - s(mu)) / M)``, with ``s`` what single scattering
        sends back at once (:func:`single_scattering_directional` times the single
        albedo). Light scattered once leaves; the diffusion cannot have more than the
        rest, so a beam at any incidence sends back at most all of it,
        ``M w(mu) + s(mu) <= 1``. 1 for the angles where that holds unclamped (every
        angle behind a boundary of index 1.5 with forward scattering); it drops toward
        grazing for an index-matched boundary, where half of a grazing beam is scattered
        once. The diffusion's exit follows the same weight over its mean, ``w / <w>``, so
        that the transport ``M w(mu_i) w(mu_o) / <w>`` is reciprocal and a beam at
        ``mu_i`` sends ``M w(mu_i)`` back through the diffusion."""
        return _entry(mu, self.a, self.eta, self.g)

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
def _line_table(albedo: float, mfp: float, eta: float, g: float, n: int
                ) -> tuple[np.ndarray, np.ndarray]:
    d = Dipole(albedo, mfp, eta, g)
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
    dipole's share of the albedo, :attr:`Dipole.multiple`."""
    return _line_table(float(dipole.albedo), float(dipole.mfp), float(dipole.eta),
                       float(dipole.g), int(n))


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
        irradiance (no Gaussian) it is the exit radiance of the light scattered more than
        once. It tends to ``multiple g(s)`` as the mean free path goes to 0; with the
        single term (local: ``g(s)`` times :func:`single_scattering` times the single
        albedo) it is a Lambertian surface's ``albedo g(s)`` under broad light.
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
def _mixture(albedo: float, mfp: float, eta: float, g: float, n: int
             ) -> tuple[np.ndarray, np.ndarray]:
    from scipy.optimize import nnls

    d = Dipole(albedo, mfp, eta, g)
    far = max(8.0 / d.sigma_tr if d.sigma_tr > 0 else 0.0, 20.0 * mfp)
    sig = np.geomspace(0.25 * mfp, 0.5 * far, n)
    r = np.concatenate([np.linspace(0.0, 2.0 * mfp, 200), np.geomspace(2.0 * mfp, far, 400)])
    area = 2.0 * np.pi * r          # match Rd where the light is: weighted by the ring area
    g = np.exp(-0.5 * (r[:, None] / sig) ** 2) / (2.0 * np.pi * sig ** 2)
    w, _ = nnls(g * area[:, None], d.rd(r) * area)
    keep = w > 0
    sig, w = sig[keep], w[keep]
    return sig, w * (d.multiple / w.sum())    # the mixture reflects exactly the dipole's share


def gaussian_mixture(dipole: Dipole, n: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """``Rd(r) ~ sum_k w_k exp(-r^2 / 2 s_k^2) / (2 pi s_k^2)``: standard deviations
    ``s_k`` (metres, from a quarter of the mean free path to a few diffusion lengths) and
    weights ``w_k`` (non-negative least squares on the profile weighted by the ring area
    ``2 pi r``), scaled so that ``sum w_k`` is the dipole's share of the albedo,
    :attr:`Dipole.multiple`, exactly."""
    return _mixture(float(dipole.albedo), float(dipole.mfp), float(dipole.eta),
                    float(dipole.g), int(n))


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
