"""The principal point: refined by a final bundle adjustment where the views constrain it,
kept at the image centre (with the reason logged and reported) where they do not.

COLMAP's mapper keeps every camera's principal point where it started (the image centre)
because on most photo sets it cannot be told apart from the cameras' rotations: a shift
of ``d`` pixels moves the whole image as turning the camera by ``atan(d / f)`` does. Real
lenses are not centred (the Strecha benchmark's camera: (15, 17) px off at f = 2760 px),
and that offset becomes a rotation error of the same size in every view (0.48 degrees).

The two differ only when the views look at the scene from a spread of directions: turning
every camera by the same angle in its own frame then bends rays that cross at a point
apart, which the reprojection error sees (the same reason that a planar target seen from
several orientations calibrates a camera, Zhang 2000). So, per camera that photos share
and whose intrinsics were not given:

1. enough views (``min_views``) and a spread of optical axes of at least
   ``min_spread_deg`` (the largest angle between two of them), else it is kept;
2. a bundle adjustment refines the principal point with everything else (poses, points,
   focal length, distortion);
3. the same refinement on two random halves of the 3-D points, twice: the halves'
   estimates differ by about twice the full set's standard error, so the larger of the
   two differences, halved, is its uncertainty, per coordinate. A coordinate is refined
   when that uncertainty, as an angle (``atan(sigma / f)``), stays below
   ``max_sigma_deg`` and the shift is at least ``min_significance`` times it (else the
   centre is as good a guess); the whole shift must stay below ``max_shift_fraction`` of
   the image's larger side;
4. a coordinate that fails keeps its start (a ring of views at one height fixes x: the
   views' yaw; a common pitch of all of them is nearly a vertical shift of the scene, so
   y is weaker), and the model is adjusted again with the principal point held.

References
----------
Z. Zhang, "A flexible new technique for camera calibration", IEEE TPAMI 22(11), 2000.
"""

from __future__ import annotations

import logging
from dataclasses import asdict, dataclass

import numpy as np

from reconstruct.sfm.colmap import _quiet_colmap

__all__ = ["PrincipalPointDecision", "refine_principal_point", "view_spread_deg",
           "decisions_report"]

log = logging.getLogger(__name__)


@dataclass
class PrincipalPointDecision:
    """What was decided for one camera, and why (``asdict`` is report-ready).

    Attributes
    ----------
    camera_id : int
    refined : bool
        True when the refined principal point was kept.
    reason : str
    views : int
        Registered views of the camera.
    spread_deg : float
        Largest angle between two of their optical axes.
    shift_px : list of float or None
        Refined minus starting principal point (x, y), pixels (what the trial moved it
        by, kept or not).
    sigma_px : list of float or None
        Its uncertainty per coordinate from the halves (see the module docstring).
    rms_px : list of float or None
        Mean reprojection error before and after.
    axes : str
        The coordinates refined: "xy", "x", "y" or "" (each is judged on its own: a ring
        of views at one height fixes x, not y, which trades against a common pitch).
    """

    camera_id: int
    refined: bool
    reason: str
    views: int
    spread_deg: float
    shift_px: list | None = None
    sigma_px: list | None = None
    rms_px: list | None = None
    axes: str = ""


def view_spread_deg(rec, camera_id: int) -> tuple[int, float]:
    """Registered views of ``camera_id`` and the largest angle (degrees) between two of
    their optical axes."""
    axes = [im.cam_from_world().rotation.matrix()[2] for im in rec.images.values()
            if im.has_pose and im.camera_id == camera_id]
    if len(axes) < 2:
        return len(axes), 0.0
    a = np.array(axes)
    cos = np.clip(a @ a.T, -1.0, 1.0)
    return len(axes), float(np.degrees(np.arccos(cos.min())))


def _adjust(rec, refine_pp: bool, num_threads: int) -> None:
    import pycolmap

    opt = pycolmap.BundleAdjustmentOptions()
    opt.refine_principal_point = refine_pp
    opt.print_summary = False
    opt.ceres.solver_options.num_threads = num_threads
    from core.io.mesh import native_output

    said: list[str] = []
    # COLMAP's INFO lines: errors only, as the mapper's; this call prints its headings to
    # the terminal whatever glog's level, so they go to the log instead
    with _quiet_colmap(2), native_output(said, fds=(2,), open3d=False):
        pycolmap.bundle_adjustment(rec, opt)
    if said:
        log.debug("COLMAP bundle adjustment: %s", " ".join(said))


def _principal_points(rec, ids) -> dict:
    return {cid: np.array([rec.cameras[cid].principal_point_x,
                           rec.cameras[cid].principal_point_y]) for cid in ids}


def _half(rec, keep_even: bool, rng: np.random.Generator):
    import pycolmap

    half = pycolmap.Reconstruction(rec)
    ids = np.array(sorted(half.point3D_ids()))
    side = rng.permutation(len(ids)) % 2 == (0 if keep_even else 1)
    for pid in ids[~side]:
        half.delete_point3D(int(pid))
    return half


def _halves_sigma(rec, candidates, splits: int, rng: np.random.Generator,
                  num_threads: int) -> dict:
    """Per camera, the uncertainty (x, y) of its refined principal point: half the
    largest difference between the estimates from two random halves of the points."""
    sigma = {cid: np.zeros(2) for cid in candidates}
    for _ in range(splits):
        seed = int(rng.integers(2**31))
        est = []
        for keep_even in (True, False):
            half = _half(rec, keep_even, np.random.default_rng(seed))
            _adjust(half, True, num_threads)
            est.append(_principal_points(half, candidates))
        for cid in candidates:
            sigma[cid] = np.maximum(sigma[cid], 0.5 * np.abs(est[0][cid] - est[1][cid]))
    return sigma


def refine_principal_point(rec, camera_ids, *, min_views: int = 5,
                           min_spread_deg: float = 10.0, max_sigma_deg: float = 0.1,
                           min_significance: float = 2.0,
                           max_shift_fraction: float = 0.05, splits: int = 2,
                           num_threads: int = -1,
                           rng: np.random.Generator | None = None) -> tuple[object, list]:
    """Refine the principal point of ``camera_ids`` in ``rec`` (a ``pycolmap.Reconstruction``)
    where the views constrain it (module docstring).

    Returns
    -------
    pycolmap.Reconstruction, list of PrincipalPointDecision
        The refined copy (``rec`` itself when no camera was refined) and one decision per
        camera of ``camera_ids`` with a registered view.
    """
    import pycolmap

    rng = rng if rng is not None else np.random.default_rng(0)
    decisions, candidates = {}, []
    for cid in camera_ids:
        if cid not in rec.cameras:
            continue
        n, spread = view_spread_deg(rec, cid)
        if n == 0:
            continue
        d = PrincipalPointDecision(int(cid), False, "", n, spread)
        if n < min_views:
            d.reason = (f"kept at the centre: {n} views (fewer than {min_views}) cannot tell "
                        "it from their rotations")
        elif spread < min_spread_deg:
            d.reason = (f"kept at the centre: the optical axes span {spread:.1f} degrees "
                        f"(< {min_spread_deg:g}), where a shift of it is indistinguishable from "
                        "a rotation of every view")
        else:
            candidates.append(cid)
        decisions[cid] = d
    if candidates:
        start = _principal_points(rec, candidates)
        rms0 = rec.compute_mean_reprojection_error()
        trial = pycolmap.Reconstruction(rec)
        _adjust(trial, True, num_threads)
        refined = _principal_points(trial, candidates)
        rms1 = trial.compute_mean_reprojection_error()
        sigma = _halves_sigma(rec, candidates, splits, rng, num_threads)
        kept_any = False
        for cid in candidates:
            cam = trial.cameras[cid]
            f = float(cam.mean_focal_length())
            shift = refined[cid] - start[cid]
            d = decisions[cid]
            d.shift_px, d.sigma_px = shift.round(3).tolist(), sigma[cid].round(3).tolist()
            d.rms_px = [rms0, rms1]
            sig_deg = np.degrees(np.arctan2(sigma[cid], f))
            stable = sig_deg <= max_sigma_deg
            ok = stable & (np.abs(shift) >= min_significance * sigma[cid])
            if np.linalg.norm(shift) > max(cam.width, cam.height) * max_shift_fraction:
                ok[:] = False
                d.reason = (f"kept at the centre: refined {np.linalg.norm(shift):.0f} px away, "
                            f"more than {100 * max_shift_fraction:g} % of the image")
            d.axes = "".join(a for a, k in zip("xy", ok, strict=True) if k)
            d.refined = bool(ok.any())
            parts = [f"{a} {'refined by' if k else 'kept: moved'} {dv:+.1f} px (halves "
                     f"{2 * sv:.1f} px apart: {sd:.3f} deg, "
                     + ("significant" if k else f"above {max_sigma_deg:g} deg" if not st
                        else f"below {min_significance:g} x its uncertainty") + ")"
                     for a, k, st, dv, sv, sd in
                     zip("xy", ok, stable, shift, sigma[cid], sig_deg, strict=True)]
            if not d.reason:
                d.reason = "; ".join(parts) + f"; reprojection {rms0:.3f} -> {rms1:.3f} px"
            if not ok.all():  # the refused axes back where they started
                kept_any = True
                p = np.array(cam.params, float)
                idx = np.asarray(cam.principal_point_idxs())
                p[idx[~ok]] = start[cid][~ok]
                cam.params = p
        if any(decisions[c].refined for c in candidates):
            if kept_any:  # everything adjusted again around the kept coordinates
                _adjust(trial, False, num_threads)
                for cid in candidates:
                    decisions[cid].rms_px[1] = trial.compute_mean_reprojection_error()
            rec = trial
    out = list(decisions.values())
    for d in out:
        log.info("principal point of camera %d (%d views, axes spanning %.1f deg): %s",
                 d.camera_id, d.views, d.spread_deg, d.reason)
    return rec, out


def decisions_report(decisions: list) -> list:
    """The decisions as report.json entries."""
    return [asdict(d) for d in decisions]
