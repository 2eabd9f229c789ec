"""Sweep: vines (tubes) along noise-driven walks on a surface.

Each vine starts at a point drawn uniformly by area (where the slope rule allows), heads
in a random tangent direction and walks in steps of ``step`` metres; at every step it
turns about the surface normal by ``wander * N(p)`` (``N`` an fBm field, so neighbouring
vines bend alike) and the new point is projected back onto the surface (closest point),
so the walk follows the surface like a discrete geodesic with noise-driven curvature.
The path, lifted by the tube radius along the normal, is swept into a tapering
generalized cylinder (:func:`procgen.sweeps.sweep`).

>>> import numpy as np, open3d as o3d
>>> ball = o3d.geometry.TriangleMesh.create_sphere(1.0, 20)
>>> res = grow_vines(ball, rng=np.random.default_rng(0), count=3, length=1.0, step=0.05,
...                  radius=0.01)
>>> len(res.paths), bool(len(res.mesh.triangles) > 0)
(3, True)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.meshes import face_normals, make_mesh
from core.sampling import sample_surface
from core.validate import check_int, check_positive, check_range, check_rng
from procgen.amplify.plants import upward_slope
from procgen.amplify.surface import mesh_input
from procgen.noise.fractal import fbm
from procgen.sweeps import sweep

__all__ = ["VineResult", "grow_vines", "surface_walks", "LEAF_TILT_DEG"]

LEAF_TILT_DEG = 20.0
"""A climber's leaf blade leans this far off the surface it grows on (ivy's blades stand
off the wall on their petioles, facing the light)."""


@dataclass
class VineResult:
    """What :func:`grow_vines` made.

    Attributes
    ----------
    mesh : open3d.geometry.TriangleMesh
        All vines in one mesh.
    paths : list of (k, 3) float64
        The walks on the surface (before lifting by the radius).
    normals : list of (k, 3) float64
        Surface normals along each walk.
    leaf : (n,) bool
        Which vertices of ``mesh`` are leaves (none for a bare vine).
    shoots : int
        Side shoots grown from the stems (their walks follow the stems' in ``paths``).
    leaves : int
        Leaves on the stems and shoots.
    """

    mesh: object
    paths: list
    normals: list
    leaf: np.ndarray | None = None
    shoots: int = 0
    leaves: int = 0


class _Projector:
    def __init__(self, v, f):
        import open3d as o3d

        tm = o3d.t.geometry.TriangleMesh()
        tm.vertex.positions = o3d.core.Tensor(v.astype(np.float32))
        tm.triangle.indices = o3d.core.Tensor(f.astype(np.int32))
        self.scene = o3d.t.geometry.RaycastingScene()
        self.scene.add_triangles(tm)
        self.fn = face_normals(v, f)
        self.o3d = o3d

    def blocked(self, a, b):
        """(k,) bool: the segments ``a``-``b`` (k, 3) cross the surface."""
        d = b - a
        length = np.linalg.norm(d, axis=1)
        rays = np.concatenate([a, d / np.maximum(length, 1e-300)[:, None]], 1)
        hit = self.scene.cast_rays(self.o3d.core.Tensor(rays.astype(np.float32)),
                                   nthreads=1)["t_hit"].numpy()
        return hit < length

    def __call__(self, p):
        ans = self.scene.compute_closest_points(self.o3d.core.Tensor(p.astype(np.float32)),
                                                nthreads=1)
        q = ans["points"].numpy().astype(np.float64)
        tri = ans["primitive_ids"].numpy().astype(np.int64)
        return q, self.fn[tri]


def _tangent(d, n):
    t = d - np.einsum("ij,ij->i", d, n)[:, None] * n
    norm = np.linalg.norm(t, axis=1, keepdims=True)
    return t, norm[:, 0]


def surface_walks(mesh, *, rng: np.random.Generator, count: int = 12, length: float = 1.0,
                  step: float = 0.02, wander_deg: float = 25.0, slope_max_deg: float = 90.0,
                  slope_min_deg: float = 0.0, climb: float = 0.0
                  ) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Noise-driven walks on the surface; returns ``(paths, normals)``, each a list of
    ``count`` arrays ``(k, 3)`` with ``k = ceil(length / step) + 1``.

    Parameters
    ----------
    mesh : open3d.geometry.TriangleMesh
    rng : numpy.random.Generator
    count : int
    length, step : float
        Walk length and step in metres (step <= length).
    wander_deg : float
        Largest turn per step (degrees, 0 to 180).
    slope_max_deg : float
        Start only where the upward slope is at most this (0 to 180; 90 allows walls).
    slope_min_deg : float
        ... and at least this (60: start on walls); when no surface is that steep, the
        walks start anywhere within ``slope_max_deg`` instead.
    climb : float
        In [0, 1]: how much each step turns toward up (+z along the surface): 0 wanders,
        1 climbs straight up a wall.
    """
    rng = check_rng(rng)
    v, f = mesh_input(mesh)
    count = check_int(count, "count", 1, 100_000)
    L = check_positive(length, "length")
    h = check_positive(step, "step")
    if h > L:
        raise ValueError(f"step: expected at most length = {L:g}, got {h:g}")
    wander = np.radians(check_range(wander_deg, "wander_deg", 0.0, 180.0))
    smax = check_range(slope_max_deg, "slope_max_deg", 0.0, 180.0)
    smin = check_range(slope_min_deg, "slope_min_deg", 0.0, 180.0)
    climb = check_range(climb, "climb", 0.0, 1.0)
    fn = face_normals(v, f)
    slope = upward_slope(fn)
    ok = slope <= smax + 1e-9
    if not ok.any():
        raise ValueError(f"slope_max_deg: no surface is gentler than {smax:g} degrees")
    if (ok & (slope >= smin - 1e-9)).any():
        ok &= slope >= smin - 1e-9
    keep = np.flatnonzero(ok)
    starts, _, tri = sample_surface(v, f[keep], count, rng=rng, return_index=True)
    n = fn[keep][tri]
    d, norm = _tangent(rng.standard_normal((count, 3)), n)
    d = d / np.maximum(norm, 1e-300)[:, None]
    seed = int(rng.integers(0, 2 ** 31 - 1))
    offsets = rng.uniform(-1000.0, 1000.0, size=(count, 1))
    project = _Projector(v, f)
    steps = int(np.ceil(L / h - 1e-9))
    P, N = _walk(project, starts, n, d, steps=steps, step=h, wander=wander, climb=climb,
                 seed=seed, offsets=offsets)
    return [P[i] for i in range(count)], [N[i] for i in range(count)]


def _walk(project, p, n, d, *, steps: int, step: float, wander: float, climb: float,
          seed: int, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Walk from points ``p`` (k, 3) with normals ``n`` and unit tangent headings ``d``
    ``steps`` steps of ``step`` metres on the surface ``project`` holds; returns the points
    and normals (k, steps + 1, 3). ``wander`` (radians) scales the fBm turn (``seed``, each
    walk shifted by its ``offsets`` (k, 1) in the field), ``climb`` leans toward up."""
    h = step
    freq = 1.0 / (8.0 * h)
    P, N = [p], [n]
    for _ in range(steps):
        q = p * freq
        a = wander * np.clip(fbm(q[:, 0] + offsets[:, 0], q[:, 1], q[:, 2], octaves=3,
                                 seed=seed) * 2.0, -1.0, 1.0)
        c, s = np.cos(a)[:, None], np.sin(a)[:, None]
        d = c * d + s * np.cross(n, d)
        if climb > 0:  # lean toward up along the surface
            up, un = _tangent(np.tile([0.0, 0.0, 1.0], (len(n), 1)), n)
            lean = (1.0 - climb) * d + climb * up / np.maximum(un, 1e-300)[:, None]
            ln = np.linalg.norm(lean, axis=1, keepdims=True)
            d = np.where((un > 1e-6)[:, None] & (ln > 1e-12), lean / np.maximum(ln, 1e-300), d)
        p_new, n_new = project(p + h * d)
        moved, mn = _tangent(p_new - p, n_new)
        # keep heading where the projection stalled (a crease or a boundary)
        dn, dnn = _tangent(d, n_new)
        d = np.where((mn > 1e-6 * h)[:, None], moved / np.maximum(mn, 1e-300)[:, None],
                     dn / np.maximum(dnn, 1e-300)[:, None])
        p, n = p_new, n_new
        P.append(p)
        N.append(n)
    return np.stack(P, axis=1), np.stack(N, axis=1)


def _untangled(path: np.ndarray, min_gap: float) -> np.ndarray:
    """The path without repeated points and without the turning points of exact
    back-and-forth steps (where a walk bounced off a crease and came back: the sweep's
    tangent there would be zero)."""
    path = path[np.r_[True, np.linalg.norm(np.diff(path, axis=0), axis=1) > min_gap]]
    while len(path) > 2:
        central = np.linalg.norm(path[2:] - path[:-2], axis=1)
        bad = np.flatnonzero(central <= min_gap)
        if bad.size == 0:
            break
        path = np.delete(path, bad[:1] + 1, axis=0)  # one at a time: neighbours change
        path = path[np.r_[True, np.linalg.norm(np.diff(path, axis=0), axis=1) > min_gap]]
    return path


def grow_vines(mesh, *, rng: np.random.Generator, count: int = 12, length: float = 1.0,
               step: float = 0.02, radius: float = 0.005, wander_deg: float = 25.0,
               slope_max_deg: float = 90.0, sides: int = 6, taper: float = 0.6,
               slope_min_deg: float = 0.0, climb: float = 0.0, branches: float = 0.0,
               leaf_size: float = 0.0, leaf_spacing: float | None = None) -> VineResult:
    """Vines on ``mesh``: :func:`surface_walks` swept into tubes; with ``branches`` and
    ``leaf_size``, a climbing plant (ivy) of stems, side shoots and leaves.

    Parameters
    ----------
    radius : float
        Tube radius at the root, metres; the path is lifted by it along the normal.
    sides : int
        Tube resolution (3 to 64).
    taper : float
        The radius shrinks linearly to ``(1 - taper) * radius`` at the tip (0 to 1).
    branches : float
        Side shoots per metre of stem (0: none). Each leaves the stem at a random point
        of its last 90 %, heading 30-60 degrees to either side of it along the surface,
        and walks 30-60 % of the stem's length, half as eager to climb, 0.6 times as thick.
    leaf_size : float
        Leaf blade length in metres (0: a bare vine), each 0.8-1.2 times it: the palmate
        outline of :func:`procgen.weber_penn.appearance.leaf_outline` on a petiole a third
        its length, alternating sides, leaning :data:`LEAF_TILT_DEG` off the surface.
    leaf_spacing : float, optional
        Metres between leaves along a stem (default: the leaf size).

    Other parameters as in :func:`surface_walks`. Every point of the plant stays within
    ``2 radius + 1.2 leaf_size sin(LEAF_TILT_DEG)`` of a flat surface.
    """
    r = check_positive(radius, "radius")
    sides = check_int(sides, "sides", 3, 64)
    tp = check_range(taper, "taper", 0.0, 1.0)
    branches = check_range(branches, "branches", 0.0, 1e6)
    leaf_size = check_range(leaf_size, "leaf_size", 0.0, 1e6)
    spacing = leaf_size if leaf_spacing is None else check_positive(leaf_spacing,
                                                                    "leaf_spacing")
    paths, normals = surface_walks(mesh, rng=rng, count=count, length=length, step=step,
                                   wander_deg=wander_deg, slope_max_deg=slope_max_deg,
                                   slope_min_deg=slope_min_deg, climb=climb)
    widths = [r] * len(paths)
    n_shoots = 0
    project = _Projector(*mesh_input(mesh)) if branches > 0 or leaf_size > 0 else None
    if branches > 0:
        sp, sn = _shoots(project, paths, normals, rng=rng, per_metre=branches, length=length,
                         step=step, wander_deg=wander_deg, climb=0.5 * climb)
        n_shoots = len(sp)
        paths, normals = paths + sp, normals + sn
        widths += [0.6 * r] * len(sp)
    ang = np.linspace(0.0, 2 * np.pi, sides, endpoint=False)
    circle = np.c_[np.cos(ang), np.sin(ang)]
    vs, fs, off = [], [], 0
    min_gap = 1e-3 * float(step)
    for P, N, w in zip(paths, normals, widths, strict=True):
        lifted = _untangled(P + w * N, min_gap)
        if len(lifted) < 2:
            continue
        t = np.linspace(0.0, 1.0, len(lifted))
        tv, tf = sweep(circle, lifted, scale=w * (1.0 - tp * t), caps=True)
        vs.append(tv)
        fs.append(tf + off)
        off += len(tv)
    if not vs:
        raise RuntimeError("grow_vines: every walk stalled where it started")
    n_wood, n_leaves = off, 0
    if leaf_size > 0:
        lv, lf, n_leaves = _climber_leaves(project, paths, normals, widths, rng=rng,
                                           size=leaf_size, spacing=spacing)
        vs.append(lv)
        fs.append(lf + off)
        off += len(lv)
    leaf = np.arange(off) >= n_wood
    return VineResult(make_mesh(np.vstack(vs), np.vstack(fs)), paths, normals, leaf, n_shoots,
                      n_leaves)


def _shoots(project, paths, normals, *, rng, per_metre, length, step, wander_deg, climb):
    """Side shoots of the stems ``paths``: walks on the surface from points along them."""
    starts, ns, ds, lengths = [], [], [], []
    for P, N in zip(paths, normals, strict=True):
        seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
        k = int(rng.poisson(per_metre * float(seg.sum())))
        if k == 0 or len(P) < 3:
            continue
        idx = rng.integers(max(len(P) // 10, 1), len(P) - 1, size=k)
        t, tn = _tangent(P[idx + 1] - P[idx], N[idx])
        t = t / np.maximum(tn, 1e-300)[:, None]
        a = np.radians(rng.uniform(30.0, 60.0, k)) * rng.choice([-1.0, 1.0], k)
        c, s = np.cos(a)[:, None], np.sin(a)[:, None]
        starts.append(P[idx])
        ns.append(N[idx])
        ds.append(c * t + s * np.cross(N[idx], t))
        lengths.append(length * rng.uniform(0.3, 0.6, k))
    if not starts:
        return [], []
    p, n, d, lens = (np.concatenate(x) for x in (starts, ns, ds, lengths))
    steps = int(np.ceil(lens.max() / step - 1e-9))
    seed = int(rng.integers(0, 2 ** 31 - 1))
    offsets = rng.uniform(-1000.0, 1000.0, size=(len(p), 1))
    P, N = _walk(project, p, n, d, steps=steps, step=step,
                 wander=np.radians(wander_deg), climb=climb, seed=seed, offsets=offsets)
    keep = np.ceil(lens / step - 1e-9).astype(int) + 1
    return [P[i, :keep[i]] for i in range(len(p))], [N[i, :keep[i]] for i in range(len(p))]


def _climber_leaves(project, paths, normals, widths, *, rng, size, spacing):
    """Leaves every ``spacing`` metres along each stem: a palmate blade of length ``size``
    (0.8-1.2 times) on a petiole, alternating sides, leaning off the surface. A leaf that
    would pass through the surface (into the corner of a recess) is left out: rays from
    the stem to its tip and its blade's two sides must reach them unhit."""
    from procgen.weber_penn.appearance import leaf_outline

    pos, nrm, tan, width = [], [], [], []
    for P, N, w in zip(paths, normals, widths, strict=True):
        seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
        arc = np.concatenate([[0.0], np.cumsum(seg)])
        at = np.arange(spacing, arc[-1], spacing)
        if not len(at):
            continue
        i = np.clip(np.searchsorted(arc, at) - 1, 0, len(P) - 2)
        t, tn = _tangent(P[i + 1] - P[i], N[i])
        ok = tn > 1e-12
        pos.append(P[i][ok])
        nrm.append(N[i][ok])
        tan.append((t / np.maximum(tn, 1e-300)[:, None])[ok])
        width.append(np.full(int(ok.sum()), w))
    if not pos:
        return np.empty((0, 3)), np.empty((0, 3), np.int64), 0
    p, n, t, w = (np.concatenate(x) for x in (pos, nrm, tan, width))
    k = len(p)
    side = np.where(np.arange(k) % 2 == 0, 1.0, -1.0)          # alternate leaves
    a = np.radians(rng.uniform(40.0, 80.0, k)) * side
    pet = np.cos(a)[:, None] * t + np.sin(a)[:, None] * np.cross(n, t)   # along the surface
    tilt = np.radians(LEAF_TILT_DEG)
    axis = np.cos(tilt) * pet + np.sin(tilt) * n
    face = np.cos(tilt) * n - np.sin(tilt) * pet
    across = np.cross(face, axis)
    length = size * rng.uniform(0.8, 1.2, k)
    base = p + w[:, None] * n + (length / 3.0)[:, None] * pet   # on its petiole
    root = p + w[:, None] * n
    free = np.ones(k, bool)
    for x, y in ((0.0, 1.0), (-0.5, 0.5), (0.5, 0.5)):
        free &= ~project.blocked(root, base + length[:, None] * (x * across + y * axis))
    p, n, t, w, base, axis, across, length = (a[free] for a in (p, n, t, w, base, axis,
                                                                across, length))
    k = len(p)
    outline = leaf_outline("lobed")
    pts = np.concatenate([[[0.0, 0.5]], outline])
    verts = (base[:, None, :] + pts[None, :, 0:1] * length[:, None, None] * across[:, None, :]
             + pts[None, :, 1:2] * length[:, None, None] * axis[:, None, :])
    m = len(outline)
    fan = np.stack([np.zeros(m, int), np.arange(1, m + 1), np.roll(np.arange(1, m + 1), -1)], 1)
    tris = (np.arange(k)[:, None, None] * (m + 1) + fan[None]).reshape(-1, 3)
    return verts.reshape(-1, 3), tris.astype(np.int64), k
