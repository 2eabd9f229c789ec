"""The received waveform of a pulse, its echoes, their energy and their range noise.

Each sub-ray ``i`` of a pulse that hits a surface at range ``R_i`` with incidence
``theta_i`` on reflectance ``rho_i`` returns the energy (radar equation for an extended
Lambertian target, per unit of emitted energy and receiver constants)::

    E_i = w_i * rho_i * cos(theta_i) / R_i**2        (w_i: the sub-ray's beam share)

The waveform is the emitted Gaussian pulse (full width at half maximum ``pulse_width``)
delayed by each ``2 R_i / c`` and scaled by ``E_i``, summed, and sampled in bins of
``bin_ns``. Echoes are its local maxima above the detection threshold, placed by
Gaussian (log-parabolic) interpolation of the three samples about the peak. Two
receivers (``detection``) differ in which of two echoes closer than ``min_separation``
survives:

- ``"waveform"`` (a digitised waveform decomposed afterwards: RIEGL's full-waveform
  scanners): the stronger, wherever it lies;
- ``"discrete"`` (an analogue detector that triggers on each echo in time, then stays
  blind for a dead time: the 4-return receivers of Leica's ALS50/ALS60 and Optech's
  ALTM 3100): the earlier, however weak, and everything within ``min_separation``
  after it is lost.

Then the first ``max_returns`` in time are kept. Each sub-ray belongs to the nearest echo within
``max(min_separation, 4 sigma)``; an echo's energy (its intensity) is the sum of its
sub-rays' energies, and its truth (object, part, true point) is that of the sub-ray
contributing most at its peak.

Range noise (the stated law): the range of an echo of signal-to-noise ratio
``SNR = E / E_noise`` is Gaussian about the noise-free range with::

    sigma_R = sigma_pulse / sqrt(SNR),    sigma_pulse = c * (pulse_width / 2.3548) / 2

the photon-counting limit of timing a Gaussian pulse (its centroid from ``SNR`` photons).
A preset's precision ``sigma_0`` at range ``R_0`` on reflectance ``rho_0`` fixes
``E_noise = (rho_0 / R_0**2) * (sigma_0 / sigma_pulse)**2``; its maximum range on
``rho_0`` fixes the detection threshold ``rho_0 / R_max**2`` (on an undistorted echo's
peak). So sigma_R grows as R and falls with cos(theta) and reflectance as
``sigma_0 * (R / R_0) * sqrt(rho_0 / (rho cos theta))``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from core.validate import InputError

__all__ = ["Receiver", "detect_echoes", "SPEED_OF_LIGHT", "FWHM_TO_SIGMA", "DETECTIONS"]

#: Echo detection by the receiver (see the module's docstring).
DETECTIONS = ("waveform", "discrete")

SPEED_OF_LIGHT = 299_792_458.0
#: A Gaussian's full width at half maximum over its standard deviation.
FWHM_TO_SIGMA = 2.0 * np.sqrt(2.0 * np.log(2.0))
_MAX_BINS = 1 << 16          # a pulse's waveform spans at most this many bins
_MAX_PEAKS = 64              # candidate peaks examined per pulse


@dataclass(frozen=True)
class Receiver:
    """The receiver's digitiser and detector.

    Parameters
    ----------
    pulse_width_ns : float
        Emitted pulse, FWHM.
    bin_ns : float
        Waveform sampling interval.
    threshold : float
        Detection threshold: energy of the weakest detectable undistorted echo.
    noise_energy : float
        ``E_noise`` of the SNR (echo energy over it).
    min_separation_m : float
        Echoes closer in range than this are one (the stronger kept, or with
        ``detection="discrete"`` the earlier).
    max_returns : int
    detection : {'waveform', 'discrete'}
        Which of two echoes closer than ``min_separation_m`` is kept (see above).
    """

    pulse_width_ns: float
    bin_ns: float
    threshold: float
    noise_energy: float
    min_separation_m: float
    max_returns: int
    detection: str = "waveform"

    def __post_init__(self):
        if self.detection not in DETECTIONS:
            raise InputError(f"expected one of {', '.join(DETECTIONS)}, got "
                             f"{self.detection!r}", field="detection")

    @property
    def sigma_m(self) -> float:
        """The emitted pulse's standard deviation in range, metres."""
        return SPEED_OF_LIGHT * self.pulse_width_ns * 1e-9 / FWHM_TO_SIGMA / 2.0

    def range_sigma(self, snr: np.ndarray) -> np.ndarray:
        """The range noise (one sigma, metres) of echoes of signal-to-noise ratio ``snr``."""
        return self.sigma_m / np.sqrt(np.maximum(np.asarray(snr, np.float64), 1e-12))


def detect_echoes(ranges: np.ndarray, energies: np.ndarray, rx: Receiver):
    """Echoes of a block of pulses from their sub-rays' ranges and energies.

    Parameters
    ----------
    ranges : (n, s) float64
        Range of each sub-ray's hit, metres (inf where it hit nothing).
    energies : (n, s) float64
        Returned energy of each sub-ray (0 where it hit nothing).
    rx : Receiver

    Returns
    -------
    dict of (k,) arrays over the k echoes, ordered by pulse then range:
    ``pulse`` int64, ``return_number`` uint8, ``number_of_returns`` uint8, ``range``
    float64 (noise-free), ``energy`` float64, ``subray`` int64 (the dominant sub-ray).
    """
    n, s = ranges.shape
    sig_b = rx.sigma_m / (SPEED_OF_LIGHT * rx.bin_ns * 1e-9 / 2.0)
    dr = rx.sigma_m / sig_b
    thr_amp = rx.threshold / (sig_b * np.sqrt(2 * np.pi))
    m = int(rx.max_returns)
    count = np.zeros(n, np.int64)
    rng_ = np.empty((n, m))
    energy = np.empty((n, m))
    sub = np.empty((n, m), np.int64)
    _echo_kernel(np.ascontiguousarray(ranges, np.float64),
                 np.ascontiguousarray(energies, np.float64), sig_b, dr, thr_amp,
                 float(rx.min_separation_m), max(float(rx.min_separation_m), 4.0 * rx.sigma_m),
                 m, rx.detection == "discrete", count, rng_, energy, sub)
    keep = np.arange(m)[None, :] < count[:, None]
    pulse = np.broadcast_to(np.arange(n)[:, None], (n, m))[keep]
    rank = np.broadcast_to(np.arange(1, m + 1, dtype=np.uint8)[None, :], (n, m))[keep]
    return {"pulse": pulse, "return_number": rank,
            "number_of_returns": count[pulse].astype(np.uint8), "range": rng_[keep],
            "energy": energy[keep], "subray": sub[keep]}


@nb.njit(cache=True)
def _peaks(buf, nb_, thr, r0, dr, min_sep, max_ret, in_time, out_r):
    """Accepted echo ranges of one waveform (sorted), their count. ``in_time``: a
    discrete receiver (the earlier of two close echoes wins), else the stronger."""
    cand_a = np.empty(_MAX_PEAKS)
    cand_r = np.empty(_MAX_PEAKS)
    nc = 0
    for j in range(1, nb_ - 1):
        b = buf[j]
        if b > thr and b > buf[j - 1] and b >= buf[j + 1]:
            a, c = buf[j - 1], buf[j + 1]
            delta = 0.0
            if a > 0 and c > 0:
                la, lb, lc = np.log(a), np.log(b), np.log(c)
                den = la - 2 * lb + lc
                if den < 0:
                    delta = 0.5 * (la - lc) / den
            if nc < _MAX_PEAKS:
                cand_a[nc] = b
                cand_r[nc] = r0 + (j + delta) * dr
                nc += 1
    # candidates are found in time order; a waveform receiver weighs them by strength
    order = np.arange(nc) if in_time else np.argsort(-cand_a[:nc])
    acc = np.empty(_MAX_PEAKS)
    na = 0
    for q in order:
        r = cand_r[q]
        ok = True
        for u in range(na):
            if abs(r - acc[u]) < min_sep:
                ok = False
                break
        if ok:
            acc[na] = r
            na += 1
    acc_s = np.sort(acc[:na])
    na = min(na, max_ret)
    for u in range(na):
        out_r[u] = acc_s[u]
    return na


@nb.njit(cache=True)
def _clusters(r, e, tol, cr, ce):
    """Merge sub-rays (sorted by range) closer than ``tol`` into energy-weighted clusters;
    their number. A cluster's Gaussians coincide to within ``tol``, a small share of the
    pulse's width, so the sum is one Gaussian at their centroid."""
    nc = 0
    i = 0
    while i < len(r):
        es, rs = 0.0, 0.0
        j = i
        while j < len(r) and r[j] - r[i] <= tol:
            es += e[j]
            rs += e[j] * r[j]
            j += 1
        cr[nc] = rs / es
        ce[nc] = es
        nc += 1
        i = j
    return nc


@nb.njit(cache=True)
def _mode(cr, ce, nc, sig_r):
    """The peak of a sum of Gaussians (width ``sig_r``) whose centres ``cr`` lie within
    ``2 sig_r`` (such a sum has one mode): mean-shift from the centroid. Returns the
    peak's range and its height in energy units (a lone Gaussian's height is its
    energy)."""
    es, rs = 0.0, 0.0
    for i in range(nc):
        es += ce[i]
        rs += ce[i] * cr[i]
    x = rs / es
    amp = es
    if nc > 1:
        for _ in range(50):
            num, den = 0.0, 0.0
            for i in range(nc):
                z = (cr[i] - x) / sig_r
                g = ce[i] * np.exp(-0.5 * z * z)
                num += g * cr[i]
                den += g
            x_new = num / den
            amp = den
            if abs(x_new - x) < 1e-5:
                x = x_new
                break
            x = x_new
    return x, amp


@nb.njit(cache=True)
def _waveform_peaks(cr, ce, nc, sig_b, dr, thr_amp, min_sep, max_ret, in_time, echo_r):
    """Render the clusters' Gaussians into a sampled waveform and find its echoes."""
    K = int(np.ceil(4.0 * sig_b))
    norm = 1.0 / (sig_b * np.sqrt(2 * np.pi))
    r0 = cr[0] - (K + 1) * dr
    nb_ = min(int((cr[nc - 1] - r0) / dr) + K + 3, _MAX_BINS)
    buf = np.zeros(nb_)
    c = np.exp(-1.0 / (sig_b * sig_b))
    for i in range(nc):
        u = (cr[i] - r0) / dr
        j0 = int(u)
        ja = max(j0 - K, 0)
        x = (ja - u) / sig_b
        g = ce[i] * norm * np.exp(-0.5 * x * x)        # the Gaussian at bin ja, then
        a = np.exp(-x / sig_b - 0.5 / (sig_b * sig_b))  # its ratio bin to bin (3 exps)
        for j in range(ja, min(j0 + K + 2, nb_)):
            buf[j] += g
            g *= a
            a *= c
    return _peaks(buf, nb_, thr_amp, r0, dr, min_sep, max_ret, in_time, echo_r)


@nb.njit(cache=True, parallel=True)
def _echo_kernel(R, E, sig_b, dr, thr_amp, min_sep, assign_dist, max_ret, in_time,
                 count, rng_, energy, sub):
    n, s = R.shape
    nchunk = min(n, 64)
    for c in nb.prange(nchunk):          # scratch allocated once per chunk of pulses
        idx = np.empty(s, np.int64)
        r, e = np.empty(s), np.empty(s)
        cr, ce = np.empty(s), np.empty(s)
        echo_r = np.empty(max_ret)
        best, e_sum = np.empty(max_ret), np.empty(max_ret)
        for p in range(c * n // nchunk, (c + 1) * n // nchunk):
            _pulse_echoes(R[p], E[p], sig_b, dr, thr_amp, min_sep, assign_dist, max_ret,
                          in_time, idx, r, e, cr, ce, echo_r, best, e_sum, p, count, rng_,
                          energy, sub)


@nb.njit(cache=True)
def _pulse_echoes(Rp, Ep, sig_b, dr, thr_amp, min_sep, assign_dist, max_ret, in_time,
                  idx, r, e, cr, ce, echo_r, best, e_sum, p, count, rng_, energy, sub):
    """One pulse's echoes into row ``p`` of the outputs."""
    nv = 0
    for i in range(len(Rp)):                   # insertion sort of the hits by range
        if Ep[i] > 0 and np.isfinite(Rp[i]):
            j = nv
            while j > 0 and r[j - 1] > Rp[i]:
                r[j], e[j], idx[j] = r[j - 1], e[j - 1], idx[j - 1]
                j -= 1
            r[j], e[j], idx[j] = Rp[i], Ep[i], i
            nv += 1
    if nv == 0:
        return
    sig_r = sig_b * dr
    nc = _clusters(r[:nv], e[:nv], 0.05 * sig_r, cr, ce)
    if cr[nc - 1] - cr[0] <= 2.0 * sig_r:      # a unimodal sum: its one peak, exactly
        x, amp = _mode(cr, ce, nc, sig_r)
        if amp / (sig_b * np.sqrt(2 * np.pi)) <= thr_amp:
            return
        echo_r[0] = x
        na = 1
    else:
        na = _waveform_peaks(cr, ce, nc, sig_b, dr, thr_amp, min_sep, max_ret, in_time,
                             echo_r)
    best[:na] = -1.0
    e_sum[:na] = 0.0
    for q in range(nv):
        u_best, d_best = -1, assign_dist
        for u in range(na):
            d = abs(r[q] - echo_r[u])
            if d <= d_best:
                u_best, d_best = u, d
        if u_best >= 0:
            e_sum[u_best] += e[q]
            x = d_best / sig_r
            w = e[q] * np.exp(-0.5 * x * x)
            if w > best[u_best]:
                best[u_best] = w
                sub[p, u_best] = idx[q]
    count[p] = na
    for u in range(na):
        rng_[p, u] = echo_r[u]
        energy[p, u] = e_sum[u]
