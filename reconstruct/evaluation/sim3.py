"""Similarity alignment of estimated cameras to true ones, and the pose errors.

SfM recovers cameras up to a similarity (scale, rotation, translation). To score
it, the estimated camera centres are aligned to the true ones with Umeyama's closed
form (least squares over centres), and then:

- rotation error: the angle of ``R_true @ (R_est @ R_align^T)^T`` per camera,
- centre error: ``|s R c_est + t - c_true|`` per camera,
- ATE: the RMS of the centre errors (absolute trajectory error, Sturm et al. 2012).

``robust=True`` fits the similarity so that a few misplaced cameras do not spoil it for
the rest (:func:`robust_umeyama`): least squares, dropping the worst camera while it
lies beyond three times the median residual of the others.

References
----------
S. Umeyama, "Least-squares estimation of transformation parameters between two point
patterns", IEEE TPAMI 13(4), 1991. doi:10.1109/34.88573
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from core.frames import rotation_angle_deg
from core.validate import check_array

__all__ = ["umeyama", "robust_umeyama", "joint_similarity", "Sim3", "PoseErrors",
           "align_cameras"]


@dataclass(frozen=True)
class Sim3:
    """``x -> scale * R @ x + t``.

    Attributes
    ----------
    scale : float
    R : (3, 3) float64
    t : (3,) float64
    """

    scale: float
    R: np.ndarray
    t: np.ndarray

    @property
    def matrix(self) -> np.ndarray:
        """(4, 4) homogeneous matrix."""
        T = np.eye(4)
        T[:3, :3] = self.scale * self.R
        T[:3, 3] = self.t
        return T

    def apply(self, points: np.ndarray) -> np.ndarray:
        """Transform ``points (n, 3)``."""
        p = check_array(points, "points", shape=(None, 3))
        return self.scale * p @ self.R.T + self.t

    def apply_cam_from_world(self, cam_from_world: np.ndarray) -> np.ndarray:
        """The pose (4, 4) of the same camera in the new world frame (metric translation)."""
        T = check_array(cam_from_world, "cam_from_world", shape=(4, 4))
        R = T[:3, :3] @ self.R.T
        centre = self.apply((-T[:3, :3].T @ T[:3, 3])[None])[0]
        out = np.eye(4)
        out[:3, :3] = R
        out[:3, 3] = -R @ centre
        return out


def umeyama(src: np.ndarray, dst: np.ndarray, *, with_scale: bool = True) -> Sim3:
    """The similarity that maps ``src`` onto ``dst`` in the least-squares sense.

    Parameters
    ----------
    src, dst : (n, 3) float64
        Corresponding points, n >= 3 and not all collinear.
    with_scale : bool
        False fixes the scale at 1 (a rigid transform).

    Returns
    -------
    Sim3

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> p = rng.normal(size=(10, 3))
    >>> sim = umeyama(p, 2.0 * p + [1.0, 2.0, 3.0])
    >>> round(sim.scale, 9), np.round(sim.t, 9).tolist()
    (2.0, [1.0, 2.0, 3.0])
    """
    src = check_array(src, "src", shape=(None, 3), min_rows=3)
    dst = check_array(dst, "dst", shape=(len(src), 3))
    mu_s, mu_d = src.mean(0), dst.mean(0)
    a, b = src - mu_s, dst - mu_d
    var_s = (a * a).sum() / len(src)
    if var_s <= 1e-300:
        raise ValueError("src: expected points that are not all the same")
    cov = b.T @ a / len(src)
    U, D, Vt = np.linalg.svd(cov)
    S = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        S[2, 2] = -1.0
    R = U @ S @ Vt
    scale = float(np.trace(np.diag(D) @ S) / var_s) if with_scale else 1.0
    t = mu_d - scale * R @ mu_s
    return Sim3(scale, R, t)


def robust_umeyama(src: np.ndarray, dst: np.ndarray, *, k: float = 3.0,
                   floor: float = 1e-9) -> tuple[Sim3, np.ndarray]:
    """The similarity mapping most of ``src`` onto ``dst``, and which points it fits.

    Least squares over all points, then the worst point is dropped and the rest refitted
    while its residual exceeds ``k`` times the median residual of the points kept (plus
    ``floor`` times the spread of ``dst``), keeping at least half of them and three.
    Points that then fit within that bound again are taken back. A least-median fit
    over triplets would be the textbook choice, but cameras on an arc (a facade's
    survey) leave a triplet's rotation about the arc barely fixed: on fountain-P11 it
    flagged 5 of 11 good views and doubled the rotation errors.

    Returns
    -------
    Sim3, (n,) bool
        The fit and its inliers.

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> p = rng.normal(size=(8, 3))
    >>> q = 3.0 * p + 1.0
    >>> q[2] += 5.0  # one point far off
    >>> sim, inl = robust_umeyama(p, q)
    >>> round(sim.scale, 9), inl.tolist()
    (3.0, [True, True, False, True, True, True, True, True])
    """
    src = check_array(src, "src", shape=(None, 3), min_rows=3)
    dst = check_array(dst, "dst", shape=(len(src), 3))
    n = len(src)
    tol = floor * max(float(np.ptp(dst, axis=0).max()), 1e-300)
    keep = np.ones(n, bool)
    sim = umeyama(src, dst)
    while keep.sum() > max(3, n // 2):
        r = np.linalg.norm(sim.apply(src) - dst, axis=1)
        worst = int(np.argmax(np.where(keep, r, -np.inf)))
        if r[worst] <= k * float(np.median(r[keep])) + tol:
            break
        keep[worst] = False
        sim = umeyama(src[keep], dst[keep])
    r = np.linalg.norm(sim.apply(src) - dst, axis=1)
    inl = r <= k * float(np.median(r[keep])) + tol
    if inl.sum() >= 3 and not np.array_equal(inl, keep):
        sim = umeyama(src[inl], dst[inl])
    return sim, inl


def joint_similarity(src: np.ndarray, dst: np.ndarray, src_rotations: np.ndarray,
                     dst_rotations: np.ndarray, *, centre_inliers: np.ndarray | None = None,
                     k: float = 3.0, iterations: int = 30) -> tuple[Sim3, float, float]:
    """The similarity that best explains both the camera centres and their orientations.

    Maximum likelihood under independent isotropic errors: per view, a centre error of
    ``sigma_c`` per axis and an orientation error of ``sigma_r`` radians per axis. The
    similarity maps ``src`` onto ``dst`` and each ``src_rotations[i] G^T`` (``G`` its
    rotation) onto ``dst_rotations[i]``; its rotation maximises ``tr(G^T M)`` with
    ``M = s / sigma_c^2 sum b_i a_i^T + 1 / (2 sigma_r^2) sum Rd_i^T Rs_i`` (``a, b`` the
    centred points), a weighted Procrustes problem, alternated with the scale and with
    both noise levels re-estimated from the residuals. Where the centres fix the rotation
    well, it is the centres' fit (:func:`umeyama`); where they leave it loose (cameras
    near a line: a facade's survey), the orientations fix what the centres do not.
    Orientation outliers (beyond ``k`` times the median) and ``centre_inliers`` False
    are left out of their terms.

    Parameters
    ----------
    src, dst : (n, 3) float64
        Camera centres.
    src_rotations, dst_rotations : (n, 3, 3) float64
        The cameras' ``cam_from_world`` rotations.
    centre_inliers : (n,) bool, optional
        The centres to fit on (e.g. :func:`robust_umeyama`'s).

    Returns
    -------
    Sim3, float, float
        The fit (``dst`` from ``src``), ``sigma_c`` (dst's units) and ``sigma_r``
        (radians), the noise levels of its last round.

    Examples
    --------
    >>> rng = np.random.default_rng(2)
    >>> p = rng.normal(size=(6, 3))
    >>> Rs = np.array([np.eye(3)] * 6)
    >>> sim, _, _ = joint_similarity(p, 2.0 * p + 1.0, Rs, Rs)
    >>> round(sim.scale, 9), bool(np.allclose(sim.R, np.eye(3)))
    (2.0, True)
    """
    src = check_array(src, "src", shape=(None, 3), min_rows=3)
    dst = check_array(dst, "dst", shape=(len(src), 3))
    rs = check_array(src_rotations, "src_rotations", shape=(len(src), 3, 3))
    rd = check_array(dst_rotations, "dst_rotations", shape=(len(src), 3, 3))
    use_c = np.ones(len(src), bool) if centre_inliers is None else np.asarray(centre_inliers,
                                                                              bool)
    sim = umeyama(src[use_c], dst[use_c])
    G, s = sim.R, sim.scale
    a_all = src - src[use_c].mean(0)
    b_all = dst - dst[use_c].mean(0)
    a, b = a_all[use_c], b_all[use_c]
    floor = 1e-12 * max(float(np.ptp(dst, axis=0).max()), 1e-300)
    rot_cross = np.einsum("nji,njk->nik", rd, rs)  # Rd_i^T Rs_i
    sigma_c = sigma_r = 0.0
    for _ in range(iterations):
        rc = b - s * a @ G.T
        sigma_c = max(float(np.sqrt(np.mean(np.sum(rc * rc, axis=1)) / 3.0)), floor)
        ang = np.array([np.linalg.norm(r - e @ G.T) for r, e in zip(rd, rs, strict=True)])
        use_r = ang <= k * float(np.median(ang)) + 1e-12
        # ||Rd - Rs G^T||_F^2 is 2 |theta|^2 for a small angle theta: E = 6 sigma_r^2
        sigma_r = max(float(np.sqrt(np.mean(ang[use_r] ** 2) / 6.0)), 1e-12)
        M = s * (b.T @ a) / sigma_c ** 2 + rot_cross[use_r].sum(0) / (2.0 * sigma_r ** 2)
        U, _, Vt = np.linalg.svd(M)
        G_new = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
        s = float(np.sum(b * (a @ G_new.T)) / np.sum(a * a))
        done = np.abs(G_new - G).max() < 1e-13
        G = G_new
        if done:
            break
    t = dst[use_c].mean(0) - s * G @ src[use_c].mean(0)
    return Sim3(s, G, t), sigma_c, sigma_r


@dataclass
class PoseErrors:
    """Errors of estimated cameras after a Sim(3) alignment to the true ones.

    Attributes
    ----------
    alignment : Sim3
        Maps the estimate's world frame into the true world frame.
    names : list of str
        Cameras present in both (the registered ones).
    rotation_deg : (n,) float64
    centre_error : (n,) float64
        In the true frame's units (metres).
    registered_fraction : float
    inliers : (n,) bool or None
        The cameras a robust fit was made on (None: least squares over all).
    """

    alignment: Sim3
    names: list
    rotation_deg: np.ndarray
    centre_error: np.ndarray
    registered_fraction: float
    inliers: np.ndarray | None = None

    @property
    def ate(self) -> float:
        """RMS centre error after alignment (absolute trajectory error)."""
        return float(np.sqrt(np.mean(self.centre_error ** 2)))

    def summary(self, scene_size: float | None = None) -> dict:
        """JSON-ready figures; with ``scene_size`` also ATE as a fraction of it."""
        out = {"registered_fraction": self.registered_fraction,
               "num_compared": len(self.names),
               "rotation_error_deg": {"mean": float(self.rotation_deg.mean()),
                                      "median": float(np.median(self.rotation_deg)),
                                      "max": float(self.rotation_deg.max())},
               "centre_error": {"mean": float(self.centre_error.mean()),
                                "median": float(np.median(self.centre_error)),
                                "max": float(self.centre_error.max())},
               "ate": self.ate,
               "alignment_scale": self.alignment.scale}
        if scene_size:
            out["scene_size"] = float(scene_size)
            out["ate_fraction_of_scene"] = self.ate / float(scene_size)
        return out


def align_cameras(est_cam_from_world: Mapping[str, np.ndarray],
                  true_cam_from_world: Mapping[str, np.ndarray], *,
                  robust: bool = False) -> PoseErrors:
    """Align estimated cameras to true ones by their centres and measure the errors
    (``robust``: by :func:`robust_umeyama`, else least squares over all).

    Parameters
    ----------
    est_cam_from_world : mapping name -> (4, 4) float64
        Registered cameras of the reconstruction.
    true_cam_from_world : mapping name -> (4, 4) float64
        Every camera of the capture.

    Raises
    ------
    ValueError
        Fewer than 3 cameras in common.
    """
    names = [n for n in true_cam_from_world if n in est_cam_from_world]
    if len(names) < 3:
        raise ValueError(f"est_cam_from_world: expected at least 3 cameras in common with the "
                         f"true ones, got {len(names)}")
    est = [check_array(est_cam_from_world[n], f"est_cam_from_world[{n!r}]", shape=(4, 4))
           for n in names]
    true = [check_array(true_cam_from_world[n], f"true_cam_from_world[{n!r}]", shape=(4, 4))
            for n in names]

    def centre(T):
        return -T[:3, :3].T @ T[:3, 3]

    src, dst = np.array([centre(T) for T in est]), np.array([centre(T) for T in true])
    inliers = None
    if robust:
        sim, inliers = robust_umeyama(src, dst)
    else:
        sim = umeyama(src, dst)
    rot, cerr = [], []
    for Te, Tt in zip(est, true, strict=False):
        Ta = sim.apply_cam_from_world(Te)
        rot.append(rotation_angle_deg(Tt[:3, :3] @ Ta[:3, :3].T))
        cerr.append(np.linalg.norm(centre(Ta) - centre(Tt)))
    return PoseErrors(sim, names, np.array(rot), np.array(cerr),
                      len(names) / len(true_cam_from_world), inliers)
