"""Errors of estimated scan poses against reference poses, after fitting the free gauge
robustly.

Registration fixes the scans' poses only up to one rigid motion of the whole set (the
gauge: which frame the model is in). To compare with a reference, that motion is fitted
first -- robustly, so that a few wrong scans do not spoil it for the rest:

1. each scan proposes a gauge (the one that makes its own pose exact); the proposal with
   the smallest *median* displacement over all scans wins (least median of squares over
   scan-wise hypotheses, Rousseeuw 1984);
2. the gauge is refitted (Umeyama, rigid) on the points of the scans it fits to within
   three times that median (plus ``floor``), twice.

Then, per scan: the rotation error (degrees) and the RMS displacement of the scan's own
points between the estimated and the reference placement.

>>> import numpy as np
>>> from core.frames import rotation_about
>>> rng = np.random.default_rng(0)
>>> pts = {f"s{k}": rng.normal(size=(100, 3)) * 0.1 for k in range(5)}
>>> ref = {n: rotation_about([0, 0, 1], 0.5 * k) for k, n in enumerate(pts)}
>>> gauge = rotation_about([1, 0, 0], 1.0); gauge[:3, 3] = [0.3, 0.2, 0.1]
>>> est = {n: np.linalg.inv(gauge) @ T for n, T in ref.items()}
>>> est["s3"] = est["s3"] @ rotation_about([0, 1, 0], 0.3)  # one wrong scan
>>> err = compare_scan_poses(est, ref, pts)
>>> [round(e, 6) for e in err.rotation_deg.tolist()]
[0.0, 0.0, 0.0, 17.188734, 0.0]
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from core.frames import rotation_angle_deg, transform_points
from core.validate import check_array

from .sim3 import umeyama

__all__ = ["ScanPoseErrors", "compare_scan_poses"]


@dataclass
class ScanPoseErrors:
    """Per-scan errors after the gauge fit.

    Attributes
    ----------
    names : list of str
        Scans present (registered) in both.
    rotation_deg : (n,) float64
    displacement_rms : (n,) float64
        RMS over the scan's points of ``|G E p - R p|`` (metres).
    gauge : (4, 4) float64
        ``reference_from_estimate``.
    inliers : (n,) bool
        The scans the gauge was fitted on.
    missing : list of str
        Reference scans the estimate did not register.
    """

    names: list
    rotation_deg: np.ndarray
    displacement_rms: np.ndarray
    gauge: np.ndarray
    inliers: np.ndarray
    missing: list

    def to_dict(self) -> dict:
        return {"scans": [{"file": n, "rotation_error_deg": float(r),
                           "displacement_rms_m": float(d), "gauge_inlier": bool(i)}
                          for n, r, d, i in zip(self.names, self.rotation_deg,
                                                self.displacement_rms, self.inliers,
                                                strict=True)],
                "missing": list(self.missing),
                "rotation_error_deg": {"median": float(np.median(self.rotation_deg)),
                                       "max": float(self.rotation_deg.max())},
                "displacement_rms_m": {"median": float(np.median(self.displacement_rms)),
                                       "max": float(self.displacement_rms.max())},
                "reference_from_estimate": self.gauge.tolist()}

    def table(self) -> str:
        rows = [f"{'scan':<32} {'rotation (deg)':>14} {'RMS displacement (mm)':>22}"]
        for n, r, d, i in zip(self.names, self.rotation_deg, self.displacement_rms,
                              self.inliers, strict=True):
            rows.append(f"{n:<32} {r:>14.4f} {1000 * d:>22.4f}" + ("" if i else "  (outlier)"))
        rows += [f"{m:<32} {'not registered':>37}" for m in self.missing]
        return "\n".join(rows)


def _disp(G, E, R, p) -> float:
    M = G @ E - R
    return float(np.sqrt(np.mean(np.sum(transform_points(M, p) ** 2, axis=1))))


def compare_scan_poses(estimated: Mapping[str, np.ndarray | None],
                       reference: Mapping[str, np.ndarray],
                       points: Mapping[str, np.ndarray], *, floor: float = 1e-6,
                       max_points: int = 2000) -> ScanPoseErrors:
    """Compare ``model_from_scan`` poses by scan name (module docstring).

    Parameters
    ----------
    estimated : mapping name -> (4, 4) float64 or None (not registered)
    reference : mapping name -> (4, 4) float64
    points : mapping name -> (n, 3) float64
        Each scan's points in its own frame (what the displacement is measured on).
    floor : float
        Smallest inlier distance of the refit (metres).
    max_points : int
        Points per scan used for the gauge refit (evenly strided).

    Raises
    ------
    ValueError
        No scan registered in both, or a scan without points.
    """
    names = [n for n in reference if estimated.get(n) is not None and n in points]
    missing = [n for n in reference if estimated.get(n) is None and n in points]
    if not names:
        raise ValueError("estimated: no scan is placed in both the estimate and the reference")
    E = {n: check_array(estimated[n], f"estimated[{n!r}]", shape=(4, 4)) for n in names}
    R = {n: check_array(reference[n], f"reference[{n!r}]", shape=(4, 4)) for n in names}
    P = {n: check_array(points[n], f"points[{n!r}]", shape=(None, 3), min_rows=1)
         for n in names}
    best, best_med = None, np.inf
    for h in names:  # least median over the scans' own gauge proposals
        G = R[h] @ np.linalg.inv(E[h])
        med = float(np.median([_disp(G, E[n], R[n], P[n][:: max(1, len(P[n]) // 200)])
                               for n in names]))
        if med < best_med:
            best, best_med = G, med
    G = best
    for _ in range(2):
        d = np.array([_disp(G, E[n], R[n], P[n]) for n in names])
        inl = d <= 3.0 * float(np.median(d)) + floor
        src, dst = [], []
        for n, ok in zip(names, inl, strict=True):
            if ok and len(names) > 1:
                p = P[n][:: max(1, len(P[n]) // max_points)]
                src.append(transform_points(E[n], p))
                dst.append(transform_points(R[n], p))
        if sum(len(s) for s in src) >= 3:
            G = umeyama(np.concatenate(src), np.concatenate(dst), with_scale=False).matrix
    rot = np.array([rotation_angle_deg((G @ E[n])[:3, :3] @ R[n][:3, :3].T) for n in names])
    disp = np.array([_disp(G, E[n], R[n], P[n]) for n in names])
    inl = disp <= 3.0 * float(np.median(disp)) + floor
    return ScanPoseErrors(names, rot, disp, G, inl, missing)
