"""Leaves too many to mesh: sub-rays through the leaves of foliage media.

A broadleaf crown holds a hundred thousand leaves of a few centimetres, more than a scene
can mesh. It is a closed envelope of leaf area density ``u`` (m² of leaf per m³:
:attr:`SceneObject.leaf_area_density`), the crown of the geometric-optical
radiative-transfer models (Li and Strahler 1992; Ni et al. 1999, GORT,
doi:10.1109/36.752225) and of DART's turbid cells (Gastellu-Etchegorry et al. 1996), whose
leaves are drawn where a ray needs them rather than stored: space is a lattice of cells of
:data:`SHOOT_CELL` (a shoot's spray of leaves), and each cell inside the media holds
Poisson(``u cell^3 / a``) discs of a leaf's area ``a`` (:data:`LEAF_AREA`) at uniform
places, their normals uniform on the sphere, drawn from a hash of the cell: every pulse,
strip and scanner meets the same leaves, and the world holds none of them.

Leaves at random places and angles make the medium Beer-Lambert's (Monsi and Saeki 1953):
a ray meets them at the rate ``G u`` per metre, ``G = 0.5`` the mean projection of a unit of
leaf area across a ray for leaves at random (spherical) angles whatever its direction (Ross
1981), so the share of rays that cross a layer of leaf area index ``L`` at zenith angle
``theta`` is ``exp(-G L / cos(theta))``. Unlike a turbid medium's free paths drawn ray by
ray, the sub-rays of one footprint meet the same centimetre leaves, clustered in the same
shoots, so a pulse's echoes come from the leaves it really meets.

Where Embree's first hit is a medium's envelope the sub-ray goes on through it, envelope
face by envelope face (entering adds ``u``, leaving takes it away, so overlapping crowns
add), and on each stretch between faces walks the cells in order to the first leaf
(:func:`acquire.lidar._kernels.leaf_hits`), which returns ``w rho mu / R^2``, ``mu`` the
cosine between ray and leaf; a solid face met first (a branch, the ground) returns as any
hit does.
"""

from __future__ import annotations

import numpy as np

__all__ = ["G_SPHERICAL", "LEAF_AREA", "SHOOT_CELL", "through_media"]

G_SPHERICAL = 0.5
"""Ross's G function of a spherical leaf angle distribution (any direction)."""

LEAF_AREA = 0.003
"""One leaf's area, m²: a European beech leaf is 5-10 cm long and 3-7 cm wide (an 8 x 5 cm
ellipse: 31 cm²)."""

SHOOT_CELL = 0.2
"""Side of the lattice cells whose leaves are drawn together, metres: a shoot's spray of
leaves (a beech's long shoots reach 10-30 cm), so a footprint of 15-30 cm meets the
leaves of one or two shoots, at nearly one range, as a real one does."""

_EPS = 1e-4           # metres: a re-cast starts this far past the face it left
_MAX_FACES = 64       # envelope faces a sub-ray may cross before it is taken as lost
_MAX_STRETCH = 200.0  # metres walked through leaves when no face lies ahead (a leak)


def through_media(world, rays: np.ndarray, weights: np.ndarray, R, E, obj, face,
                  min_range: float, *, normals: np.ndarray) -> None:
    """Carry the sub-rays whose first hit is a medium's envelope on through the media, in
    place of their envelope hits: ``R, E, obj, face`` (:meth:`LidarWorld.cast_energy`'s
    arrays) are updated to the leaf or solid surface each one meets, or to no return.
    ``normals (n*s, 3)``: the outward normals of the faces first hit (Embree's)."""
    import open3d as o3d

    from acquire.lidar import _kernels

    lad = world.leaf_area_density
    hit = obj >= 0
    act = np.flatnonzero(hit)
    act = act[lad[obj[act]] > 0]
    if not len(act):
        return
    s = len(weights)
    o = rays[act, :3].astype(np.float64)
    d = rays[act, 3:].astype(np.float64)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    w = weights[act % s]
    t = R[act].copy()                       # distance travelled, to the current face
    k = np.zeros(len(act))                  # extinction (1/m) past the current face
    inside = np.full(len(act), -1, np.int64)  # the medium last entered (its leaves' owner)
    inface = np.zeros(len(act), np.int64)
    cur_obj, cur_face = obj[act].copy(), face[act].copy()
    normal = normals[act].astype(np.float64)
    R[act], E[act], obj[act] = np.inf, 0.0, -1
    live = np.arange(len(act))
    for _ in range(_MAX_FACES):
        if not len(live):
            break
        # the face just reached: a medium's envelope (in or out), by the face's normal
        entering = np.einsum("ij,ij->i", d[live], normal) < 0
        gu = G_SPHERICAL * lad[cur_obj[live]]
        k[live] = np.maximum(k[live] + np.where(entering, gu, -gu), 0.0)
        k[live[k[live] < 1e-12]] = 0.0
        ent = live[entering]
        inside[ent], inface[ent] = cur_obj[ent], cur_face[ent]
        # on to the next face
        start = o[live] + d[live] * (t[live] + _EPS)[:, None]
        q = np.hstack([start, d[live]]).astype(np.float32)
        ans = world.rs.cast_rays(o3d.core.Tensor.from_numpy(q))
        th = ans["t_hit"].numpy().astype(np.float64)
        gid = ans["geometry_ids"].numpy()
        pid = ans["primitive_ids"].numpy().astype(np.int64)
        nrm = ans["primitive_normals"].numpy().astype(np.float64)
        t0 = t[live] + _EPS
        t1 = t0 + np.minimum(th, _MAX_STRETCH)
        hit_t, hit_mu = np.empty(len(live)), np.empty(len(live))
        _kernels.leaf_hits(o[live], d[live], t0, t1, k[live] / G_SPHERICAL, SHOOT_CELL,
                           LEAF_AREA, 0, hit_t, hit_mu)
        leaf = np.isfinite(hit_t)
        # a leaf met on this stretch
        li = live[leaf]
        rl = hit_t[leaf]
        mu = hit_mu[leaf]
        ok = rl >= min_range
        a = act[li[ok]]
        R[a] = rl[ok]
        E[a] = w[li[ok]] * world.reflectance[inside[li[ok]]] * mu[ok] / rl[ok] ** 2
        obj[a], face[a] = inside[li[ok]], inface[li[ok]]
        # past the stretch: nothing (lost), a solid face (returns), or another envelope face
        go = ~leaf & np.isfinite(th)
        gi = live[go]
        ob = world.lut[gid[go]]
        fc = world.face_offset[ob] + pid[go]
        tt = t[gi] + _EPS + th[go]
        solid = lad[ob] <= 0
        si = gi[solid]
        n = nrm[go][solid]
        cos = np.abs(np.einsum("ij,ij->i", n, d[si])) / np.maximum(
            np.linalg.norm(n, axis=1), 1e-12)
        ok = tt[solid] >= min_range
        a = act[si[ok]]
        R[a] = tt[solid][ok]
        E[a] = w[si[ok]] * world.reflectance[ob[solid][ok]] * cos[ok] / tt[solid][ok] ** 2
        obj[a], face[a] = ob[solid][ok], fc[solid][ok]
        mi = gi[~solid]
        t[mi] = tt[~solid]
        cur_obj[mi], cur_face[mi] = ob[~solid], fc[~solid]
        normal = nrm[go][~solid]
        live = mi
