"""Ground classification: a cloth, then a progressive TIN densification; water apart.

Four steps, each after a published method:

1. **Candidates.** Only last returns reach the ground (a pulse that returned again later
   went through), so by default the others are never ground (LAStools' ``lasground`` does
   the same). **Water** is set apart: a last return inside a disc of ``water_radius``
   (15 m) whose last returns all lie within ``water_flatness`` (0.1 m) of each other lies
   on a horizontal plane tens of metres across -- a lake; forest floor, slopes and shrubs
   are never that flat, and a level clearing or forest gap is narrower (on a perfectly
   level simulated stand, a 6 m disc called a fifth of the ground water). Water is not
   ground (ASPRS class 9). Water's other cue, few returns in the near infrared, is not
   used: the lake of lidR's ``Topography.laz`` returns 0.95 of the tile's median pulse
   density (:func:`find_water`).
2. **Seeds: the cloth simulation filter** (CSF) of Zhang, Qi, Wan, Wang, Xie, Wang and Yan
   (2016), "An easy-to-use airborne LiDAR data filtering method based on cloth simulation",
   Remote Sensing 8(6), 501 (doi:10.3390/rs8060501): the cloud is turned upside down and a
   cloth of ``cloth_resolution`` dropped on it, stiff enough (``rigidness``) to bridge the
   gaps under trees and buildings; points within ``class_threshold`` of it are ground.
   The cloth drops on the cloud less its lower plane (``cloth_detrend``: a plane through
   the lowest point of every 10 m cell, reweighted towards the lower ones): a horizontal
   cloth on a steep slope hangs off it, its springs pulling the particles of the slope's
   low side up (on a 45-degree simulated stand it missed twice the ground it misses on
   the slope less its plane). It runs on one OpenMP thread: the package's loops race.
   The ``CSF`` package stops its simulation once no particle moves more than 5 mm in a
   step; a particle pulled by gravity ``0.2 time_step²`` per step while held by its settled
   neighbours sags slower than that into a deep (upside down) pit -- a hill of the real
   terrain -- and stops above it. With the paper's ``time_step`` 0.65 the cloth hung 1-4 m
   above the knolls of a real hillside (lidR's ``Topography.laz``); with 1.0 (lidR's own
   example for that file) it settles on them.
3. **Densification: Axelsson's progressive TIN** (2000, "DEM generation from laser scanner
   data using adaptive TIN models", IAPRS 33(B4), 110-117). The lowest cloth-ground point
   of every ``seed_step`` cell (5 m, LAStools ``lasground``'s step for forests and
   mountains), and those on the hull of the cloth's ground, start a triangulation. A
   candidate inside a triangle joins it when it lies within ``densify_distance`` (1.4 m)
   of the triangle's plane and is seen from the nearest of its corners at most
   ``densify_angle`` (6 deg) off that plane -- the iteration distance and angle TerraScan
   proposes by default -- or when it lies within ``densify_offset`` (0.1 m) of the plane
   whatever its angle: close to a corner the angle measures the survey's noise, not the
   terrain, and 0.1 m is the vertical accuracy (RMSEz) the USGS asks of a quality-level-2
   survey (with no such floor a simulated stand lost 13 % of its ground points, 0.4 m
   apart on a rough floor). Repeated until no point joins. The angle makes the test strict
   near ground already found (a point 0.2 m above the plane 1 m from a ground point is
   11 deg off) and lenient far from it; measured from the triangle's plane, it follows
   slopes. Two terms follow steep, rough and convex terrain (``densify_slope_gain``: the
   angle grows 0.5 degree per degree of the seeds' TIN's slope -- the seeds', fixed: the
   slope of the triangles being densified rises with every shrub point that joins, and on
   a 45-degree mountainside it let the ground climb a cliff's edge into the canopy;
   ``densify_local``: the
   angle may also be measured from the nearest corner's own plane, which follows a crest
   where the triangle's plane cuts below it). A point *below* its triangle's plane is
   held to ``densify_below`` (20 deg) instead: vegetation is never below the ground, while
   the seeds' TIN spans the hollows (a ravine, a dip) that crowns hide from most pulses,
   and the few pulses that reach their floor arrive far below that TIN and far from its
   corners: at 6 degrees they stayed out and the DTM bridged the hollow.
4. **Lower surface.** Those terms take in low vegetation too, so a ground point more than
   ``lower_offset`` (0.1 m) above a robust quadratic through its 30 nearest ground
   neighbours (Kraus and Pfeifer's asymmetric weights) -- or, where the ground itself
   strays from a quadratic, more than ``lower_spread`` (3) times the weighted RMS of
   those neighbours' residuals -- is not ground (a fixed 0.1 m took the ground's own
   microrelief, and both sides of a step, where the quadratic cannot follow it)
   (:func:`trim_above_lower_surface`), repeated on what is kept until nothing more goes
   (``lower_passes``, 3 at most): on a steep slope under shrubs the ground is seen in
   patches, and a shrub taken in whole holds itself up -- its points are each other's
   neighbours -- until its top is gone; 30 neighbours reach past it to the ground around.
   A cliff's top edge stands above the surface its foot pulls down; it is kept when it
   lies on the robust plane of its neighbours on one side and most of the other side
   lies 2 m or more below that plane (``lower_edges``).

>>> import numpy as np
>>> rng = np.random.default_rng(0)
>>> xy = rng.uniform(0, 30, (3000, 2))
>>> z = 0.1 * xy[:, 0] + np.where(rng.random(3000) < 0.3, rng.uniform(2, 15, 3000), 0.0)
>>> g = classify_ground(np.column_stack([xy, z]), options=GroundOptions(rigidness=1))
>>> inner = np.all((xy > 3) & (xy < 27), axis=1)  # the cloth's edges are less sure
>>> bool(np.all(g[inner] == (z < 0.1 * xy[:, 0] + 0.5)[inner]))
True
"""

from __future__ import annotations

import logging
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from core.config import Config, option
from core.validate import check_array

__all__ = ["GroundOptions", "classify_ground", "find_water", "densify_tin", "delaunay_2d",
           "trim_above_lower_surface"]

log = logging.getLogger(__name__)

LOWER_CERTAIN = 0.3  # metres above the robust lower surface: Kraus and Pfeifer's weight 0
LOWER_CLUSTER = 2.0  # metres: later trims only where a point's neighbours lie this close
EDGE_DIRECTIONS = 8  # the half-discs a point's sides are fitted on
# metres: a top edge is kept when most of its other side lies this far below the plane of
# the ground behind it -- a step, not the 0.3-1.1 m that vegetation stands over a bank
# (on lidR's Topography.laz, a 1-1.5 m drop kept such vegetation: its DTM 0.125 -> 0.133 m)
EDGE_DROP = 2.0
EDGE_SHARE = 0.5  # of the other side's points that must lie EDGE_DROP below the plane


@dataclass
class GroundOptions(Config):
    """Options of the ground filter (cloth, TIN densification, water)."""

    cloth_resolution: float = option(1.0, unit="m", range="(0, 50]",
                                     help="cloth grid spacing")
    rigidness: int = option(1, choices=(1, 2, 3),
                            help="cloth stiffness: 1 steep slopes, 2 terraces, 3 flat ground")
    cloth_detrend: bool = option(True, help="drop the cloth on the cloud less its lower "
                                            "plane (a robust plane through the lowest point "
                                            "of every 10 m cell): a cloth on a steep slope "
                                            "hangs off it")
    class_threshold: float = option(0.5, unit="m", range="(0, 10]",
                                    help="points this close to the cloth are ground seeds")
    slope_smooth: bool = option(True, help="post-process the cloth on steep slopes")
    iterations: int = option(500, range="[10, 5000]", help="cloth simulation steps at most")
    time_step: float = option(1.0, range="(0, 2]",
                              help="cloth simulation time step (0.65 in the CSF paper; "
                                   "smaller ones stop above high knolls)")
    last_returns: bool = option(True, help="only last returns can be ground")
    seed_step: float = option(5.0, unit="m", range="[0, 100]",
                              help="the lowest cloth ground point per cell of this size "
                                   "seeds the TIN (0: every cloth ground point)")
    densify_angle: float = option(6.0, unit="deg", range="[0, 90]",
                                  help="TIN densification: largest angle from a triangle's "
                                       "plane to a new point, seen from its nearest corner "
                                       "(0: keep the cloth's ground, no densification)")
    densify_below: float = option(20.0, unit="deg", range="[0, 90]",
                                  help="TIN densification: densify_angle for a point below "
                                       "the triangle's plane (a hollow under a canopy gap "
                                       "the seeds' TIN spans; vegetation is never below "
                                       "the ground)")
    densify_distance: float = option(1.4, unit="m", range="(0, 10]",
                                     help="TIN densification: largest distance of a new point "
                                          "to the triangle's plane")
    densify_offset: float = option(0.1, unit="m", range="[0, 1]",
                                   help="TIN densification: a point this close to a triangle's "
                                        "plane joins whatever its angle (the range noise)")
    densify_slope_gain: float = option(0.5, range="[0, 2]",
                                       help="TIN densification: degrees added to densify_angle "
                                            "per degree of the triangle's slope (0: a fixed "
                                            "angle)")
    densify_slope_rise: float = option(5.0, unit="deg", range="[0, 90]",
                                       help="TIN densification: the slope term's slope is "
                                            "the triangle's, at most this much steeper than "
                                            "the seeds' TIN under it (90: the triangle's)")
    densify_local: bool = option(True,
                                 help="TIN densification: a point also joins when within the "
                                      "angle of its nearest corner's own plane (the mean of "
                                      "that corner's triangles), so that convex terrain keeps "
                                      "its crests")
    lower_offset: float = option(0.1, unit="m", range="[0, 1]",
                                 help="after densification, a ground point more than this above "
                                      "the robust lower surface of its ground neighbours is "
                                      "not ground (low vegetation; 0: off)")
    lower_spread: float = option(3.0, range="[0, 10]",
                                 help="the lower-surface trim's offset is at least this "
                                      "many times the weighted RMS of the residuals of the "
                                      "neighbours below the surface: how far the ground "
                                      "itself strays from a quadratic there -- microrelief, "
                                      "a step's edges (0: lower_offset alone)")
    lower_neighbours: int = option(15, range="[6, 100]",
                                   help="the ground neighbours that surface (a quadratic) is "
                                        "fitted to")
    lower_radius: float = option(2.5, unit="m", range="[0, 20]",
                                 help="the lower surface's neighbours are also all those "
                                      "within this radius at the ground's mean density (60 "
                                      "at most; 0: lower_neighbours alone)")
    lower_edges: bool = option(True, help="the lower-surface trim keeps a point lying on "
                                          "the plane of its ground neighbours on one side "
                                          "of it when most of the other side lies 2 m or "
                                          "more below that plane: a cliff's top edge, "
                                          "which the points of its foot make stand out")
    lower_passes: int = option(3, range="[1, 20]",
                               help="the lower-surface trim repeated on what it kept, until "
                                    "it removes nothing, this many times at most")
    densify_passes: int = option(50, range="[1, 500]", help="densification passes at most")
    water_radius: float = option(15.0, unit="m", range="[0, 100]",
                                 help="water: a last return inside a disc of this radius whose "
                                      "last returns are all level is water, not ground: a lake "
                                      "is level over tens of metres, a clearing or forest gap "
                                      "over less (0: off)")
    water_flatness: float = option(0.1, unit="m", range="(0, 1]",
                                   help="water: the height range that counts as level")


def classify_ground(points: np.ndarray, *, options: GroundOptions | None = None,
                    last: np.ndarray | None = None, water: np.ndarray | None = None
                    ) -> np.ndarray:
    """Which points are ground.

    Parameters
    ----------
    points : (n, 3) float64
        Metres (any origin: they are shifted to their minimum before the filter).
    options : GroundOptions, optional
    last : (n,) bool, optional
        Last returns (``return_number == number_of_returns``); with
        ``options.last_returns`` the others are never ground.
    water : (n,) bool, optional
        Filled with the points found to be water (never ground).

    Returns
    -------
    (n,) bool
    """
    o = options or GroundOptions()
    p = check_array(points, "points", shape=(None, 3), min_rows=1)
    eligible = np.ones(len(p), bool)
    if last is not None and o.last_returns:
        eligible = check_array(last, "last", shape=(len(p),), dtype=bool).copy()
    if o.water_radius > 0:
        w = find_water(p, eligible, radius=o.water_radius, flatness=o.water_flatness)
        if water is not None:
            water[:] = w
        eligible &= ~w
    out = np.zeros(len(p), bool)
    idx = np.flatnonzero(eligible)
    if len(idx) < 3:
        return out
    local = p[idx] - p[idx].min(axis=0)
    if o.cloth_detrend:
        local[:, 2] -= _lower_plane(local)
    out[idx[_cloth(local, o)]] = True
    if o.densify_angle > 0 and out.sum() >= 3:
        seeds = _lowest_per_cell(p, out, o.seed_step) if o.seed_step > 0 else out
        seeds |= _hull(p, out)  # the seeds' TIN spans all of the cloth's ground
        out = densify_tin(p, seeds, eligible, angle=o.densify_angle,
                          distance=o.densify_distance, offset=o.densify_offset,
                          passes=o.densify_passes, slope_gain=o.densify_slope_gain,
                          slope_rise=o.densify_slope_rise,
                          local=o.densify_local, angle_below=o.densify_below)
        state = None
        for k in range(o.lower_passes if o.lower_offset > 0 else 0):
            # a cluster of points above the ground (a shrub's) holds itself up: each is
            # its neighbours' support; without its top the rest stands out. Later passes
            # take only what stands LOWER_CERTAIN above (where the robust weights are 0):
            # at lower_offset they would erode sparse ground's convex tops pass by pass
            if out.sum() < 7:
                break
            state = _lower_fit(p, out, min(_lower_k(p, out, o), int(out.sum()) - 1),
                               prev=state, edges=o.lower_offset if o.lower_edges else 0.0)
            base = o.lower_offset if k == 0 else max(o.lower_offset, LOWER_CERTAIN)
            trimmed = _trim(out, state["height"],
                            offset=np.maximum(base, o.lower_spread * state["spread"]),
                            reach=state["reach"], within=0.0 if k == 0 else LOWER_CLUSTER)
            if np.array_equal(trimmed, out):
                break
            out = trimmed
    return out


def _lower_plane(p: np.ndarray, cell: float = 10.0) -> np.ndarray:
    """Heights at ``p``'s points of a plane through the lowest point of every ``cell``
    square, fitted by least squares reweighted to follow the lower ones (Kraus and
    Pfeifer's asymmetric weights on the residuals' scale)."""
    low = _lowest_per_cell(p, np.ones(len(p), bool), cell)
    q = p[low]
    if len(q) < 3:
        return np.zeros(len(p))
    a = np.column_stack([np.ones(len(q)), q[:, 0], q[:, 1]])
    w = np.ones(len(q))
    for _ in range(5):
        coef = np.linalg.lstsq(a * w[:, None], q[:, 2] * w, rcond=None)[0]
        e = q[:, 2] - a @ coef
        scale = max(float(np.median(np.abs(e))), 1e-6)
        w = np.clip(2.0 - e / scale, 0.0, 1.0)  # 1 below 1 scale above, 0 from 2 up
    return coef[0] + coef[1] * p[:, 0] + coef[2] * p[:, 1]


def _cloth(local: np.ndarray, o: GroundOptions) -> np.ndarray:
    """Indices of ``local`` the cloth calls ground."""
    import CSF

    from core.io.mesh import native_output

    csf = CSF.CSF()
    csf.params.bSloopSmooth = bool(o.slope_smooth)
    csf.params.cloth_resolution = float(o.cloth_resolution)
    csf.params.rigidness = int(o.rigidness)
    csf.params.class_threshold = float(o.class_threshold)
    csf.params.interations = int(o.iterations)
    csf.params.time_step = float(o.time_step)
    csf.setPointCloud(np.ascontiguousarray(local))
    ground, rest = CSF.VecInt(), CSF.VecInt()
    said: list[str] = []
    with native_output(said, fds=(1, 2), open3d=False), _one_openmp_thread():  # progress
        csf.do_filtering(ground, rest, exportCloth=False)
    log.debug("CSF: %s", "; ".join(said))
    return np.asarray(ground, np.int64)


def _lower_k(p: np.ndarray, ground: np.ndarray, o: GroundOptions) -> int:
    """The lower surface's neighbour count: ``lower_neighbours``, or as many ground points
    as lie within ``lower_radius`` at the ground's mean density over its hull (60 at
    most) when more."""
    k = int(o.lower_neighbours)
    if o.lower_radius <= 0 or ground.sum() < 3:
        return k
    from scipy.spatial import ConvexHull, QhullError

    xy = p[ground, :2]
    try:
        area = ConvexHull(xy - xy.mean(axis=0)).volume
    except QhullError:
        return k
    return int(np.clip(len(xy) / max(area, 1e-9) * np.pi * o.lower_radius ** 2, k, 60))


@contextmanager
def _one_openmp_thread():
    """The OpenMP runtimes loaded in this process run one thread in this block.

    The ``CSF`` package's OpenMP loops race: on a loaded machine the same cloud gave
    4 007, 3 989, 4 087 and 4 010 ground points in four runs (one thread: 4 010 every
    time), and on steep slopes the cloth's ground then came and went in patches. Set
    through ``omp_set_num_threads`` of each libgomp/libomp this process has loaded (its
    own copy in the package's wheel), restored after.
    """
    import ctypes

    libs = []
    try:
        with open("/proc/self/maps") as f:
            paths = {line.split()[-1] for line in f if "omp" in line.rsplit("/", 1)[-1]
                     and ".so" in line}
    except OSError:
        paths = set()
    for path in sorted(paths):
        try:
            lib = ctypes.CDLL(path)
            before = lib.omp_get_max_threads()
            lib.omp_set_num_threads(1)
            libs.append((lib, before))
        except (OSError, AttributeError):
            continue
    try:
        yield
    finally:
        for lib, before in libs:
            lib.omp_set_num_threads(before)


def _lowest_per_cell(p: np.ndarray, mask: np.ndarray, cell: float) -> np.ndarray:
    """``mask`` kept at its lowest point in every ``cell`` x ``cell`` square."""
    idx = np.flatnonzero(mask)
    ij = np.floor((p[idx, :2] - p[idx, :2].min(axis=0)) / cell).astype(np.int64)
    key = ij[:, 0] * (int(ij[:, 1].max()) + 1) + ij[:, 1]
    order = np.lexsort((p[idx, 2], key))
    first = np.r_[True, key[order][1:] != key[order][:-1]]
    out = np.zeros(len(p), bool)
    out[idx[order[first]]] = True
    return out


def _hull(p: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """The points of ``mask`` on its horizontal convex hull."""
    from scipy.spatial import ConvexHull, QhullError

    idx = np.flatnonzero(mask)
    out = np.zeros(len(p), bool)
    try:
        out[idx[ConvexHull(p[idx, :2] - p[idx, :2].mean(axis=0)).vertices]] = True
    except QhullError:
        out[idx] = True
    return out


def densify_tin(p: np.ndarray, seeds: np.ndarray, eligible: np.ndarray, *,
                angle: float = 6.0, distance: float = 1.4, offset: float = 0.1,
                passes: int = 50, slope_gain: float = 0.0, slope_rise: float = 90.0,
                local: bool = False, angle_below: float | None = None,
                stats: dict | None = None) -> np.ndarray:
    """Axelsson's progressive TIN densification from ``seeds``.

    A point of ``eligible`` inside a triangle of the current ground joins the ground when
    its distance ``d`` to the triangle's plane is below ``distance`` and
    ``atan(|d| / r) < angle``, ``r`` the horizontal distance to the triangle's nearest
    corner, or when ``|d| < offset`` (close to a corner the angle measures the range
    noise, not the terrain); all such points join at once, then they are inserted into
    the triangulation, ``passes`` times at most or until none joins. The triangulation is
    the seeds' Delaunay kept Delaunay by insertion (Bowyer-Watson, in
    :mod:`reconstruct.lidar._kernels`), and a pass re-locates only the candidates whose
    triangle changed: a pass costs what joined, not the whole cloud (rebuilding it
    every pass took minutes on 1 ha at 15 pts/m2). With ``slope_gain`` the angle
    of a triangle sloping ``s`` degrees is ``angle + slope_gain * s`` (89 at most): a
    terrain slope term, as TerraScan's guidance ties its angles to the terrain's. ``s`` is
    at most ``slope_rise`` degrees more than the slope of the seeds' TIN under the point:
    points that join steepen their triangles, and a shrub let in by its triangle's slope
    would let in more, up a cliff's edge into the canopy. With
    ``local`` the angle test also passes when the point is within the angle of its nearest
    corner's own plane (the area-weighted mean of that corner's triangles' normals): on a
    convex crest the triangle's plane runs from the ground found so far to a seed beyond
    the crest, well below it, while the corner's plane follows the slope where the ground
    ends; a shrub stands above both.

    Parameters
    ----------
    p : (n, 3) float64
    seeds, eligible : (n,) bool
    angle : float
        Degrees.
    distance, offset : float
        Metres.
    slope_gain : float
        Degrees of angle per degree of the triangle's slope.
    slope_rise : float
        Degrees the slope term's slope may exceed the seeds' (90: unbounded).
    local : bool
    angle_below : float, optional
        Degrees: the angle for a point below its triangle's plane (``angle`` when None).
    stats : dict, optional
        Filled with the work done: ``passes``, ``walks`` (point locations), ``steps``
        (triangles the walks stepped through), ``inserted`` and ``candidates``.

    Returns
    -------
    (n,) bool
        The seeds and every point that joined.
    """
    from scipy.spatial import QhullError

    from reconstruct.lidar._kernels import densify

    g = np.asarray(seeds, bool).copy()
    elig = np.asarray(eligible, bool)
    gi = np.flatnonzero(g)
    cand = np.flatnonzero(elig & ~g)
    if len(gi) < 3 or len(cand) == 0 or passes < 1:
        return g
    # projected coordinates lose digits in Qhull; the candidates in a space-filling order,
    # so that each walk to a candidate's triangle starts near it
    pc = np.column_stack([p[:, :2] - p[:, :2].mean(axis=0), p[:, 2]])
    cand = cand[np.argsort(_morton(pc[cand, :2]), kind="stable")]
    try:
        tri = delaunay_2d(pc[gi, :2])
    except QhullError:
        return g
    loc = tri.find_simplex(pc[cand, :2], bruteforce=False).astype(np.int64)  # -1: outside
    tv = gi[tri.simplices].astype(np.int64)
    tn = tri.neighbors.astype(np.int64)
    c = pc[tv, :2]
    cw = ((c[:, 1, 0] - c[:, 0, 0]) * (c[:, 2, 1] - c[:, 0, 1])
          - (c[:, 1, 1] - c[:, 0, 1]) * (c[:, 2, 0] - c[:, 0, 0])) < 0
    tv[cw] = tv[cw][:, [0, 2, 1]]  # counter-clockwise, neighbours still opposite
    tn[cw] = tn[cw][:, [0, 2, 1]]
    # the slope term's slope is the seeds' (fixed): the current triangle's own slope fed
    # back -- a shrub that joined steepened its triangles, which let more of it in, up a
    # cliff's edge and into the canopy (a 45-degree stand: type II 12 %, DTM RMSE 12 m)
    rise = float(slope_rise) if slope_gain > 0 and slope_rise < 90 else 90.0
    work = np.zeros(4, np.int64)
    densify(pc, tv, tn, g, cand, loc, float(angle), float(distance), float(offset),
            int(passes), float(slope_gain), rise, bool(local),
            float(angle if angle_below is None else angle_below), work)
    if stats is not None:
        stats.update(passes=int(work[0]), walks=int(work[1]), steps=int(work[2]),
                     inserted=int(work[3]), candidates=len(cand))
    return g


def _morton(xy: np.ndarray) -> np.ndarray:
    """Z-order keys of ``(n, 2)`` points on a grid of 2^16 cells a side over their box."""
    lo, span = xy.min(axis=0), np.maximum(np.ptp(xy, axis=0), 1e-9)
    ij = np.minimum((xy - lo) / span * 65535, 65535).astype(np.uint64)
    key = np.zeros(len(xy), np.uint64)
    for b in range(16):
        bit = np.uint64(1 << b)
        key |= ((ij[:, 0] & bit) << np.uint64(b)) | ((ij[:, 1] & bit) << np.uint64(b + 1))
    return key


def trim_above_lower_surface(p: np.ndarray, ground: np.ndarray, *, offset: float = 0.1,
                             neighbours: int = 15, iterations: int = 4,
                             within: float = 0.0) -> np.ndarray:
    """``ground`` without the points more than ``offset`` above their neighbours' lower
    surface.

    For every ground point a quadratic ``z(dx, dy)`` is fitted to its ``neighbours``
    nearest other ground points by weighted least squares, reweighted ``iterations``
    times with the asymmetric weights of Kraus and Pfeifer's robust interpolation (1998,
    "Determination of terrain models in wooded areas with airborne laser scanner data",
    ISPRS J. 53(4), 193-203): 1 at most 0.05 m above the fit, falling linearly to 0 at
    0.3 m, so that a layer of low vegetation over the ground pulls the fit no more than
    the ground under it. A point more than ``offset`` above its fit is dropped. A
    quadratic follows the terrain's bulges and crests, which a plane through the
    neighbours cuts below (an up-spike filter with a plane eroded every convex top).

    Returns
    -------
    (n,) bool
    """
    g = np.asarray(ground, bool)
    if g.sum() < 7:
        return g.copy()
    f = _lower_fit(p, g, min(int(neighbours), int(g.sum()) - 1), iterations=iterations)
    return _trim(g, p[:, 2] - f["fit"], offset=offset, reach=f["reach"], within=within)


def _trim(ground, height, *, offset, reach, within):
    """``ground`` less its points ``height`` more than ``offset`` above their lower surface
    (with ``within``, only those whose neighbours lie within it: ``reach``)."""
    above = ground & (height > offset)
    if within > 0:  # only where the ground is dense enough for a shrub to hold k points
        above &= reach < within
    return ground & ~above


def _lower_fit(p, ground, k, *, iterations=4, prev=None, edges=0.0):
    """The robust lower surface of ``ground`` at each of its points (the quadratic of its
    ``k`` nearest other ground points, :func:`trim_above_lower_surface`).

    Returns a dict of (n,) arrays by point: ``fit`` (its height; NaN off the ground),
    ``reach`` (the distance to its k-th neighbour) and ``nb`` (n, k) its neighbours, and
    ``k``. With ``prev``, such a dict for a superset of ``ground`` and the same ``k``,
    only the points that lost a neighbour are fitted again: the others' k nearest are
    the same points, so is their fit. With ``edges`` > 0, ``height`` is the point's
    height above its fit, or, for those more than ``edges`` above it, its least
    distance to the robust plane of its neighbours on one side of it when less
    (:func:`reconstruct.lidar._kernels.edge_surface`): a cliff's or a terrace's top edge
    stands above the fit that its foot pulls down, but lies on the plane of the ground
    behind it; a shrub lies on no side's.
    """
    from scipy.spatial import cKDTree

    from reconstruct.lidar._kernels import edge_surface, lower_surface

    n = len(p)
    gi = np.flatnonzero(ground)
    xy = p[gi, :2] - p[:, :2].mean(axis=0)
    if prev is not None and prev["k"] == k:
        rows = np.flatnonzero(~np.all(ground[prev["nb"][gi]], axis=1))
        fit, reach, nb = prev["fit"].copy(), prev["reach"].copy(), prev["nb"].copy()
        spread = prev["spread"].copy()
    else:
        rows = np.arange(len(gi))
        fit, reach, nb = np.full(n, np.nan), np.full(n, np.inf), np.zeros((n, k), np.int64)
        spread = np.zeros(n)
    if len(rows):
        dist, j = cKDTree(xy).query(xy[rows], k + 1, workers=-1)  # the same on any count
        nb[gi[rows]] = gi[j[:, 1:]]  # the point itself left out
        reach[gi[rows]] = dist[:, -1]
        local = np.full(n, -1, np.int64)
        local[gi] = np.arange(len(gi))
        out = np.empty(len(gi))
        sd = np.zeros(len(gi))
        lower_surface(xy, p[gi, 2], local[nb[gi]], rows, int(iterations), LOWER_CERTAIN,
                      0.25, 1e-6, out, sd)
        fit[gi[rows]] = out[rows]
        spread[gi[rows]] = sd[rows]
    height = p[:, 2] - fit
    edge = prev["edge"].copy() if prev is not None and prev["k"] == k else np.full(n, np.nan)
    if edges > 0:  # NaN: not measured; inf: no side
        edge[gi[rows]] = np.nan  # fitted again: its sides too
        todo = np.flatnonzero((height[gi] > edges) & np.isnan(edge[gi]))
        if len(todo):
            local = np.full(n, -1, np.int64)
            local[gi] = np.arange(len(gi))
            out = np.full(len(gi), np.inf)
            edge_surface(xy, p[gi, 2], local[nb[gi]], todo, EDGE_DIRECTIONS,
                         max(6, k // 4), EDGE_DROP, EDGE_SHARE, int(iterations),
                         LOWER_CERTAIN, 0.25, 1e-6, out)
            edge[gi[todo]] = out[todo]
        height = np.minimum(height, np.nan_to_num(edge, nan=np.inf))
    return {"fit": fit, "reach": reach, "nb": nb, "k": k, "edge": edge, "height": height,
            "spread": spread}


def delaunay_2d(xy: np.ndarray):
    """``scipy.spatial.Delaunay`` of ``(n, 2)`` points, its barycentric transforms computed.

    scipy computes them (for ``find_simplex``) with a LAPACK call per triangle; OpenBLAS
    threads each call, which on a loaded machine took 66 s for 5 600 triangles instead of
    0.03 s. The 2 x 2 inverses are written out here instead (same layout: ``T[:2]`` maps
    ``x - r_2`` to the first two barycentric coordinates, ``T[2] = r_2``; NaN for flat
    triangles).
    """
    from scipy.spatial import Delaunay

    tri = Delaunay(xy)
    v = np.asarray(tri.points)[tri.simplices]  # (t, 3, 2)
    a, b = v[:, 0] - v[:, 2], v[:, 1] - v[:, 2]
    det = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    flat = np.abs(det) <= 1e-12 * np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1)
    det = np.where(flat, np.nan, det)
    t = np.empty((len(v), 3, 2))
    t[:, 0, 0], t[:, 0, 1] = b[:, 1] / det, -b[:, 0] / det
    t[:, 1, 0], t[:, 1, 1] = -a[:, 1] / det, a[:, 0] / det
    t[:, 2] = v[:, 2]
    if hasattr(tri, "_transform"):  # scipy's cache of the property (1.x)
        tri._transform = t
    return tri


def find_water(p: np.ndarray, eligible: np.ndarray, *, radius: float = 15.0,
               flatness: float = 0.1) -> np.ndarray:
    """Points of ``eligible`` inside a level disc of ``radius``: a lake's surface.

    The eligible points are binned in square cells (1 m, or ``radius / 3`` when smaller).
    A disc is the cells whose centres lie within ``radius`` of a cell's centre; it is level
    when it holds at least 3 eligible points and their heights span less than
    ``flatness``. Discs lie within the points' bounding box (beyond it the ground is
    unknown; a lake's corners at a tile's corner are missed). A point is water when its
    cell lies in a level disc -- the morphological opening of the level ground by the
    disc, so that a lake is found up to its shore while a level patch narrower than the
    disc (a clearing, a forest gap, a stream) is not. Empty cells break nothing: water
    returns few pulses, and its voids are no ground.

    Returns
    -------
    (n,) bool
    """
    from scipy import ndimage

    idx = np.flatnonzero(eligible)
    out = np.zeros(len(p), bool)
    if len(idx) < 3 or radius <= 0:
        return out
    cell = min(1.0, radius / 3)
    pad = int(np.ceil(radius / cell))
    ij = np.floor((p[idx, :2] - p[idx, :2].min(axis=0)) / cell).astype(np.int64) + pad
    shape = tuple(ij.max(axis=0) + pad + 1)
    at = (ij[:, 0], ij[:, 1])
    z = p[idx, 2]
    zmax = np.full(shape, -np.inf)
    zmin = np.full(shape, np.inf)
    count = np.zeros(shape)
    np.maximum.at(zmax, at, z)
    np.minimum.at(zmin, at, z)
    np.add.at(count, at, 1.0)
    k = np.arange(-pad, pad + 1) * cell
    disc = k[:, None] ** 2 + k[None, :] ** 2 <= radius ** 2
    top = ndimage.maximum_filter(zmax, footprint=disc, mode="constant", cval=-np.inf)
    low = ndimage.minimum_filter(zmin, footprint=disc, mode="constant", cval=np.inf)
    n = _disc_sum(count, disc)  # points per disc
    level = (n > 2.5) & (top - low < flatness)  # centres of level discs (empty ones too)
    # a disc must lie within the points' bounds: beyond them the ground is unknown, and
    # half a disc at a tile's edge would take a strip as narrow as a clearing
    ext = np.ptp(p[idx, :2], axis=0)
    for a in (0, 1):
        c = (np.arange(shape[a]) - pad + 0.5) * cell
        inside = (c >= radius - cell / 2) & (c <= ext[a] - radius + cell / 2)
        level &= inside[:, None] if a == 0 else inside[None, :]
    wet = ndimage.binary_dilation(level, structure=disc)
    out[idx[wet[at]]] = True
    return out


def _disc_sum(a: np.ndarray, disc: np.ndarray) -> np.ndarray:
    """Sum of ``a`` over the (odd-sized, symmetric) footprint ``disc`` centred on every
    cell, zero beyond ``a``: a row of the disc is an interval, summed from the rows'
    running sums -- exact, and one pass of ``a`` per disc row."""
    h = disc.shape[0] // 2
    c = np.zeros((a.shape[0] + 2 * h, a.shape[1] + 2 * h + 1))
    c[h:h + a.shape[0], h + 1:h + 1 + a.shape[1]] = a
    c = np.cumsum(c, axis=1)  # c[i, j + 1] - c[i, j - w]: a's row from j - w - h to j - h
    out = np.zeros(a.shape)
    cols = np.arange(a.shape[1]) + h
    for r in range(disc.shape[0]):
        on = np.flatnonzero(disc[r])
        if len(on) == 0:
            continue
        lo, hi = on[0] - h, on[-1] - h
        out += c[r:r + a.shape[0], cols + hi + 1] - c[r:r + a.shape[0], cols + lo]
    return out
