"""Which way is up in a reconstruction that arrives in its own frame.

A reconstruction from photographs (COLMAP, Meshroom, a phone app) or a scan from another
tool comes in the frame its software chose: up may be -y, +z or anything between. What
is built on it (plants, snow, a city) needs gravity. Two sources, in order of trust:

1. **The cameras beside the mesh.** People hold cameras upright (give or take a roll of
   a few degrees, which averages out), so the image's up, ``-y`` of an OpenCV camera, in
   the world, averaged over the views, is up. A COLMAP model (``sparse/0``), a
   nerfstudio ``transforms.json``, a Meshroom ``cameras.sfm`` or an OpenMVS ``*.mvs``
   scene next to the mesh (or in its parent folder) is read for it.
2. **The mesh itself**, without trusting its triangles' winding or normals (tools write
   either winding). Candidate axes are the directions that make the most area level
   (within ``ground_deg``, facing either way) and walls (within ``wall_deg`` of
   perpendicular): the best few, at least 30 degrees apart, each refined by its level
   faces' principal normal. Each candidate, with each sign, is then scored by cues that
   hold for real scenes: the ground is the extreme of the scene along -up (level area
   in the lowest quarter of the heights, little in the highest: things stand on it);
   walls rise from it (the level area lies at the walls' lower end; roofs at their
   upper end); the heights are skewed up (a tie-break); and camera centres, when a file
   gives them, lie above the ground. Area alone cannot tell a facade with a strip of
   ground from a strip of ground with a facade (the wall is the largest plane): the
   walls-rise cue does. ``decision`` in the estimate names the cue that separated the
   winner from the runner-up, the margin (1 - runner-up / winner) as the confidence,
   and the runner-up; a close call (under :data:`CLOSE_MARGIN`) is logged and makes
   ``scanamp amplify`` warn naming ``--up``.
3. **How the object would rest**, for a mesh with no ground (a scanned statue, the
   dragon): the stable faces of its convex hull, the face the centre of mass projects
   into, each with its quasi-static probability (the share of drop directions whose
   descent on the hull's support function ends on it: Moll & Erdmann's quasi-static
   pose distribution; Fu et al. 2008 use the same stability for upright orientation),
   over the share of the surface hugging the floor in that pose (an object stands on
   its base or its feet; the side it stood on was not seen when it was captured). It
   adds to the structural score with a weight that vanishes as the level
   share at one end grows, so a scene with a ground is decided by its ground. A scene
   can bury its ground's area under plants (a canopy seen from above, a stand's leaves)
   but not its cover: seen along up, a ground spans the footprint under what stands on
   it. A pose whose top end has level surface spanning the footprint (more than its
   bottom end) stands a scene on its head and does not count: a canopy of crowns
   touches a floor at a few tops only, which the resting cue alone would favour. The
   centre of mass of an open capture whose signed volume is spurious (outside its hull)
   is the surface's centroid.

:func:`orient_winding` then turns the triangles so what is seen from the sky faces up, so
steps that read normals (plants on gentle slopes, snow) work on a mesh written with the
other winding.

:func:`estimate_up` tries them in that order unless ``up`` is given.

>>> import numpy as np
>>> from core.meshes import mesh_arrays
>>> import open3d as o3d
>>> box = o3d.geometry.TriangleMesh.create_box(4.0, 4.0, 0.2)   # a slab: its top is ground
>>> v, f = mesh_arrays(box)
>>> est = up_from_mesh(v @ np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]]).T, f)  # z -> -y
>>> (np.round(est.up, 6) + 0.0).tolist(), est.source
([0.0, -1.0, 0.0], 'mesh')
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from core.validate import check_unit_vector

__all__ = ["UpEstimate", "RestPose", "estimate_up", "up_from_cameras", "up_from_mesh",
           "rest_poses", "find_camera_model", "is_close", "orient_winding", "CLOSE_MARGIN",
           "CUES", "BAND"]

log = logging.getLogger(__name__)


#: a runner-up scoring within this fraction of the winner makes the call a close one
CLOSE_MARGIN = 0.25
#: the share of the scene's height, at either end, where the ground is looked for
BAND = 0.25
#: cameras whose image ups average to a vector at least this long give up by themselves
CAMERA_AGREEMENT = 0.5


def is_close(up: dict) -> bool:
    """Whether an up estimate (:meth:`UpEstimate.to_dict`, as report.json keeps it) came
    from the mesh with a runner-up within :data:`CLOSE_MARGIN` of the winner."""
    d = up.get("decision") or {}
    return bool(up.get("source") == "mesh" and d.get("runner_up")
                and d.get("margin", 1.0) < CLOSE_MARGIN)


@dataclass(frozen=True)
class UpEstimate:
    """A unit ``up`` vector, where it came from (``given``, ``cameras``, ``mesh``), and how
    well it is supported: for cameras the length of the mean of their unit up vectors (1:
    all agree), for the mesh the fraction of the area that is ground or wall."""

    up: np.ndarray
    source: str
    support: float
    detail: str = ""
    decision: dict | None = None

    @property
    def close(self) -> bool:
        """From the mesh, and the runner-up scored within :data:`CLOSE_MARGIN` of the
        winner: worth a look (``--up`` overrides)."""
        return is_close(self.to_dict())

    def to_dict(self) -> dict:
        out = {"up": [float(x) for x in self.up], "source": self.source,
               "support": float(self.support), "detail": self.detail}
        if self.decision is not None:
            out["decision"] = self.decision
        return out


def up_from_cameras(world_from_cams) -> UpEstimate:
    """Up as the mean image-up (``-y`` of each OpenCV camera) in the world."""
    ups = np.array([-np.asarray(T, np.float64)[:3, 1] for T in world_from_cams])
    if len(ups) == 0:
        raise ValueError("cameras: expected at least one camera")
    mean = ups.mean(axis=0)
    return UpEstimate(check_unit_vector(mean, "up"), "cameras", float(np.linalg.norm(mean)),
                      f"{len(ups)} cameras")


def _fibonacci(n: int) -> np.ndarray:
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    r = np.sqrt(1.0 - z * z)
    phi = np.pi * (3.0 - np.sqrt(5.0)) * k
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def _faces(vertices, triangles):
    """Unit normals, areas, and the lowest and highest vertex of each non-degenerate face."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(triangles, np.int64)
    if len(f) == 0:
        raise ValueError("mesh: expected triangles, got none")
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    keep = area > 0
    return cross[keep] / (2.0 * area[keep, None]), area[keep], v[f[keep]], v


def _candidate_axes(n, a, cos_g, sin_w, directions: int, count: int = 3,
                    apart_deg: float = 30.0) -> list:
    """The best axes by ground + half walls, at least ``apart_deg`` apart (each a local
    best: the true up and the walls' normals of a facade), each refined by its ground
    faces' principal normal."""
    total = float(a.sum())
    cand = _fibonacci(directions)
    cand = cand[cand[:, 2] >= 0]  # an axis; the sign is decided by the structure
    # score on at most 20 000 faces drawn by area (a fixed draw: the same mesh, the same
    # answer); the refinement uses every face
    ns, ws = n, a
    if len(n) > 20_000:
        pick = np.random.default_rng(0).choice(len(n), 20_000, p=a / total)
        ns, ws = n[pick], np.full(20_000, total / 20_000)
    score = np.zeros(len(cand))
    for i in range(0, len(cand), 256):  # (faces x 256) dot products at a time
        d = np.abs(ns @ cand[i:i + 256].T)
        score[i:i + 256] = ws @ (d > cos_g) + 0.5 * (ws @ (d < sin_w))
    axes = []
    for i in np.argsort(-score):
        if score[i] < 0.3 * score.max() or len(axes) == count:
            break
        if all(abs(cand[i] @ b) < np.cos(np.radians(apart_deg)) for b in axes):
            axes.append(cand[i])
    out = []
    for axis in axes:
        for _ in range(3):  # refine: the principal direction of the ground faces' normals
            ground = np.abs(n @ axis) > cos_g
            if not ground.any():
                break
            w, vec = np.linalg.eigh((n[ground] * a[ground, None]).T @ n[ground])
            axis = vec[:, -1] * np.sign(vec[:, -1] @ axis or 1.0)
        out.append(axis)
    return out


def _area_draw(area: np.ndarray, n: int = 20_000) -> tuple[np.ndarray, np.ndarray]:
    """``n`` points spread over faces by area (a fixed draw): each one's face and its
    barycentric weights ``(n, 3)``."""
    rng = np.random.default_rng(0)
    pick = rng.choice(len(area), n, p=area / area.sum())
    r1, r2 = np.sqrt(rng.random(n)), rng.random(n)
    return pick, np.stack([1 - r1, r1 * (1 - r2), r1 * r2], axis=1)


def _area_samples(heights: np.ndarray, area: np.ndarray, n: int = 20_000) -> np.ndarray:
    """Heights of ``n`` points spread over faces by area (a fixed draw), from each face's
    vertex heights ``(faces, 3)``: where a face's area lies, not only its corners."""
    pick, w = _area_draw(area, n)
    return (heights[pick] * w).sum(axis=1)


def _structure(up, n, a, tri, cos_g, sin_w) -> dict:
    """How well ``up`` (signed) explains the mesh as ground, walls and roofs, from the
    faces' orientation up to sign and their heights only: a reconstruction's winding (and
    so its normals) may point either way.

    ``area``: level faces plus half the walls, over the whole area. ``base``: the share of
    the level area lying at the walls' lower end (within 2 % of the height range of the
    lowest 1 % of the walls' area): walls stand on the ground. ``top``: the share at their
    upper end (roofs). ``low`` and ``high``: the shares of the whole area that are level
    and lie in the lowest and highest :data:`BAND` of the scene's height: the ground is
    the extreme of the scene along -up, and things stand on it. The score is
    ``area x (0.1 + base + top / 2 + max(low - high, 0) / 4)``, times 1.01 when the
    heights are skewed up (0.99 when down): the tie-break of a bare mesh."""
    d = n @ up
    h = tri @ up  # (faces, 3) vertex heights
    span = float(h.max() - h.min())
    tol = 0.02 * span
    total = float(a.sum())
    ground = np.abs(d) > cos_g
    walls = np.abs(d) < sin_w
    out = {"ground": float(a[ground].sum() / total), "walls": float(a[walls].sum() / total),
           "base": 0.0, "top": 0.0, "low": 0.0, "high": 0.0}
    out["area"] = out["ground"] + 0.5 * out["walls"]
    if ground.any():
        gh, ga = h[ground].mean(axis=1), a[ground]
        out["low"] = float(ga[gh <= h.min() + BAND * span].sum() / total)
        out["high"] = float(ga[gh >= h.max() - BAND * span].sum() / total)
        if walls.any():
            wh = _area_samples(h[walls], a[walls])
            w_lo, w_hi = np.quantile(wh, 0.01), np.quantile(wh, 0.99)
            out["base"] = float(ga[np.abs(gh - w_lo) <= tol].sum() / ga.sum())
            out["top"] = float(ga[np.abs(gh - w_hi) <= tol].sum() / ga.sum())
    hc = h.mean(axis=1)
    hc = hc - np.average(hc, weights=a)
    out["skew"] = float(np.average(hc ** 3, weights=a))
    out["score"] = out["area"] * (0.1 + out["base"] + 0.5 * out["top"]
                                  + 0.25 * max(out["low"] - out["high"], 0.0)) \
        * (1.0 + 0.01 * np.sign(out["skew"]))
    return out


#: the share of the extent above the support plane where a resting pose's contact is measured
CONTACT_BAND = 0.01
#: the weight of the resting pose against the structural score, on a mesh with no ground
REST_WEIGHT = 1.0
#: a level share this large at one end of a candidate axis (``low - high``) is a ground:
#: the resting pose then does not count (a terrain does not rest like an object)
GROUND_SHARE = 0.3
#: a resting pose whose top end has level surface covering this much more of the
#: footprint than its bottom end (``cover_high - cover_low``) stands a scene on its head:
#: its ground, spanning the scene under what stands on it, is up; the pose does not count
GROUND_COVER = 0.5
#: the cells across the footprint's longer side where the ground's cover is counted
FOOTPRINT_CELLS = 48
#: a mesh whose convex hull is thinner than this share of its extent is a sheet, not an
#: object that rests
SHEET = 0.05
#: a candidate up within this angle of a resting pose's up takes that pose's share
REST_DEG = 10.0


@dataclass(frozen=True)
class RestPose:
    """A stable pose of an object on a floor: ``up`` (the outward normal of the convex
    hull face it rests on, negated), its quasi-static ``probability``, the ``contact``
    (share of the surface hugging the floor, a flat base excepted) and its ``share`` of
    the resting cue. An object stands on its base or its feet, and the side it stood on
    was not seen when it was captured; lying on its flank, much of its surface hugs the
    floor: the share favours likely poses that touch the floor little."""

    up: np.ndarray
    probability: float
    contact: float
    share: float


def _centre_of_mass(tri: np.ndarray, a: np.ndarray) -> np.ndarray:
    """The centre of mass of the solid when the mesh closes one (the signed tetrahedra
    about the area centroid give a volume of either sign, whatever the winding, and the
    centroid is their ratio), else the area centroid of the surface (a merged scan)."""
    c0 = _area_centroid(tri, a)
    t = tri - c0
    vol = np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])) / 6.0
    total = float(vol.sum())
    # a closed mesh: the signed volumes add up to nearly the sum of their sizes' share
    if abs(total) > 0.05 * float(np.abs(vol).sum()):
        return c0 + ((t.sum(axis=1) / 4.0) * vol[:, None]).sum(axis=0) / total
    return c0


def _area_centroid(tri: np.ndarray, a: np.ndarray) -> np.ndarray:
    """The centroid of the surface, by area."""
    return (tri.mean(axis=1) * a[:, None]).sum(axis=0) / a.sum()


def rest_poses(vertices: np.ndarray, triangles: np.ndarray, *,
               directions: int = 4000) -> list[RestPose]:
    """The stable resting poses of a mesh as an object on a floor, most likely first
    (:class:`RestPose`); empty when it spans no volume or its convex hull is thinner
    than :data:`SHEET` of its extent (a sheet: an open terrain, a wall). The winding does
    not matter."""
    n, a, tri, v = _faces(vertices, triangles)
    return _rest_poses(_used(v, triangles), n, a, tri, directions)


def _used(v, triangles) -> np.ndarray:
    """The vertices the triangles use (a file may hold others: the hull is of the mesh)."""
    return v[np.unique(np.asarray(triangles, np.int64))]


def _rest_poses(v, n, a, tri, directions: int = 4000) -> list[RestPose]:
    """The stable resting poses (the convex hull faces the centre of mass projects into),
    each with its quasi-static probability: the share of the directions of a drop (a
    Fibonacci sphere of ``directions``) that land on it, the ray from the centre of mass
    leaving the hull through it, or on an unstable face that rolls to it (steepest
    descent of the hull's support function about the centre of mass).
    Each pose's ``contact`` is the share of the surface within :data:`CONTACT_BAND` of the
    extent from its support plane and facing it (within 45 degrees, either way: walls
    rising from the floor do not hug it), flat faces lying on the plane excepted (a
    base); its
    ``share`` is probability over contact (at least 1e-3), normalised to sum to 1."""
    from scipy.spatial import ConvexHull, QhullError, cKDTree

    com = _centre_of_mass(tri, a)
    try:
        hull = ConvexHull(v)
    except (QhullError, ValueError):
        return []
    hv = v[hull.vertices] - com
    nrm, off = hull.equations[:, :3], hull.equations[:, 3]
    depth = -(nrm @ com + off)  # the centre of mass's height above each face's plane
    if depth.min() <= 0:
        # an open mesh (a capture without its undersides) can pass for a closed one with
        # a spurious volume whose centroid lies outside it: the surface's own centroid
        com = _area_centroid(tri, a)
        hv = v[hull.vertices] - com
        depth = -(nrm @ com + off)
    if depth.min() <= 0:  # the centre of mass on or outside the hull: a sheet
        return []
    # the faces the centre of mass projects into: each a stable pose
    proj = com - (nrm @ com + off)[:, None] * nrm
    p3 = v[hull.simplices]
    sides = np.stack([np.einsum("ij,ij->i", np.cross(p3[:, (k + 1) % 3] - p3[:, k],
                                                     proj - p3[:, k]), nrm)
                      for k in range(3)], axis=1)
    stable = np.nonzero(np.all(sides >= 0, axis=1) | np.all(sides <= 0, axis=1))[0]
    if len(stable) == 0:
        return []
    d = _fibonacci(directions)
    # the face a drop in each direction lands on: the hull face the ray from the centre
    # of mass along it leaves through (the radial projection of the hull on the sphere)
    hit = np.empty(len(d), np.int64)
    for i in range(0, len(d), 256):
        c = d[i:i + 256] @ nrm.T
        t = np.where(c > 1e-12, depth / np.maximum(c, 1e-12), np.inf)
        hit[i:i + 256] = np.argmin(t, axis=1)
    # an unstable face rolls on: steepest descent of the support function (the height of
    # the centre of mass over the floor) from its normal, on the sphere of directions
    proj_d = [d[i:i + 256] @ hv.T for i in range(0, len(d), 256)]
    h = np.concatenate([p.max(axis=1) for p in proj_d])
    width = h - np.concatenate([p.min(axis=1) for p in proj_d])
    if width.min() < SHEET * float(np.linalg.norm(v.max(axis=0) - v.min(axis=0))):
        return []  # a sheet (an open terrain, a wall) does not rest like an object
    tree = cKDTree(d)
    _, nb = tree.query(d, k=7)
    down = nb[np.arange(len(d)), np.argmin(h[nb], axis=1)]
    while True:
        nxt = down[down]
        if np.array_equal(nxt, down):
            break
        down = nxt
    is_stable = np.zeros(len(nrm), bool)
    is_stable[stable] = True
    faces, counts = np.unique(hit, return_counts=True)
    _, start = tree.query(nrm[faces])
    prob = {}
    for face, count, s0 in zip(faces, counts, start, strict=True):
        if not is_stable[face]:
            face = int(stable[np.argmax(nrm[stable] @ d[down[s0]])])
        prob[int(face)] = prob.get(int(face), 0.0) + count / len(d)
    extent = float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
    pick, w = _area_draw(a)  # the surface as points spread over the faces by area
    corners, normals = tri[pick] - com, n[pick]
    pts = (corners * w[:, :, None]).sum(axis=1)
    band = CONTACT_BAND * extent
    poses = []
    for face, p in prob.items():
        if p < 0.01:  # a pose hardly ever reached
            continue
        height = depth[face] - pts @ nrm[face]  # above the support plane
        facing = np.abs(normals @ nrm[face])
        base = (depth[face] - (corners @ nrm[face]).min(axis=1) < 0.25 * band) \
            & (facing > np.cos(np.radians(5.0)))
        near = (height < band) & (facing > np.sqrt(0.5)) & ~base
        poses.append((-nrm[face], p, float(near.mean())))
    s = sum(p / max(c, 1e-3) for _, p, c in poses)
    return sorted((RestPose(u, p, c, p / max(c, 1e-3) / s) for u, p, c in poses),
                  key=lambda r: -r.share)


#: what each structural cue means, for the report
CUES = {"area": "ground and wall area (the largest level part is the ground)",
        "base": "the ground lies at the walls' lower end",
        "top": "roofs lie at the walls' upper end",
        "low": "the ground is the scene's extreme along -up (things stand on it)",
        "cameras": "the cameras are above the ground",
        "rest": "the object rests on a stable face of its convex hull (quasi-static "
                "probability), touching the floor little"}


def _points_on(faces: np.ndarray, a: np.ndarray, tri: np.ndarray, n: int = 20_000) -> np.ndarray:
    """``n`` points spread by area over the faces selected by ``faces`` (a mask), a fixed
    draw; none when the selection has no area."""
    if not faces.any() or float(a[faces].sum()) <= 0:
        return np.empty((0, 3))
    pick, w = _area_draw(a[faces], n)
    return (tri[faces][pick] * w[:, :, None]).sum(axis=1)


def _footprint_ground(up, n, a, tri, cos_g, everything=None) -> tuple[float, float]:
    """The shares of the scene's footprint (the surface seen along ``up``, in cells of
    1 / :data:`FOOTPRINT_CELLS` of its longer side) covered by level surface in the lowest
    and in the highest :data:`BAND` of its height. A ground spans the scene under what
    stands on it: seen along up it covers most of the footprint at the bottom, however
    much area trees or furniture add above it. An object's flat side covers part of it,
    and the tops of things at the other end leave the gaps between them.

    Each of the three (the footprint, the level surface at either end) is drawn with its
    own points, so a cover measures where the surface lies and not how much of the area
    it is: a ground that is a tenth of the area under a dense canopy covers its gaps as
    fully as a bare one. The cells are laid along the footprint's principal axes, centred
    on its middle, so the measure turns with the scene and not with its frame.
    ``everything``: the footprint's points when drawn already (:func:`_points_on` over
    every face)."""
    h = tri @ up
    lo_h, span = float(h.min()), float(np.ptp(h))
    if span <= 0:
        return 0.0, 0.0
    hc = h.mean(axis=1)
    level = np.abs(n @ up) > cos_g
    if everything is None:
        everything = _points_on(np.ones(len(a), bool), a, tri, 40_000)
    # the plane across up, its axes the footprint's principal ones (a fixed frame of the
    # scene, whatever frame the file is in)
    flat = everything - np.outer(everything @ up, up)
    mid = flat.mean(axis=0)
    _, vec = np.linalg.eigh((flat - mid).T @ (flat - mid))
    plane = vec[:, 1:]  # the two largest: the smallest is along up
    xy = (flat - mid) @ plane
    size = float(np.abs(xy).max()) * 2.0
    if size <= 0:
        return 0.0, 0.0
    cell = size / FOOTPRINT_CELLS

    def cells(pts):  # each point's cell as one integer (the footprint is 48 cells across)
        ij = np.floor((pts - np.outer(pts @ up, up) - mid) @ plane / cell).astype(np.int64) \
            + 4 * FOOTPRINT_CELLS
        return np.unique(ij[:, 0] * 8 * FOOTPRINT_CELLS + ij[:, 1])

    foot = cells(everything)
    low = np.intersect1d(cells(_points_on(level & (hc <= lo_h + BAND * span), a, tri)), foot)
    high = np.intersect1d(cells(_points_on(level & (hc >= lo_h + (1 - BAND) * span), a, tri)),
                          foot)
    return len(low) / len(foot), len(high) / len(foot)


def _head_ground(up, n, a, tri, cos_g, everything=None) -> float:
    """How much more of the footprint the level surface at the top end of ``up`` covers
    than that at its bottom end (:func:`_footprint_ground`), 0 when less: a ground seen
    overhead, the scene upside down."""
    low, high = _footprint_ground(up, n, a, tri, cos_g, everything)
    return max(high - low, 0.0)


def _rest_weight(scored, rest, n, a, tri, cos_g) -> tuple[float, list[RestPose]]:
    """The resting cue's weight and the poses with their shares as they count. The
    resting pose counts where the mesh has no ground (a level share at one end of a
    candidate axis in ``scored``), and not for a pose that stands the scene on its head:
    a ground seen spanning the footprint at the pose's top end (plants, furniture and
    walls can outweigh its area, not its cover)."""
    ground = max(st["low"] - st["high"] for _, st in scored)
    rest_w = REST_WEIGHT * max(1.0 - ground / GROUND_SHARE, 0.0)
    everything = _points_on(np.ones(len(a), bool), a, tri, 40_000)
    return rest_w, [RestPose(r.up, r.probability, r.contact, r.share * max(
        1.0 - _head_ground(r.up, n, a, tri, cos_g, everything) / GROUND_COVER, 0.0))
        for r in rest]


def _cameras_above(up, tri, a, centres) -> float:
    """Share of the camera centres above the ground (the lowest 5 % of the area)."""
    h = _area_samples(tri @ up, a)
    return float(np.mean(np.asarray(centres) @ up > np.quantile(h, 0.05)))


def up_from_mesh(vertices: np.ndarray, triangles: np.ndarray, *, ground_deg: float = 20.0,
                 wall_deg: float = 10.0, directions: int = 4000,
                 centres: np.ndarray | None = None) -> UpEstimate:
    """Up from the mesh (and camera centres ``(k, 3)`` when given): the best candidate axes
    (module docstring), each with both signs, and the likeliest resting poses
    (:func:`rest_poses`), scored by structure (:func:`_structure`) plus the resting
    pose's share times :data:`REST_WEIGHT` ``(1 - ground / GROUND_SHARE)`` (``ground`` the
    largest level share at one end less that at the other, over the candidates: the pose
    counts on an object, not on a scene with a ground; each pose's share is scaled by
    ``1 - head / GROUND_COVER``, ``head`` the footprint its top end's level surface covers
    beyond its bottom end's: a ground overhead), times ``0.1 + `` the share of
    the cameras above the ground when given; ``decision`` names the
    cue that separated the winner from the runner-up, the confidence (the margin) and the
    runner-up. A close call is logged as a warning naming ``--up``."""
    n, a, tri, v = _faces(vertices, triangles)
    cos_g, sin_w = np.cos(np.radians(ground_deg)), np.sin(np.radians(wall_deg))
    if centres is not None:
        centres = np.asarray(centres, np.float64).reshape(-1, 3)
    rest = _rest_poses(_used(v, triangles), n, a, tri)
    near = np.cos(np.radians(REST_DEG))
    axes = [sign * axis for axis in _candidate_axes(n, a, cos_g, sin_w, directions)
            for sign in (1.0, -1.0)]
    resting = [r.up for r in rest[:3] if r.share >= 0.05]
    scored = [(u, _structure(u, n, a, tri, cos_g, sin_w)) for u in axes + resting]
    rest_w, rest = _rest_weight(scored, rest, n, a, tri, cos_g)
    # each candidate once (two axes may refine to one, a resting pose may lie near an
    # axis): on an object the resting pose's own face normal is kept, on a scene the axis
    # refined by its ground
    if rest_w >= 0.5 * REST_WEIGHT:
        scored = scored[len(axes):] + scored[:len(axes)]
    ups, structure = [], []
    for u, st in scored:
        if all(u @ w <= near for w in ups):
            ups.append(u)
            structure.append(st)
    options = []
    for u, st in zip(ups, structure, strict=True):
        st["rest"] = max([r.share for r in rest if r.up @ u > near], default=0.0)
        st["score"] += rest_w * st["rest"]
        st["cameras"] = None
        if centres is not None and len(centres):
            st["cameras"] = _cameras_above(u, tri, a, centres)
            st["score"] *= 0.1 + st["cameras"]
        options.append((u, st))
    options.sort(key=lambda o: -o[1]["score"])
    up, best = options[0]
    decision = {"cue": "only candidate", "margin": 1.0, "runner_up": None}
    if len(options) > 1:
        other_up, other = options[1]
        # each cue's share of the winner's lead: its score with that cue set to the
        # runner-up's value, taken from the winner's
        weight = best["base"] + 0.5 * best["top"]

        def ext(o):
            return 0.25 * max(o["low"] - o["high"], 0.0)

        weight += ext(best)
        lead = {"area": (best["area"] - other["area"]) * weight,
                "base": best["area"] * (best["base"] - other["base"]),
                "top": best["area"] * 0.5 * (best["top"] - other["top"]),
                "low": best["area"] * (ext(best) - ext(other))}
        lead["rest"] = rest_w * (best["rest"] - other["rest"])
        if best["cameras"] is not None:
            lead["cameras"] = best["area"] * weight * (best["cameras"] - other["cameras"])
        cue = max(lead, key=lead.get)
        decision = {"cue": CUES[cue],
                    "margin": float(1.0 - other["score"] / max(best["score"], 1e-300)),
                    "runner_up": {"up": [float(x) for x in other_up],
                                  "angle_deg": float(np.degrees(np.arccos(np.clip(
                                      up @ other_up, -1.0, 1.0)))),
                                  "score": other["score"]}}
    decision["confidence"] = decision["margin"]
    if decision["runner_up"] is not None and decision["margin"] < CLOSE_MARGIN:
        alt = ",".join(f"{x:.3f}" for x in decision["runner_up"]["up"])
        log.warning("up from the mesh: low confidence %.2f (runner-up %s, %.0f degrees away, "
                    "scored within %.0f %%); if the result is wrong, set --up %s",
                    decision["margin"], alt, decision["runner_up"]["angle_deg"],
                    100 * decision["margin"], alt)
    return UpEstimate(up, "mesh", best["ground"] + best["walls"],
                      f"ground {best['ground']:.2f} and walls {best['walls']:.2f} of the "
                      f"area; {best['base']:.2f} of the ground at the walls' foot, "
                      f"{best['low']:.2f} at the scene's bottom; resting pose share "
                      f"{best['rest']:.2f} (weight {rest_w:.2f}); decided by "
                      f"{decision['cue']} (margin {decision['margin']:.2f})",
                      decision)


def orient_winding(vertices: np.ndarray, triangles: np.ndarray, up) -> tuple[np.ndarray, bool]:
    """``triangles`` wound so what is seen from the sky faces ``up``: reversed (every one)
    when the level faces with nothing above them (a ray along ``up`` from each leaves the
    mesh: open ground, roofs, the tops of things) face down by area; and whether they
    were. Undersides and overhangs, which face down, have the mesh above them and do not
    vote."""
    import open3d as o3d

    u = check_unit_vector(up, "up")
    v = np.asarray(vertices, np.float64)
    f = np.asarray(triangles, np.int64)
    n, a, tri, _ = _faces(v, f)
    d = n @ u
    level = np.nonzero(np.abs(d) > np.cos(np.radians(20.0)))[0]
    if len(level) == 0:
        return f, False
    tm = o3d.t.geometry.TriangleMesh()
    tm.vertex.positions = o3d.core.Tensor(v.astype(np.float32))
    tm.triangle.indices = o3d.core.Tensor(f.astype(np.int32))
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(tm)
    eps = 1e-4 * float(np.linalg.norm(v.max(0) - v.min(0)))
    start = tri[level].mean(axis=1) + eps * u
    rays = np.hstack([start, np.tile(u, (len(level), 1))]).astype(np.float32)
    open_sky = ~np.isfinite(scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy())
    sky = level[open_sky]
    if len(sky) and float((a[sky] * np.sign(d[sky])).sum()) < 0:
        return f[:, ::-1].copy(), True
    return f, False


def find_camera_model(mesh_path: str | os.PathLike) -> Path | None:
    """A camera model beside the mesh, in the mesh's folder or its parent: ``transforms.json``,
    ``sparse/0`` or ``sparse`` (COLMAP), ``cameras.sfm`` (Meshroom), or an OpenMVS scene
    ``*.mvs`` (the first by name); None when there is none.

    ``transforms.json`` comes first: ``scanamp reconstruct sfm`` writes it in the mesh's
    frame, while ``sparse/`` stays in COLMAP's own frame when the mesh was aligned to a
    capture's ground truth."""
    here = Path(mesh_path).resolve().parent
    for folder in (here, here.parent):
        for cand in (folder / "transforms.json", folder / "sparse" / "0", folder / "sparse",
                     folder / "cameras.sfm", *sorted(folder.glob("*.mvs"))):
            if cand.is_file() or (cand.is_dir() and any(
                    (cand / n).is_file() for n in ("cameras.bin", "cameras.txt"))):
                return cand
    return None


def estimate_up(vertices: np.ndarray, triangles: np.ndarray, *, up=None,
                cameras: str | os.PathLike | None = None) -> UpEstimate:
    """Up of a mesh: ``up`` when given, else from the camera model at ``cameras`` (a COLMAP
    model, transforms.json, a Meshroom cameras.sfm or an OpenMVS .mvs:
    :func:`reconstruct.camera_files.read_cameras`), else from the mesh. A camera model
    that cannot be read is logged and the mesh used."""
    if up is not None:
        return UpEstimate(check_unit_vector(up, "up"), "given", 1.0)
    if cameras is not None:
        from core.validate import InputError
        from reconstruct.camera_files import read_cameras

        try:
            cams = read_cameras(cameras)
            poses = [c.world_from_cam for c in cams.values()]
            est = up_from_cameras(poses)
        except (InputError, ValueError) as exc:
            log.warning("up: the cameras in %s cannot be read (%s); using the mesh",
                        cameras, exc)
        else:
            if est.support >= CAMERA_AGREEMENT:
                return UpEstimate(est.up, est.source, est.support,
                                  f"{est.detail} in {cameras}")
            # the images' ups disagree (a rolled or spherical capture): the mesh decides,
            # with the camera centres above its ground as one more cue
            log.info("up: the cameras in %s disagree on up (%.2f); using the mesh and "
                     "their centres", cameras, est.support)
            return up_from_mesh(vertices, triangles,
                                centres=[np.asarray(T)[:3, 3] for T in poses])
    return up_from_mesh(vertices, triangles)
