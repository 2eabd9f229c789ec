"""Sweeps: a 2-D generating curve moved along a 3-D sweep curve.

- :func:`sweep` — the generalized sweep (generalized cylinder): a closed or open profile
  carried along a path with parallel-transport (rotation-minimizing) or Frenet frames,
  with twist and scale profiles, open or capped ends.
- :func:`extrude` — the translational sweep along a straight line.
- :func:`revolve` — the rotational sweep (surface of revolution) about the Z axis.
- :func:`segment_tubes` — many generalized cylinders at once along the segment chains of
  an L-system turtle, sharing rings at joints, widths tapering from parent to child.
- :func:`transport_frames`, :func:`frenet_frames` — the frames themselves.

Profile points ``(u, v)`` are placed at ``path + u * N + v * B`` where ``(T, N, B)`` is the
frame (T the unit tangent); meshes follow the canonical convention (counter-clockwise
seen from outside) for counter-clockwise profiles.

>>> import numpy as np
>>> t = np.linspace(0, 2 * np.pi, 64, endpoint=False)
>>> circle = np.c_[np.cos(t), np.sin(t)]
>>> v, f = sweep(circle, np.c_[np.zeros(2), np.zeros(2), [0.0, 2.0]])
>>> bool(abs(mesh_volume(v, f) - 64 / 2 * np.sin(2 * np.pi / 64) * 2) < 1e-9)
True
"""

from __future__ import annotations

import numba
import numpy as np

from core.frames import unit
from core.validate import check_array, check_choice

__all__ = ["sweep", "extrude", "revolve", "transport_frames", "frenet_frames",
           "segment_tubes", "mesh_volume", "edge_manifold_report"]


def _tangents(path: np.ndarray, closed: bool) -> np.ndarray:
    if closed:
        t = np.roll(path, -1, axis=0) - np.roll(path, 1, axis=0)
    else:
        t = np.gradient(path, axis=0)
    t = unit(t)
    if np.any(np.linalg.norm(t, axis=1) == 0):
        raise ValueError("path: expected distinct consecutive points, got repeated points")
    return t


def transport_frames(path: np.ndarray, *, closed: bool = False,
                     normal: np.ndarray | None = None) -> np.ndarray:
    """Parallel-transport (rotation-minimizing) frames along a polyline.

    Parameters
    ----------
    path : (n, 3) float64
    closed : bool
        The path is a loop; the residual rotation after one loop is spread evenly over
        the frames so that the last frame meets the first.
    normal : (3,) float64, optional
        Initial normal (projected perpendicular to the first tangent).

    Returns
    -------
    (n, 3, 3) float64
        Rows ``T, N, B`` (right-handed) per point.
    """
    path = check_array(path, "path", shape=(None, 3), min_rows=2)
    T = _tangents(path, closed)
    n = len(path)
    if normal is None:
        helper = np.eye(3)[np.argmin(np.abs(T[0]))]
    else:
        helper = check_array(normal, "normal", shape=(3,))
    N0 = unit(helper - np.dot(helper, T[0]) * T[0])
    N = np.empty_like(T)
    N[0] = N0
    for i in range(1, n):  # double reflection (Wang et al. 2008)
        v1 = path[i] - path[i - 1]
        c1 = v1 @ v1
        r = N[i - 1] - (2 / c1) * (v1 @ N[i - 1]) * v1 if c1 > 0 else N[i - 1]
        tl = T[i - 1] - (2 / c1) * (v1 @ T[i - 1]) * v1 if c1 > 0 else T[i - 1]
        v2 = T[i] - tl
        c2 = v2 @ v2
        N[i] = r - (2 / c2) * (v2 @ r) * v2 if c2 > 1e-300 else r
        N[i] = unit(N[i] - (N[i] @ T[i]) * T[i])
    B = np.cross(T, N)
    if closed:
        # angle between the transported last normal carried to the first point and N0
        ang = np.arctan2(np.dot(np.cross(N[-1], N0), T[0]), np.dot(N[-1], N0))
        ang_i = ang * np.arange(n) / n
        c, s = np.cos(ang_i)[:, None], np.sin(ang_i)[:, None]
        N, B = c * N + s * B, -s * N + c * B
    return np.stack([T, N, B], axis=1)


def frenet_frames(path: np.ndarray, *, closed: bool = False) -> np.ndarray:
    """Frenet frames ``(n, 3, 3)`` (rows T, N, B); fails where the curvature vanishes.

    Raises
    ------
    ValueError
        The path is straight somewhere (no principal normal): use parallel transport.
    """
    path = check_array(path, "path", shape=(None, 3), min_rows=3)
    T = _tangents(path, closed)
    dT = np.roll(T, -1, axis=0) - np.roll(T, 1, axis=0) if closed else np.gradient(T, axis=0)
    dT = dT - np.sum(dT * T, axis=1, keepdims=True) * T
    if np.any(np.linalg.norm(dT, axis=1) < 1e-12):
        raise ValueError("path: zero curvature somewhere, Frenet frames undefined; "
                         "use frames='parallel'")
    N = unit(dT)
    return np.stack([T, N, np.cross(T, N)], axis=1)


def _profile_area(profile: np.ndarray) -> float:
    x, y = profile[:, 0], profile[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def sweep(profile: np.ndarray, path: np.ndarray, *, frames: str = "parallel",
          twist: np.ndarray | float = 0.0, scale: np.ndarray | float = 1.0,
          closed_profile: bool = True, closed_path: bool = False, caps: bool = True,
          normal: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Generalized sweep of ``profile`` along ``path``.

    Parameters
    ----------
    profile : (m, 2) float64
        Generating curve in the (N, B) plane; counter-clockwise for outward normals.
    path : (n, 3) float64
    frames : {'parallel', 'frenet'}
    twist : float or (n,) float64
        Rotation of the profile about T, radians, per path point.
    scale : float, (n,) or (n, 2) float64
        Uniform or per-axis scale of the profile per path point.
    closed_profile : bool
        Connect the last profile point to the first (a tube) or not (a ribbon).
    closed_path : bool
        Connect the last ring to the first (a torus-like surface; no caps).
    caps : bool
        Close both ends with a fan (closed profiles on open paths only).
    normal : (3,) float64, optional
        Initial normal for parallel transport.

    Returns
    -------
    vertices : (k, 3) float64
    triangles : (t, 3) int64
    """
    profile = check_array(profile, "profile", shape=(None, 2), min_rows=2)
    path = check_array(path, "path", shape=(None, 3), min_rows=2)
    check_choice(frames, "frames", {"parallel", "frenet"})
    n, m = len(path), len(profile)
    F = (transport_frames(path, closed=closed_path, normal=normal) if frames == "parallel"
         else frenet_frames(path, closed=closed_path))
    tw = np.broadcast_to(np.asarray(twist, np.float64), (n,))
    sc = np.asarray(scale, np.float64)
    sc = np.broadcast_to(sc[:, None] if sc.ndim == 1 else sc, (n, 2))
    c, s = np.cos(tw)[:, None], np.sin(tw)[:, None]
    Nt = c * F[:, 1] + s * F[:, 2]
    Bt = -s * F[:, 1] + c * F[:, 2]
    u = profile[None, :, 0] * sc[:, 0:1]
    v = profile[None, :, 1] * sc[:, 1:2]
    verts = path[:, None, :] + u[..., None] * Nt[:, None, :] + v[..., None] * Bt[:, None, :]
    verts = verts.reshape(-1, 3)
    rings = n if closed_path else n - 1
    segs = m if closed_profile else m - 1
    i = np.arange(rings)[:, None]
    j = np.arange(segs)[None, :]
    a0 = i * m + j
    a1 = i * m + (j + 1) % m
    b0 = ((i + 1) % n) * m + j
    b1 = ((i + 1) % n) * m + (j + 1) % m
    # profile counter-clockwise in (N, B), moving along T: (a0, a1, b1) faces outward
    tris = np.concatenate([np.stack([a0, a1, b1], -1).reshape(-1, 3),
                           np.stack([a0, b1, b0], -1).reshape(-1, 3)])
    if caps and closed_profile and not closed_path:
        c0 = len(verts)
        centers = np.vstack([path[0], path[-1]])
        verts = np.vstack([verts, centers])
        jj = np.arange(m)
        start = np.stack([np.full(m, c0), (jj + 1) % m, jj], -1)
        end = np.stack([np.full(m, c0 + 1), (n - 1) * m + jj, (n - 1) * m + (jj + 1) % m], -1)
        tris = np.concatenate([tris, start, end])
    tris = tris.astype(np.int64)
    if closed_profile and _profile_area(profile) < 0:
        tris = tris[:, ::-1].copy()
    return verts, tris


def extrude(profile: np.ndarray, height: float, *, caps: bool = True,
            direction=(0.0, 0.0, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """Translational sweep: ``profile (m, 2)`` in the XY plane moved by ``height`` along
    ``direction``; returns ``(vertices, triangles)``."""
    d = unit(check_array(direction, "direction", shape=(3,)))
    path = np.stack([np.zeros(3), d * float(height)])
    # frame with N = +X, B = +Y when the direction is +Z
    helper = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    return sweep(profile, path, caps=caps, normal=helper)


def revolve(profile: np.ndarray, *, segments: int = 64, angle: float = 2 * np.pi,
            caps: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Rotational sweep: ``profile (m, 2)`` of ``(r, z)`` points revolved about the Z axis.

    Parameters
    ----------
    profile : (m, 2) float64
        An open curve, ``r >= 0``; points on the axis (r = 0) are welded to one vertex,
        so a profile from the axis to the axis gives a closed surface.
    segments : int
        Number of angular steps over ``angle``.
    angle : float
        Radians; ``2 pi`` closes the surface of revolution.
    caps : bool
        For a partial angle, close the two planar cuts (only when the profile starts and
        ends on the axis).

    Returns
    -------
    vertices : (k, 3) float64
    triangles : (t, 3) int64
    """
    prof = check_array(profile, "profile", shape=(None, 2), min_rows=2)
    if np.any(prof[:, 0] < 0):
        raise ValueError("profile: expected r >= 0 in every (r, z) point")
    if segments < 3:
        raise ValueError(f"segments: expected >= 3, got {segments}")
    full = abs(angle - 2 * np.pi) < 1e-12
    k = segments if full else segments + 1
    th = np.arange(k) * (angle / segments)
    m = len(prof)
    on_axis = prof[:, 0] <= 1e-12 * max(1.0, float(np.abs(prof).max()))
    # vertex index of (profile point, angle step)
    idx = np.empty((m, k), np.int64)
    verts = []
    count = 0
    for a in range(m):
        if on_axis[a]:
            idx[a] = count
            verts.append([[0.0, 0.0, prof[a, 1]]])
            count += 1
        else:
            idx[a] = count + np.arange(k)
            verts.append(np.c_[prof[a, 0] * np.cos(th), prof[a, 0] * np.sin(th),
                               np.full(k, prof[a, 1])])
            count += k
    verts = np.vstack(verts)
    tris = []
    steps = k if full else k - 1
    for a in range(m - 1):
        for_j = np.arange(steps)
        p0, p1 = idx[a, for_j], idx[a, (for_j + 1) % k]
        q0, q1 = idx[a + 1, for_j], idx[a + 1, (for_j + 1) % k]
        # profile going up in z at r > 0 faces outward with (p0, p1, q1), (p0, q1, q0)
        t1 = np.stack([p0, p1, q1], -1)
        t2 = np.stack([p0, q1, q0], -1)
        keep1 = (t1[:, 0] != t1[:, 1]) & (t1[:, 1] != t1[:, 2]) & (t1[:, 0] != t1[:, 2])
        keep2 = (t2[:, 0] != t2[:, 1]) & (t2[:, 1] != t2[:, 2]) & (t2[:, 0] != t2[:, 2])
        tris += [t1[keep1], t2[keep2]]
    tris = np.concatenate(tris).astype(np.int64)
    if not full and caps and on_axis[0] and on_axis[-1]:
        for j, flip in ((0, False), (k - 1, True)):
            ring = idx[:, j]
            fan = np.stack([np.full(m - 2, ring[0]), ring[1:-1], ring[2:]], -1)
            tris = np.vstack([tris, fan[:, ::-1] if flip else fan])
    return verts, tris


@numba.njit(cache=True)
def _tube_layout(parent):
    """Continuations, own start rings and output sizes of :func:`segment_tubes`."""
    m = len(parent)
    cont = np.full(m, -1, np.int64)
    for i in range(m):
        if parent[i] >= 0:
            cont[parent[i]] = i  # the last child continues the tube (the main axis)
    own_start = np.empty(m, np.int64)
    n_own = 0
    n_end_caps = 0
    for i in range(m):
        if parent[i] >= 0 and cont[parent[i]] == i:
            own_start[i] = -1
        else:
            own_start[i] = m + n_own
            n_own += 1
        if cont[i] < 0:
            n_end_caps += 1
    return cont, own_start, n_own, n_end_caps


@numba.njit(cache=True, fastmath=True)
def _tube_fill(p0, p1, frames, r0, r1, parent, cont, own_start, sides, caps, nrings,
               verts, tris):
    """Write rings, caps and triangles into ``verts`` and ``tris`` (allocated by numpy,
    which asks the kernel for huge pages: first-touch page faults were most of the cost)."""
    m = len(p0)
    V = verts.reshape(-1)
    T = tris.reshape(-1)
    cs = np.empty(sides)
    sn = np.empty(sides)
    for j in range(sides):
        cs[j] = np.cos(2 * np.pi * j / sides)
        sn[j] = np.sin(2 * np.pi * j / sides)
    q_t = 0
    cv = nrings * sides
    for i in range(m):
        hx, hy, hz = frames[i, 0, 0], frames[i, 0, 1], frames[i, 0, 2]
        lx, ly, lz = frames[i, 1, 0], frames[i, 1, 1], frames[i, 1, 2]
        # end ring of segment i: in the bisector plane with its continuation
        dx, dy, dz = hx, hy, hz
        c = cont[i]
        if c >= 0:
            dx += frames[c, 0, 0]
            dy += frames[c, 0, 1]
            dz += frames[c, 0, 2]
            nd = np.sqrt(dx * dx + dy * dy + dz * dz)
            if nd < 1e-9:
                dx, dy, dz = hx, hy, hz
            else:
                dx /= nd
                dy /= nd
                dz /= nd
        dl = dx * lx + dy * ly + dz * lz
        ax, ay, az = lx - dl * dx, ly - dl * dy, lz - dl * dz
        na = 1.0 / np.sqrt(ax * ax + ay * ay + az * az)
        ax *= na
        ay *= na
        az *= na
        bx = dy * az - dz * ay
        by = dz * ax - dx * az
        bz = dx * ay - dy * ax
        ex, ey, ez = p1[i, 0], p1[i, 1], p1[i, 2]
        _ring(V, 3 * i * sides, ex, ey, ez, r1[i], ax, ay, az, bx, by, bz, cs, sn)
        s_ring = own_start[i]
        if s_ring >= 0:
            _ring(V, 3 * s_ring * sides, p0[i, 0], p0[i, 1], p0[i, 2], r0[i], lx, ly, lz,
                  frames[i, 2, 0], frames[i, 2, 1], frames[i, 2, 2], cs, sn)
            sa = s_ring * sides
        else:
            sa = parent[i] * sides
        eb = i * sides
        for j in range(sides):
            j1 = j + 1 if j + 1 < sides else 0
            T[q_t] = sa + j
            T[q_t + 1] = sa + j1
            T[q_t + 2] = eb + j1
            T[q_t + 3] = sa + j
            T[q_t + 4] = eb + j1
            T[q_t + 5] = eb + j
            q_t += 6
        if caps and s_ring >= 0:
            q_t = _cap(V, T, q_t, cv, p0[i, 0], p0[i, 1], p0[i, 2], sa, sides, True)
            cv += 1
        if caps and c < 0:
            q_t = _cap(V, T, q_t, cv, ex, ey, ez, eb, sides, False)
            cv += 1


@numba.njit(inline="always", cache=True)
def _ring(V, q, x, y, z, r, ax, ay, az, bx, by, bz, cs, sn):
    """Ring of ``len(cs)`` vertices at ``V[q:]``: centre (x, y, z), radius r, axes a and b."""
    for j in range(len(cs)):
        u = r * cs[j]
        w = r * sn[j]
        V[q] = x + u * ax + w * bx
        V[q + 1] = y + u * ay + w * by
        V[q + 2] = z + u * az + w * bz
        q += 3


@numba.njit(inline="always", cache=True)
def _cap(V, T, q_t, cv, x, y, z, ring, sides, start):
    """A fan closing ``ring`` around the centre vertex ``cv`` (facing back at a start)."""
    V[3 * cv] = x
    V[3 * cv + 1] = y
    V[3 * cv + 2] = z
    for j in range(sides):
        j1 = j + 1 if j + 1 < sides else 0
        T[q_t] = cv
        T[q_t + 1] = ring + (j1 if start else j)
        T[q_t + 2] = ring + (j if start else j1)
        q_t += 3
    return q_t


def _tubes(p0, p1, frames, r0, r1, parent, sides, caps):
    cont, own_start, n_own, n_end_caps = _tube_layout(parent)
    m = len(p0)
    n_caps = (n_own + n_end_caps) if caps else 0
    nrings = m + n_own
    verts = np.empty((nrings * sides + n_caps, 3))
    tris = np.empty((m * 2 * sides + n_caps * sides, 3), np.int32)
    if np.iinfo(np.int32).max < len(verts):
        raise ValueError(f"starts: {m} segments need {len(verts):,} vertices, more than int32 "
                         "triangle indices address; use fewer sides or segments")
    _tube_fill(p0, p1, frames, r0, r1, parent, cont, own_start, sides, caps, nrings,
               verts, tris)
    return verts, tris


def segment_tubes(starts: np.ndarray, ends: np.ndarray, frames: np.ndarray,
                  radii: np.ndarray, parents: np.ndarray, *, sides: int = 8,
                  caps: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Generalized cylinders along turtle segments, one mesh for all.

    A segment's last child (in drawing order) continues its tube through a shared ring in
    the bisector plane of the two headings; any other child starts its own capped tube.
    Each tube's radius runs from its parent's radius to its own, so widths taper. Every
    unbranched chain is a closed, consistently oriented surface (watertight).

    Parameters
    ----------
    starts, ends : (m, 3) float64
    frames : (m, 3, 3) float64
        Rows H, L, U per segment (H along the segment).
    radii : (m,) float64
    parents : (m,) int64
        Segment each one continues from, or -1; parents precede children.
    sides : int
        Ring resolution (>= 3).
    caps : bool
        Close the tube ends.

    Returns
    -------
    vertices : (k, 3) float64
    triangles : (t, 3) int32
    """
    m = len(starts)
    if sides < 3:
        raise ValueError(f"sides: expected >= 3, got {sides}")
    p0 = check_array(starts, "starts", shape=(m, 3))
    p1 = check_array(ends, "ends", shape=(m, 3))
    fr = check_array(frames, "frames", shape=(m, 3, 3))
    r1 = check_array(radii, "radii", shape=(m,))
    par = check_array(parents, "parents", shape=(m,), dtype=np.int64)
    if np.any(par >= np.arange(m)):
        raise ValueError("parents: expected every parent index to precede its child")
    r0 = np.where(par >= 0, r1[np.maximum(par, 0)], r1) if m else r1
    return _tubes(p0, p1, np.ascontiguousarray(fr), r0, r1, par, int(sides), bool(caps))


def mesh_volume(vertices: np.ndarray, triangles: np.ndarray) -> float:
    """Signed volume of a closed triangle mesh (divergence theorem)."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(triangles, np.int64)
    return float(np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]])).sum() / 6)


def edge_manifold_report(triangles: np.ndarray) -> dict:
    """Count edges by how many triangles use them and how consistently.

    Returns ``{'edges', 'boundary', 'nonmanifold', 'inconsistent'}``: a closed, oriented
    2-manifold has zero boundary, non-manifold and inconsistently oriented edges.
    """
    f = np.asarray(triangles, np.int64)
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    key = np.sort(e, axis=1)
    uniq, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    forward = (e[:, 0] < e[:, 1]).astype(np.int64)
    fsum = np.bincount(inv.ravel(), weights=forward, minlength=len(uniq))
    two = counts == 2
    return {"edges": int(len(uniq)), "boundary": int(np.sum(counts == 1)),
            "nonmanifold": int(np.sum(counts > 2)),
            "inconsistent": int(np.sum(two & (fsum != 1)))}
