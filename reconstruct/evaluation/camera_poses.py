"""Errors of estimated cameras against reference cameras (a benchmark's, a rig's), view
by view, after a robust similarity fit.

SfM places cameras up to a similarity. The estimate's camera centres are mapped onto the
reference's by :func:`reconstruct.evaluation.sim3.robust_umeyama` (least squares,
dropping the worst camera while it lies beyond three times the others' median), so one
misplaced view does not move the others' errors. Then, per view present in both:

- the rotation error (degrees): the angle of ``R_ref (R_est G^T)^T``, ``G`` the centres'
  Sim(3)'s rotation. This is what openMVG's evaluation reports (its
  ``tools_precisionEvaluationToGt.hpp`` fits the similarity on the centres only and
  measures each orientation against it). Where the cameras stand near a line, the
  centres leave that fit's rotation loose about the line, and every view inherits the
  slack: with centre noise ``sigma`` per axis and a spread ``d`` (rms) of the centres
  across the line, the rotation about it is fixed to ``sigma / (d sqrt(n))`` radians
  only, whatever the orientations' own accuracy;
- the same after the **joint** fit (:func:`reconstruct.evaluation.sim3.joint_similarity`):
  the maximum-likelihood similarity of centres and orientations together, each weighted
  by its own noise level estimated from the residuals. It reduces to the centres' fit
  where the centres fix the rotation and lets the orientations fix what they do not, so
  it holds for any layout of cameras. It cannot tell a rotation common to every camera's
  frame (a wrong principal point when the views look the same way) from the gauge about
  the axes the centres leave loose; the centres' figure does, so both are reported;
- the **relative** rotation error per view (degrees): the median over the other views
  of the angle of ``(R_ref_i R_ref_j^T)(R_est_i R_est_j^T)^T``, which no gauge enters:
  it bounds what any fit can make of the orientations;
- the centre error, in the reference's units and as a share of the scene's extent (the
  largest distance between two reference camera centres);
- the focal-length error (relative, of ``(fx + fy) / 2``) and the principal point's
  offset (pixels), which say how well the intrinsics were estimated (they are zero up
  to bundle adjustment's refinement when the intrinsics were given).

References
----------
R. Hartley, J. Trumpf, Y. Dai, H. Li, "Rotation averaging", IJCV 103(3), 2013.

>>> from core.frames import rotation_about
>>> ref = {}
>>> for k in range(6):
...     T = rotation_about([0, 1, 0], 0.3 * k); T[:3, 3] = [0.5 * k, 0.0, 4.0]
...     ref[f"v{k}"] = Camera(640, 480, 500.0, 500.0, 319.5, 239.5, np.zeros(5), T)
>>> est = {n: c.with_pose(Sim3(2.0, np.eye(3), np.ones(3)).apply_cam_from_world(
...     c.cam_from_world)) for n, c in ref.items()}  # the same cameras, twice the size
>>> err = compare_cameras(est, ref)
>>> float(err.rotation_deg.max()) < 1e-9, float(err.centre_error.max()) < 1e-9
(True, True)
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from acquire.camera import Camera
from core.frames import rotation_angle_deg
from core.validate import InputError

from .sim3 import Sim3, align_cameras, joint_similarity

__all__ = ["CameraErrors", "compare_cameras", "read_estimated_cameras",
           "relative_rotation_errors"]


@dataclass
class CameraErrors:
    """Per-view errors after the robust Sim(3) fit.

    Attributes
    ----------
    names : list of str
        Views present in both.
    rotation_deg, centre_error : (n,) float64
        Centre error in the reference's units.
    extent : float
        Largest distance between two reference camera centres.
    focal_error : (n,) float64
        ``|f_est - f_ref| / f_ref`` with ``f = (fx + fy) / 2``.
    principal_point_error_px : (n,) float64
    inliers : (n,) bool
        The views the similarity was fitted on.
    missing : list of str
        Reference views the estimate does not hold.
    alignment : Sim3
        ``reference_from_estimate``.
    rotation_deg_joint, centre_error_joint : (n,) float64
        The errors after the joint fit of centres and orientations.
    relative_rotation_deg : (n,) float64
        Per view, the median relative-rotation error against the other views.
    joint_alignment : Sim3
        The joint fit (``reference_from_estimate``).
    """

    names: list
    rotation_deg: np.ndarray
    centre_error: np.ndarray
    extent: float
    focal_error: np.ndarray
    principal_point_error_px: np.ndarray
    inliers: np.ndarray
    missing: list
    alignment: Sim3
    rotation_deg_joint: np.ndarray
    centre_error_joint: np.ndarray
    relative_rotation_deg: np.ndarray
    joint_alignment: Sim3

    def summary(self) -> dict:
        """The medians and maxima (JSON-ready)."""
        def stats(v):
            return {"median": float(np.median(v)), "max": float(np.max(v)),
                    "mean": float(np.mean(v))}

        return {"views": len(self.names), "missing": len(self.missing),
                "rotation_error_deg": stats(self.rotation_deg),
                "rotation_error_deg_joint": stats(self.rotation_deg_joint),
                "centre_error_joint": stats(self.centre_error_joint),
                "centre_error_joint_fraction_of_extent":
                    stats(self.centre_error_joint / self.extent),
                "relative_rotation_error_deg": stats(self.relative_rotation_deg),
                "centre_error": stats(self.centre_error),
                "centre_error_fraction_of_extent": stats(self.centre_error / self.extent),
                "extent": self.extent, "focal_error": stats(self.focal_error),
                "principal_point_error_px": stats(self.principal_point_error_px)}

    def to_dict(self) -> dict:
        return {"views": [{"image": n, "rotation_error_deg": float(r),
                           "rotation_error_deg_joint": float(rc),
                           "centre_error_joint": float(cj),
                           "relative_rotation_error_deg": float(rr),
                           "centre_error": float(c),
                           "centre_error_fraction_of_extent": float(c / self.extent),
                           "focal_error": float(f), "principal_point_error_px": float(p),
                           "sim3_inlier": bool(i)}
                          for n, r, rc, cj, rr, c, f, p, i in zip(
                              self.names, self.rotation_deg, self.rotation_deg_joint,
                              self.centre_error_joint, self.relative_rotation_deg,
                              self.centre_error, self.focal_error,
                              self.principal_point_error_px, self.inliers, strict=True)],
                "missing": list(self.missing), "summary": self.summary(),
                "reference_from_estimate": self.alignment.matrix.tolist(),
                "reference_from_estimate_joint": self.joint_alignment.matrix.tolist()}

    def table(self) -> str:
        rows = [f"{'view':<24} {'rotation (deg)':>14} {'(joint)':>9} {'(relative)':>10} "
                f"{'centre':>12} {'% extent':>9} {'(joint)':>9} {'focal %':>8} {'pp (px)':>8}"]
        for n, r, rc, rr, c, cj, f, p, i in zip(
                self.names, self.rotation_deg, self.rotation_deg_joint,
                self.relative_rotation_deg, self.centre_error, self.centre_error_joint,
                self.focal_error, self.principal_point_error_px, self.inliers, strict=True):
            rows.append(f"{n:<24} {r:>14.4f} {rc:>9.4f} {rr:>10.4f} {c:>12.5f} "
                        f"{100 * c / self.extent:>9.4f} {100 * cj / self.extent:>9.4f} "
                        f"{100 * f:>8.3f} {p:>8.2f}" + ("" if i else "  (Sim(3) outlier)"))
        rows += [f"{m:<24} {'not registered':>14}" for m in self.missing]
        s = self.summary()
        rows.append(f"{'median':<24} {s['rotation_error_deg']['median']:>14.4f} "
                    f"{s['rotation_error_deg_joint']['median']:>9.4f} "
                    f"{s['relative_rotation_error_deg']['median']:>10.4f} "
                    f"{s['centre_error']['median']:>12.5f} "
                    f"{100 * s['centre_error_fraction_of_extent']['median']:>9.4f} "
                    f"{100 * s['centre_error_joint_fraction_of_extent']['median']:>9.4f} "
                    f"{100 * s['focal_error']['median']:>8.3f} "
                    f"{s['principal_point_error_px']['median']:>8.2f}")
        rows.append(f"({len(self.names)} of {len(self.names) + len(self.missing)} views; "
                    f"extent {self.extent:.4g}: the largest distance between two reference "
                    f"cameras; rotation against the centres' Sim(3) as openMVG reports it, "
                    f"after the joint fit of centres and orientations, and relative: no "
                    f"gauge)")
        return "\n".join(rows)


def compare_cameras(estimated: Mapping[str, Camera],
                    reference: Mapping[str, Camera]) -> CameraErrors:
    """Compare cameras by image name (module docstring).

    Raises
    ------
    ValueError
        Fewer than 3 views in common, or reference cameras all at one place.
    """
    names = [n for n in reference if n in estimated]
    missing = [n for n in reference if n not in estimated]
    if len(names) < 3:
        raise ValueError(f"estimated: expected at least 3 views in common with the "
                         f"reference, got {len(names)}")
    centres = np.array([c.center for c in reference.values()])
    extent = float(np.max(np.linalg.norm(centres[:, None] - centres[None], axis=2)))
    if extent <= 0:
        raise ValueError("reference: the cameras are all at one place (no extent)")
    errs = align_cameras({n: estimated[n].cam_from_world for n in names},
                         {n: reference[n].cam_from_world for n in names}, robust=True)
    f_est = np.array([0.5 * (estimated[n].fx + estimated[n].fy) for n in names])
    f_ref = np.array([0.5 * (reference[n].fx + reference[n].fy) for n in names])
    pp = np.array([np.hypot(estimated[n].cx - reference[n].cx,
                            estimated[n].cy - reference[n].cy) for n in names])
    R_est = np.array([estimated[n].cam_from_world[:3, :3] for n in names])
    R_ref = np.array([reference[n].cam_from_world[:3, :3] for n in names])
    c_est = np.array([estimated[n].center for n in names])
    c_ref = np.array([reference[n].center for n in names])
    joint, _, _ = joint_similarity(c_est, c_ref, R_est, R_ref, centre_inliers=errs.inliers)
    rot_joint = np.array([rotation_angle_deg(r @ (e @ joint.R.T).T)
                          for e, r in zip(R_est, R_ref, strict=True)])
    centre_joint = np.linalg.norm(joint.apply(c_est) - c_ref, axis=1)
    return CameraErrors(names, errs.rotation_deg, errs.centre_error, extent,
                        np.abs(f_est - f_ref) / f_ref, pp, errs.inliers, missing,
                        errs.alignment, rot_joint, centre_joint,
                        relative_rotation_errors(R_est, R_ref), joint)


def relative_rotation_errors(est: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Per view, the median over the other views of the angle (degrees) between the
    estimated and the reference relative rotations ``R_i R_j^T`` (``est, ref : (n, 3, 3)``
    cam_from_world rotations): an error no choice of world frame enters."""
    n = len(est)
    err = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1, n):
            err[i, j] = err[j, i] = rotation_angle_deg(
                (ref[i] @ ref[j].T) @ (est[i] @ est[j].T).T)
    return np.array([np.median(np.delete(err[i], i)) for i in range(n)])


def read_estimated_cameras(path: str | os.PathLike, *, sizes: Mapping[str, tuple[int, int]]
                           | None = None) -> tuple[dict[str, Camera], str | None]:
    """The cameras of a reconstruction folder (its ``sparse/0`` model) or of any file
    :func:`reconstruct.camera_files.read_cameras` reads; and where the reconstruction's
    intrinsics came from (its report.json's ``intrinsics_source``), when it says."""
    from reconstruct.camera_files import read_cameras

    path = Path(path)
    source = None
    if path.is_dir() and (path / "sparse" / "0").is_dir():
        rep = path / "report.json"
        if rep.is_file():
            try:
                source = json.loads(rep.read_text()).get("intrinsics_source")
            except (json.JSONDecodeError, UnicodeDecodeError):
                raise InputError("unreadable JSON", path=rep) from None
        path = path / "sparse" / "0"
    return read_cameras(path, sizes=sizes), source
