"""Registering the views the default sparse stage left out, as COLMAP practitioners do.

The default (:func:`reconstruct.sfm.colmap.reconstruct`) runs first. When it leaves views
out, :func:`escalate` tries the stronger, slower steps on the same photos, in order, and
stops as soon as every view is in:

1. **Stronger features**: SIFT again with a lower peak threshold (dark, low-contrast
   photos: the Middlebury dino on black has ~250 default features per view, ~1 500 at
   0.001), twice the features, affine-covariant shapes and domain-size pooling
   (``SiftExtractionOptions.estimate_affine_shape``, ``domain_size_pooling``: about
   three times the extraction time of plain SIFT, and more accurate poses on the dino).
2. **Matching with geometry**: exhaustive up to 100 images, else sequential in file order
   with the ring closed (the last views matched to the first: loop closure without a
   vocabulary tree); guided matching (``FeatureMatchingOptions.guided_matching``) once a
   pair's two-view geometry is known adds the matches along its epipolar lines.
3. **The default's focal length as the prior**: a camera without EXIF starts at COLMAP's
   guess of 1.2 x the larger side (768 px for a 640 px photo; the dino's lens has 3 310);
   the focal length bundle adjustment refined on the views that did register replaces it.
4. **Relaxed mapping, tried in order** (:data:`LADDER`): fewer inliers and a smaller
   triangulation angle for the initial pair, fewer inliers for each registration, and
   the distortion held at zero (a long lens cannot tell it from the focal length).
5. **Models merged**: the mapper may give several models of one ring (a weak link breaks
   it); two models that share at least two views are joined by the similarity of those
   views (their rotations and centres), and the union is triangulated again.
6. **Re-localization**: the views still out are registered against the finished model
   with permissive absolute-pose settings (:data:`RELOCALIZE`); a model that was merged
   or grew so gets a second bundle adjustment (:func:`refine`: the points triangulated
   again from every verified match, a Huber loss, in rounds whose largest reprojection
   error shrinks from 32 to 4 px, so that the matches across a merge's kinked joins are
   admitted and pull it straight instead of being dropped as outliers). A model the
   relaxed mapper built in one piece has had its global bundle adjustment already.
7. **Restarts when the ring is weak**: joined from models, short of views, or with a
   view tied to one neighbour only (:func:`weakly_tied`). A ring the mapper built as
   several models and the merge joined is weakly determined at its joins (a long lens
   barely tells a turn from a shift, and few points tie the views across a join): from
   the same features, the matching's verification seed alone moved the dino's mean
   rotation error between 1.2 and 6.2 degrees at the same reprojection error. Steps 2-6
   then run again with :attr:`EscalationOptions.restarts` other seeds; the runs' verified
   matches are pooled (:func:`pool_matches`: a weak link verified by one seed only ties
   every run's ring), each run's model is refined again on them, and the model whose
   cameras best explain the pooled matches (:func:`epipolar_consistency`) is kept.

Every step is a pycolmap call; nothing is learned, nothing is downloaded. The report says
which steps ran, what each registered and how long it took.
"""

from __future__ import annotations

import logging
import shutil
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2  # noqa: F401  (before pycolmap)
import numpy as np

from reconstruct.camera_files import image_cam_from_world
from reconstruct.evaluation.sim3 import Sim3
from reconstruct.sfm.colmap import ColmapOptions, _extract_cameras, _quiet_colmap, hold_intrinsics

__all__ = ["EscalationOptions", "escalate", "LADDER", "RELOCALIZE", "merge_models",
           "similarity_from_common_views", "pair_inliers", "ring_pairs",
           "epipolar_consistency", "pool_matches", "refine", "weakly_tied",
           "remap_in_file_order", "ORDERED_OVERLAP"]

log = logging.getLogger(__name__)

#: relaxed mapper thresholds, tried in order: (initial pair: min inliers, min
#: triangulation angle in degrees; registration: min inliers, min inlier ratio)
LADDER = ((50, 8.0, 15, 0.15), (30, 4.0, 12, 0.10))
#: absolute-pose settings of the re-localization: min inliers, min inlier ratio, max error px
RELOCALIZE = (8, 0.05, 12.0)
#: how far apart in file order two views may be for :func:`remap_in_file_order` to keep
#: their matches (a ring of 12-16 views: neighbours up to 45-90 degrees apart)
ORDERED_OVERLAP = 3


@dataclass
class EscalationOptions:
    """The stronger steps' settings (defaults: what registered the dino ring).

    Attributes
    ----------
    peak_threshold : float
        SIFT's difference-of-Gaussians threshold (COLMAP's default 0.0067).
    max_features : int
    affine : bool
        Affine-covariant SIFT (``estimate_affine_shape``, about three times the extraction
        time of plain SIFT; on the dino ring it gave 1.25 degrees of mean rotation error
        where plain SIFT at the same threshold gave 1.66, both registering 16 of 16).
    dsp : bool
        Domain-size pooling of the descriptors.
    guided : bool
        Guided matching after the two-view geometry.
    sequential_overlap : int
        Neighbours matched beyond 100 images (file order, the ring closed).
    exhaustive_max : int
        Exhaustive matching up to this many images.
    restarts : int
        When the relaxed mapper broke the set into models that had to be merged (a ring
        joined at weak links), left views out, or left a view tied to one neighbour only
        (:func:`weakly_tied`), the matching's verification, the mapping, the merge and the
        second bundle adjustment run again with this many other seeds, and the model most
        consistent with every run's verified matches is kept (:func:`epipolar_consistency`).
        The joins are weakly determined: on the dino ring three seeds gave mean rotation
        errors of 1.28, 1.20 and 6.19 degrees at the same reprojection error.
    refine_schedule_px : tuple of float
        The second bundle adjustment's rounds (:func:`refine`): in each, the largest
        reprojection error in pixels a triangulated point may keep, shrinking so that the
        matches across a merged model's joins are admitted first and the outliers dropped
        last. COLMAP's own threshold is 4 px; ``(4.0, 4.0)`` keeps it throughout.
    pool_restarts : bool
        After the restarts, the runs' verified matches are pooled (for each pair, the
        run that verified the most inliers) and every run's model is refined again on
        them before the choice (:func:`pool_matches`): a weak link verified by one seed
        only then ties every run's ring together.
    """

    peak_threshold: float = 0.001
    max_features: int = 16384
    affine: bool = True
    dsp: bool = True
    guided: bool = True
    sequential_overlap: int = 10
    exhaustive_max: int = 100
    restarts: int = 2
    refine_schedule_px: tuple[float, ...] = (32.0, 16.0, 8.0, 4.0)
    pool_restarts: bool = True


def ring_pairs(names: Sequence[str], overlap: int) -> list[tuple[str, str]]:
    """Each view with its next ``overlap`` views in file order, wrapping around (a ring
    closes on itself).

    >>> ring_pairs(["a", "b", "c", "d"], 1)
    [('a', 'b'), ('b', 'c'), ('c', 'd'), ('a', 'd')]
    """
    n, out = len(names), set()
    for i in range(n):
        for k in range(1, min(overlap, n - 1) + 1):
            a, b = sorted((i, (i + k) % n))
            out.add((a, b))
    return [(names[a], names[b]) for a, b in sorted(out, key=lambda p: (p[1] - p[0] > overlap,
                                                                        p))]


def pair_inliers(database: str | Path) -> dict[tuple[str, str], int]:
    """Verified inlier matches of every image pair of a COLMAP database, by names."""
    import pycolmap

    db = pycolmap.Database.open(str(database))
    try:
        names = {im.image_id: im.name for im in db.read_all_images()}
        out = {}
        if db.num_verified_image_pairs():
            ids, geoms = db.read_two_view_geometries()
            for pid, g in zip(ids, geoms, strict=False):
                a, b = pycolmap.pair_id_to_image_pair(pid)
                out[(names[a], names[b])] = len(g.inlier_matches)
        return out
    finally:
        db.close()


def similarity_from_common_views(target: dict, source: dict) -> tuple[Sim3 | None, list]:
    """The similarity taking ``source``'s world into ``target``'s, from the views both
    registered (``{name: (4, 4) cam_from_world}`` each): the mean of the rotations
    ``R_t^T R_s`` projected on SO(3), then scale and translation by least squares over
    the centres. None with fewer than two views in common (the scale is then free)."""
    common = sorted(set(target) & set(source))
    if len(common) < 2:
        return None, common
    m = sum(target[n][:3, :3].T @ source[n][:3, :3] for n in common)
    u, _, vt = np.linalg.svd(m)
    rot = u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt

    def centre(T):
        return -T[:3, :3].T @ T[:3, 3]

    ct = np.array([centre(target[n]) for n in common])
    cs = np.array([centre(source[n]) for n in common]) @ rot.T
    dt, ds = ct - ct.mean(0), cs - cs.mean(0)
    denom = float(np.sum(ds * ds))
    if denom <= 0:
        return None, common
    scale = float(np.sum(ds * dt) / denom)
    if scale <= 0:
        return None, common
    return Sim3(scale, rot, ct.mean(0) - scale * cs.mean(0)), common


def _poses(rec) -> dict:
    return {im.name: image_cam_from_world(im) for im in rec.images.values() if im.has_pose}


def merge_models(models: Sequence) -> tuple[dict, object, list]:
    """Join models that share at least two views into the largest.

    Returns ``(poses, base, joined)``: ``{name: cam_from_world}`` in the largest model's
    frame, that model (its cameras give the intrinsics), and for each other model
    ``(views it had, views in common)`` when it was joined."""
    order = sorted(models, key=lambda r: -r.num_reg_images())
    base = order[0]
    poses, joined, left = _poses(base), [], list(order[1:])
    progress = True
    while left and progress:  # a model may share views only with one joined later
        progress = False
        for rec in list(left):
            sim, common = similarity_from_common_views(poses, _poses(rec))
            if sim is None:
                continue
            for name, T in _poses(rec).items():
                poses.setdefault(name, sim.apply_cam_from_world(T))
            joined.append((rec.num_reg_images(), common))
            left.remove(rec)
            progress = True
    return poses, base, joined


def escalate(database: Path, image_dir: Path, names: Sequence[str], groups: Sequence,
             opts: ColmapOptions, work: Path, default_rec, *,
             options: EscalationOptions | None = None, verbose: bool = False):
    """The stronger steps (module docstring) on the views ``default_rec`` left out.

    Parameters
    ----------
    database : path
        The default run's database (its images and cameras).
    image_dir : path
    names : sequence of str
        Every image.
    groups : sequence of (names, model, params)
        The COLMAP cameras of the default run.
    opts : ColmapOptions
    work : path
        A folder for the new database and models.
    default_rec : pycolmap.Reconstruction or None
        The default run's largest model.

    Returns
    -------
    (rec, database, report) : the best model (``default_rec`` when nothing did better),
        the database whose matches it used, and what each step did.
    """
    esc = options or EscalationOptions()
    work = Path(work)
    work.mkdir(parents=True, exist_ok=True)
    best_n = default_rec.num_reg_images() if default_rec is not None else 0
    report = {"entered_because": f"{best_n} of {len(names)} views registered by the default",
              "steps": []}
    state = {"best": default_rec, "db": Path(database), "n": best_n}
    with _quiet_colmap(0 if verbose else 2):
        cams, prior = _focal_priors(groups, default_rec)
        features = work / "strong_features.db"
        t = time.perf_counter()
        _extract_strong(features, image_dir, cams, opts, esc, affine=esc.affine, dsp=esc.dsp)
        report["steps"].append({"step": "stronger features",
                                "features": f"SIFT, peak threshold {esc.peak_threshold:g}"
                                            + (", affine-covariant" if esc.affine else "")
                                            + (", domain-size pooling" if esc.dsp else ""),
                                "focal_prior": prior, "seconds": time.perf_counter() - t})
        runs = [_solve(features, int(opts.seed), image_dir, names, opts, esc, work,
                       Path(database), dict(state), report["steps"])]
        # restarts only for a model of the stronger steps (none: nothing to improve on,
        # e.g. photos without camera motion)
        own = runs[0]["best"] is not None and runs[0]["db"] != Path(database)
        weak = weakly_tied(runs[0]["best"]) if own else []
        if esc.restarts > 0 and (runs[0]["merged"]
                                 or (own and (runs[0]["n"] < len(names) or weak))):
            for k in range(1, esc.restarts + 1):
                runs.append(_solve(features, int(opts.seed) + k, image_dir, names, opts, esc,
                                   work, Path(database), dict(state), []))
            if esc.pool_restarts:
                _pool_and_refine(runs, Path(database), image_dir, work, esc, report["steps"])
            chosen = _choose(runs)
            log.info("escalation: %d runs (seeds %s), "
                     "epipolar consistency %s px^2, kept seed %d", len(runs),
                     [r["seed"] for r in runs],
                     [round(r.get("consistency", float("nan")), 3) for r in runs],
                     runs[chosen]["seed"])
            report["steps"].append({
                "step": "restarts with other seeds",
                "because": ("the ring was joined from models" if runs[0]["merged"] else
                            f"{runs[0]['n']} of {len(names)} views registered"
                            if runs[0]["n"] < len(names) else
                            "views tied to one other view only: " + ", ".join(weak)),
                "runs": [{"seed": r["seed"], "registered": r["n"],
                          "epipolar_consistency_px2": r.get("consistency"),
                          "seconds": r["seconds"]} for r in runs],
                "chosen_seed": runs[chosen]["seed"],
                "seconds": sum(r["seconds"] for r in runs[1:])})
            runs = [runs[chosen]]
        best, best_db, best_n = runs[0]["best"], runs[0]["db"], runs[0]["n"]
    report["registered"] = best_n
    return best, best_db, report


def _solve(features: Path, seed: int, image_dir, names, opts: ColmapOptions,
           esc: EscalationOptions, work: Path, default_db: Path, state: dict,
           steps: list) -> dict:
    """On the stronger features (``features``, a database without matches): guided
    matching with ``seed``, the relaxed mapping ladder, re-localization of the views still
    out and the second bundle adjustment of a merged or grown model. ``state`` holds the
    default's model (``best``, ``db``, ``n``); ``steps`` receives what each step did.
    Returns the best model, its database and its count, whether a merge happened."""
    t0 = time.perf_counter()
    tag = "" if seed == int(opts.seed) else f"_seed{seed}"
    db = work / f"strong0{tag}.db"
    shutil.copy2(features, db)
    t = time.perf_counter()
    _match_strong(db, names, opts, esc, seed=seed)
    steps.append({"step": "guided matching", "seed": seed,
                  "seconds": time.perf_counter() - t})
    merged = False
    for rung, thresholds in enumerate(LADDER):
        t = time.perf_counter()
        rec, step = _map_relaxed(db, image_dir, work / f"relaxed0_{rung}{tag}", opts,
                                 thresholds, seed=seed)
        step["seconds"] = time.perf_counter() - t
        steps.append(step)
        merged |= "merged" in step
        if rec is not None and rec.num_reg_images() > state["n"]:
            state.update(best=rec, db=db, n=rec.num_reg_images(), joined="merged" in step)
        if state["n"] == len(names):
            break
    best, best_n = state["best"], state["n"]
    if best_n < len(names) and best is not None and state["db"] != default_db:
        t = time.perf_counter()
        rec = _relocalize(state["db"], image_dir, best, work / f"relocalized{tag}", opts)
        steps.append({"step": "re-localization against the model",
                      "settings": dict(zip(("min_inliers", "min_inlier_ratio",
                                            "max_error_px"), RELOCALIZE, strict=True)),
                      "registered": rec.num_reg_images(),
                      "seconds": time.perf_counter() - t})
        if rec.num_reg_images() > best_n:
            best, best_n, state["joined"] = rec, rec.num_reg_images(), True
    if best is not None and state.get("joined"):
        t = time.perf_counter()
        best = refine(best, state["db"], image_dir, work / f"refine{tag}",
                      schedule_px=esc.refine_schedule_px)
        steps.append({"step": "second bundle adjustment",
                      "mean_reprojection_error_px": best.compute_mean_reprojection_error(),
                      "seconds": time.perf_counter() - t})
    return {"best": best, "db": state["db"], "n": best_n, "merged": merged, "seed": seed,
            "seconds": time.perf_counter() - t0}


def pool_matches(databases: Sequence[str | Path], out: str | Path) -> tuple[Path, int]:
    """One database with, for every image pair, the verified two-view geometry of
    whichever of ``databases`` found the most inliers for it (all of them copies of one
    features database: the same images and keypoints). Returns its path and how many
    pairs came from a database other than the first."""
    import pycolmap

    out = Path(out)
    out.unlink(missing_ok=True)
    shutil.copy2(databases[0], out)
    pooled = pycolmap.Database.open(str(out))
    replaced = 0
    try:
        for path in databases[1:]:
            other = pycolmap.Database.open(str(path))
            try:
                ids, geoms = other.read_two_view_geometries() \
                    if other.num_verified_image_pairs() else ([], [])
            finally:
                other.close()
            for pid, g in zip(ids, geoms, strict=False):
                a, b = pycolmap.pair_id_to_image_pair(pid)
                have = pooled.exists_two_view_geometry(a, b)
                if len(g.inlier_matches) > (len(pooled.read_two_view_geometry(a, b)
                                                 .inlier_matches) if have else 0):
                    if have:
                        pooled.delete_two_view_geometry(a, b)
                    pooled.write_two_view_geometry(a, b, g)
                    replaced += 1
    finally:
        pooled.close()
    return out, replaced


def _pool_and_refine(runs: list, default_db: Path, image_dir, work: Path,
                     esc: EscalationOptions, steps: list) -> None:
    """The restarts' verified matches pooled (:func:`pool_matches`) and every run's model
    refined again on them (:func:`refine`), in place. A weak link (two views with few
    matches) is verified by some seeds and not by others: a ring closed at a join in one
    run is closed in all of them once the matches are pooled."""
    t = time.perf_counter()
    most = max(r["n"] for r in runs)
    # every run's matches count (a run whose mapping fell short may have verified the
    # weak link); the models refined are those with the most views
    dbs = list(dict.fromkeys(r["db"] for r in runs if r["db"] != default_db))
    usable = [r for r in runs if r["n"] == most and r["best"] is not None
              and r["db"] != default_db]
    if len(dbs) < 2 or not usable:
        return
    pooled, replaced = pool_matches(dbs, work / "pooled.db")
    for r in usable:
        r["best"] = refine(r["best"], pooled, image_dir, work / f"pooled_refine{r['seed']}",
                           schedule_px=esc.refine_schedule_px)
        r["db"] = pooled
    steps.append({"step": "matches of the restarts pooled, each model refined on them",
                  "runs": len(usable), "pairs_from_other_runs": replaced,
                  "seconds": time.perf_counter() - t})


def weakly_tied(rec, min_points: int = 15) -> list[str]:
    """The registered views that share at least ``min_points`` 3-D points with fewer than
    two other views: a ring open at that view (the dino's view 6 with seed 1: 29 points
    with view 5, none with view 7), held by one neighbour only."""
    names = {i: rec.images[i].name for i in rec.reg_image_ids()}
    shared: dict[tuple[int, int], int] = {}
    for p in rec.points3D.values():
        ids = sorted({e.image_id for e in p.track.elements})
        for k, a in enumerate(ids):
            for b in ids[k + 1:]:
                shared[(a, b)] = shared.get((a, b), 0) + 1
    ties = dict.fromkeys(names, 0)
    for (a, b), n in shared.items():
        if n >= min_points:
            ties[a] += 1
            ties[b] += 1
    return sorted(names[i] for i, n in ties.items() if n < 2)


def _choose(runs: list) -> int:
    """The run with the most views registered, then the lowest mean
    :func:`epipolar_consistency` over every run's database (each run's verified matches
    count once, so no run is judged on its own matches only); sets ``consistency``."""
    most = max(r["n"] for r in runs)
    dbs = list(dict.fromkeys(r["db"] for r in runs if r["n"] == most))
    for r in runs:
        if r["n"] == most and r["best"] is not None:
            r["consistency"] = float(np.mean([epipolar_consistency(r["best"], d)
                                              for d in dbs]))
    scored = [i for i, r in enumerate(runs) if "consistency" in r]
    return min(scored, key=lambda i: runs[i]["consistency"]) if scored else 0


def epipolar_consistency(rec, database: str | Path, max_error: float = 4.0) -> float:
    """How well a model's cameras agree with a database's verified matches: the mean over
    every inlier match between two registered views of its squared Sampson distance
    (px^2) to the epipolar geometry of the model's poses and intrinsics, each capped at
    ``max_error`` squared (a match the model does not explain costs the same whatever
    its distance: MSAC's score). NaN when no match is between registered views."""
    import pycolmap

    from reconstruct.sfm.self_check import sampson_distance

    db = pycolmap.Database.open(str(database))
    try:
        names = {im.image_id: im.name for im in db.read_all_images()}
        ids, geoms = db.read_two_view_geometries() if db.num_verified_image_pairs() \
            else ([], [])
        keypoints = {i: db.read_keypoints(i)[:, :2].astype(np.float64) for i in names}
    finally:
        db.close()
    posed = {im.name: im for im in rec.images.values() if im.has_pose}
    errors = []
    for pid, g in zip(ids, geoms, strict=False):
        a, b = pycolmap.pair_id_to_image_pair(pid)
        im1, im2 = posed.get(names[a]), posed.get(names[b])
        matches = np.asarray(g.inlier_matches)
        if im1 is None or im2 is None or len(matches) == 0:
            continue
        E = pycolmap.essential_matrix_from_pose(im2.cam_from_world()
                                                * im1.cam_from_world().inverse())
        k1 = np.linalg.inv(im1.camera.calibration_matrix())
        k2 = np.linalg.inv(im2.camera.calibration_matrix())
        F = k2.T @ E @ k1
        d = sampson_distance(F, keypoints[a][matches[:, 0]], keypoints[b][matches[:, 1]])
        errors.append(np.minimum(d * d, max_error ** 2))
    return float(np.mean(np.concatenate(errors))) if errors else float("nan")


def _focal_priors(groups, default_rec) -> tuple[list, str]:
    """The default run's cameras, a camera without a known focal length starting from
    the focal length bundle adjustment refined on the views that registered."""
    if default_rec is None or default_rec.num_reg_images() < 3:
        return list(groups), "none (the default registered fewer than 3 views)"
    refined = {}
    for im in default_rec.images.values():
        if im.has_pose:
            refined[im.name] = float(im.camera.params[0])
    cam = next(im.camera for im in default_rec.images.values() if im.has_pose)
    out, used = [], []
    for names, model, params in groups:
        f = [refined[n] for n in names if n in refined]
        if params is None and f:
            extra = ", 0" * (len(_param_names(model)) - 3)
            params = f"{float(np.median(f))!r}, {cam.width / 2.0!r}, {cam.height / 2.0!r}{extra}"
            used.append(f"{np.median(f):.0f} px, refined on {len(f)} views")
        out.append((names, model, params))
    return out, "; ".join(used) if used else "the default's"


def _param_names(model: str) -> tuple:
    from reconstruct.camera_files import CAMERA_MODELS

    return CAMERA_MODELS[model]


def _extract_strong(db: Path, image_dir, cameras, opts: ColmapOptions,
                    esc: EscalationOptions, *, affine: bool, dsp: bool) -> None:
    import pycolmap

    db.unlink(missing_ok=True)
    pycolmap.set_random_seed(int(opts.seed))
    ex = pycolmap.FeatureExtractionOptions()
    ex.num_threads = opts.num_threads
    ex.sift.max_num_features = max(esc.max_features, opts.max_features)
    ex.sift.peak_threshold = esc.peak_threshold
    ex.sift.estimate_affine_shape = affine
    ex.sift.domain_size_pooling = dsp
    _extract_cameras(db, image_dir, cameras, ex)


def _match_strong(db: Path, names: Sequence[str], opts: ColmapOptions,
                  esc: EscalationOptions, *, seed: int) -> None:
    import pycolmap

    matching = pycolmap.FeatureMatchingOptions()
    matching.num_threads = opts.num_threads
    matching.guided_matching = esc.guided
    verification = pycolmap.TwoViewGeometryOptions()
    verification.ransac.random_seed = int(seed)
    cpu = pycolmap.Device.cpu
    if len(names) <= esc.exhaustive_max:
        pycolmap.match_exhaustive(str(db), matching_options=matching,
                                  verification_options=verification, device=cpu)
        return
    pairs = db.parent / "ring_pairs.txt"
    pairs.write_text("".join(f"{a} {b}\n" for a, b in ring_pairs(sorted(names),
                                                                  esc.sequential_overlap)))
    pairing = pycolmap.ImportedPairingOptions()
    pairing.match_list_path = str(pairs)
    pycolmap.match_image_pairs(str(db), matching_options=matching, pairing_options=pairing,
                               verification_options=verification, device=cpu)


def _mapper_options(opts: ColmapOptions, thresholds, seed: int | None = None) -> object:
    import pycolmap

    init_inliers, init_angle, abs_inliers, abs_ratio = thresholds
    m = pycolmap.IncrementalPipelineOptions()
    m.num_threads = opts.num_threads
    seed = int(opts.seed if seed is None else seed)
    m.random_seed = seed
    m.mapper.random_seed = seed
    m.mapper.num_threads = opts.num_threads
    m.mapper.init_min_num_inliers = init_inliers
    m.mapper.init_min_tri_angle = init_angle
    m.mapper.abs_pose_min_num_inliers = abs_inliers
    m.mapper.abs_pose_min_inlier_ratio = abs_ratio
    m.ba_refine_extra_params = False
    m.mapper.abs_pose_refine_extra_params = False
    hold_intrinsics(m, opts)
    return m


def _map_relaxed(db: Path, image_dir, out: Path, opts: ColmapOptions, thresholds, *,
                 seed: int | None = None):
    """One rung of :data:`LADDER`: the mapper, then its models merged."""
    import pycolmap

    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    models = pycolmap.incremental_mapping(str(db), str(image_dir), str(out),
                                          options=_mapper_options(opts, thresholds, seed)) or {}
    step = {"step": "relaxed mapping", "thresholds": dict(zip(
        ("init_min_inliers", "init_min_tri_angle_deg", "abs_pose_min_inliers",
         "abs_pose_min_inlier_ratio"), thresholds, strict=True)),
        "models": [r.num_reg_images() for r in models.values()]}
    if not models:
        step["registered"] = 0
        return None, step
    rec = max(models.values(), key=lambda r: r.num_reg_images())
    if len(models) > 1:
        poses, base, joined = merge_models(list(models.values()))
        if joined:
            rec = _triangulate_merged(db, image_dir, out / "merged", poses, base, opts)
            step["merged"] = [{"views": n, "common": c} for n, c in joined]
    step["registered"] = rec.num_reg_images()
    return rec, step


def _triangulate_merged(db: Path, image_dir, out: Path, poses: dict, base, opts):
    """The merged poses with the base model's intrinsics, triangulated from the database
    and bundle-adjusted (focal length refined, distortion held)."""
    import pycolmap

    from reconstruct.sfm.colmap import _triangulate_known

    out.mkdir(parents=True, exist_ok=True)
    names = {im.name for im in _db_images(db)}
    rec = _triangulate_known(db, image_dir, out, {n: T for n, T in poses.items()
                                                  if n in names}, opts.num_threads)[0]
    cam_params = {c.camera_id: c.params for c in base.cameras.values()}
    for cid, cam in rec.cameras.items():
        if cid in cam_params:
            cam.params = cam_params[cid]
    rec = pycolmap.triangulate_points(rec, str(db), str(image_dir), str(out / "0"),
                                      options=pycolmap.IncrementalPipelineOptions(),
                                      refine_intrinsics=False)
    _bundle_adjust(rec)
    return rec


def remap_in_file_order(database: str | Path, image_dir, opts: ColmapOptions, work: Path, *,
                        overlap: int = ORDERED_OVERLAP) -> tuple[object, Path, dict]:
    """The mapper again on the verified pairs of views at most ``overlap`` apart in file
    order (the ring closed: :func:`ring_pairs`), the others' matches left out.

    A scene that repeats itself (a symmetric temple, a row of equal windows) gives
    verified matches between views that see *different* parts that look alike; the
    mapper may then fold the set onto itself (:mod:`reconstruct.sfm.self_check`). In a
    capture taken in order (a ring, a walk along a facade), views close in file order see
    the same part from nearby, so their matches are the least likely to be of that kind:
    COLMAP's sequential matching rests on the same assumption. Each rung of
    :data:`LADDER` is tried until every view is in; the model with the most views is
    returned with the database it used (a copy of ``database``) and what was done.
    """
    import pycolmap

    work = Path(work)
    work.mkdir(parents=True, exist_ok=True)
    db = work / "ordered.db"
    db.unlink(missing_ok=True)
    shutil.copy2(database, db)
    d = pycolmap.Database.open(str(db))
    try:
        ids = {im.name: im.image_id for im in d.read_all_images()}
        keep = {tuple(sorted((ids[a], ids[b]))) for a, b in ring_pairs(sorted(ids), overlap)}
        pairs, _ = d.read_two_view_geometries() if d.num_verified_image_pairs() else ([], [])
        dropped = 0
        for pid in pairs:
            a, b = pycolmap.pair_id_to_image_pair(pid)
            if tuple(sorted((a, b))) not in keep:
                d.delete_two_view_geometry(a, b)
                dropped += 1
    finally:
        d.close()
    best, steps = None, []
    for rung, thresholds in enumerate(LADDER):
        t = time.perf_counter()
        rec, step = _map_relaxed(db, image_dir, work / f"ordered_{rung}", opts, thresholds)
        step["seconds"] = time.perf_counter() - t
        steps.append(step)
        if rec is not None and (best is None or rec.num_reg_images() > best.num_reg_images()):
            best = rec
        if best is not None and best.num_reg_images() == len(ids):
            break
    return best, db, {"overlap": overlap, "pairs_left_out": dropped,
                      "pairs_kept": len(pairs) - dropped, "steps": steps,
                      "registered": best.num_reg_images() if best is not None else 0}


def _db_images(db: Path) -> list:
    import pycolmap

    d = pycolmap.Database.open(str(db))
    try:
        return d.read_all_images()
    finally:
        d.close()


def _relocalize(db: Path, image_dir, rec, out: Path, opts: ColmapOptions):
    """The views still out registered against ``rec`` with :data:`RELOCALIZE`'s
    permissive absolute-pose settings (the incremental mapper continued from ``rec``)."""
    import pycolmap

    shutil.rmtree(out, ignore_errors=True)
    (out / "input").mkdir(parents=True)
    rec.write(str(out / "input"))
    m = _mapper_options(opts, LADDER[-1])
    m.mapper.abs_pose_min_num_inliers, m.mapper.abs_pose_min_inlier_ratio, \
        m.mapper.abs_pose_max_error = RELOCALIZE
    m.mapper.max_reg_trials = 5
    m.multiple_models = False
    (out / "0").mkdir()
    models = pycolmap.incremental_mapping(str(db), str(image_dir), str(out / "0"),
                                          options=m, input_path=str(out / "input")) or {}
    if not models:
        return rec
    return max(models.values(), key=lambda r: r.num_reg_images())


def _bundle_adjust(rec) -> None:
    """Bundle adjustment with a Huber loss, the focal length refined, the distortion held
    and the gauge fixed by two cameras (a long lens leaves the problem ill-conditioned:
    the solver may stop at its iteration limit, having still lowered the cost)."""
    import pycolmap

    ba = pycolmap.BundleAdjustmentOptions()
    ba.refine_focal_length = True
    ba.refine_extra_params = False
    ba.ceres.loss_function_type = pycolmap.LossFunctionType.HUBER
    config = pycolmap.BundleAdjustmentConfig()
    for image_id in rec.reg_image_ids():
        config.add_image(image_id)
    config.fix_gauge(pycolmap.BundleAdjustmentGauge.TWO_CAMS_FROM_WORLD)
    pycolmap.create_default_bundle_adjuster(ba, config, rec).solve()


def refine(rec, database: Path, image_dir, work: Path, *,
           schedule_px: Sequence[float] = (32.0, 16.0, 8.0, 4.0)):
    """The second bundle adjustment: points triangulated again from every verified match
    of the registered views, then :func:`_bundle_adjust`, once per entry of
    ``schedule_px``, the largest reprojection error a point may keep (when it is created,
    merged, completed or filtered) shrinking from round to round.

    A model merged from sub-models is kinked at its joins: the matches across a join
    disagree with the merged poses by more than COLMAP's 4 px, so a triangulation at
    4 px drops them as outliers and the bundle adjustment never sees them (on the dino
    ring not one point tied view 12 to view 13 after the merge, though they share 85
    verified matches). Admitted at a generous threshold first, they pull the join
    straight; the later rounds drop what is still far off. Returns the refined model."""
    import pycolmap

    for k, px in enumerate(schedule_px):
        tri = pycolmap.IncrementalPipelineOptions()
        tri.triangulation.ignore_two_view_tracks = False
        tri.triangulation.merge_max_reproj_error = float(px)
        tri.triangulation.complete_max_reproj_error = float(px)
        # the angular thresholds of track creation follow the pixel ones (2 degrees,
        # COLMAP's default, at 4 px)
        tri.triangulation.create_max_angle_error = max(2.0, float(px) / 2.0)
        tri.triangulation.continue_max_angle_error = max(2.0, float(px) / 2.0)
        tri.mapper.filter_max_reproj_error = float(px)
        out = Path(work) / f"refine{k}"
        shutil.rmtree(out, ignore_errors=True)
        out.mkdir(parents=True)
        rec = pycolmap.triangulate_points(rec, str(database), str(image_dir), str(out),
                                          clear_points=True, options=tri,
                                          refine_intrinsics=False)
        _bundle_adjust(rec)
    return rec
