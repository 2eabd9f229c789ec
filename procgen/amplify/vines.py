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

__all__ = ["VineResult", "grow_vines", "surface_walks"]


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
    """

    mesh: object
    paths: list
    normals: list


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
    freq = 1.0 / (8.0 * h)
    offsets = rng.uniform(-1000.0, 1000.0, size=(count, 1))
    project = _Projector(v, f)
    steps = int(np.ceil(L / h - 1e-9))
    P, N = [starts], [n]
    p = starts
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
    P = np.stack(P, axis=1)
    N = np.stack(N, axis=1)
    return [P[i] for i in range(count)], [N[i] for i in range(count)]


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
               slope_min_deg: float = 0.0, climb: float = 0.0) -> VineResult:
    """Vines on ``mesh``: :func:`surface_walks` swept into tubes.

    Parameters
    ----------
    radius : float
        Tube radius at the root, metres; the path is lifted by it along the normal.
    sides : int
        Tube resolution (3 to 64).
    taper : float
        The radius shrinks linearly to ``(1 - taper) * radius`` at the tip (0 to 1).

    Other parameters as in :func:`surface_walks`.
    """
    r = check_positive(radius, "radius")
    sides = check_int(sides, "sides", 3, 64)
    tp = check_range(taper, "taper", 0.0, 1.0)
    paths, normals = surface_walks(mesh, rng=rng, count=count, length=length, step=step,
                                   wander_deg=wander_deg, slope_max_deg=slope_max_deg,
                                   slope_min_deg=slope_min_deg, climb=climb)
    ang = np.linspace(0.0, 2 * np.pi, sides, endpoint=False)
    circle = np.c_[np.cos(ang), np.sin(ang)]
    vs, fs, off = [], [], 0
    min_gap = 1e-3 * float(step)
    for P, N in zip(paths, normals, strict=True):
        lifted = _untangled(P + r * N, min_gap)
        if len(lifted) < 2:
            continue
        t = np.linspace(0.0, 1.0, len(lifted))
        tv, tf = sweep(circle, lifted, scale=r * (1.0 - tp * t), caps=True)
        vs.append(tv)
        fs.append(tf + off)
        off += len(tv)
    if not vs:
        raise RuntimeError("grow_vines: every walk stalled where it started")
    return VineResult(make_mesh(np.vstack(vs), np.vstack(fs)), paths, normals)
