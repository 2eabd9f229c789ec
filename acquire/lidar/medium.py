"""Leaves too small to mesh: sub-rays through turbid-medium crowns, by Beer-Lambert.

A broadleaf crown holds a hundred thousand leaves of a few centimetres, more than a scene
can mesh and finer than a footprint's sub-rays. It is a closed envelope of leaf area
density ``u`` (m² of leaf per m³: :attr:`SceneObject.leaf_area_density`), the crown of the
geometric-optical radiative-transfer models (Li and Strahler 1992; Ni et al. 1999, GORT,
doi:10.1109/36.752225) and of DART's turbid cells (Gastellu-Etchegorry et al. 1996). A ray
inside it meets leaves at the rate ``G u`` per metre, ``G`` the mean projection of a unit of
leaf area on the plane across the ray: 0.5 for leaves at random (spherical) angles, whatever
the ray's direction (Ross 1981). So the distance to the first leaf is exponential, and the
share of rays that cross a layer of leaf area index ``L`` at zenith angle ``theta`` without
meeting a leaf is ``exp(-G L / cos(theta))`` (Beer-Lambert; Monsi and Saeki 1953).

Each sub-ray is one such ray: where Embree's first hit is a medium's envelope the sub-ray
goes on through it, envelope face by envelope face (entering adds ``G u`` to its extinction,
leaving takes it away, so overlapping crowns add), and on each stretch between faces draws
its free path; a leaf met within the stretch returns ``w rho mu / R^2`` with ``mu`` the cosine
between the ray and the leaf's normal, ``2 mu`` distributed for leaves at random angles (the
area a leaf shows the ray is proportional to ``mu``); a solid face met first (a branch, the
ground) returns as any hit does. A pulse's sub-rays draw apart, so its footprint spreads
over the crown's depth as the waveform of real foliage does.
"""

from __future__ import annotations

import numpy as np

__all__ = ["G_SPHERICAL", "through_media"]

G_SPHERICAL = 0.5
"""Ross's G function of a spherical leaf angle distribution (any direction)."""

_EPS = 1e-4           # metres: a re-cast starts this far past the face it left
_MAX_FACES = 64       # envelope faces a sub-ray may cross before it is taken as lost


def through_media(world, rays: np.ndarray, weights: np.ndarray, R, E, obj, face,
                  min_range: float, rng: np.random.Generator, *, normals: np.ndarray) -> None:
    """Carry the sub-rays whose first hit is a medium's envelope on through the media, in
    place of their envelope hits: ``R, E, obj, face`` (:meth:`LidarWorld.cast_energy`'s
    arrays) are updated to the leaf or solid surface each one meets, or to no return.
    ``normals (n*s, 3)``: the outward normals of the faces first hit (Embree's)."""
    import open3d as o3d

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
        with np.errstate(divide="ignore"):
            free = np.where(k[live] > 0, rng.standard_exponential(len(live))
                            / np.maximum(k[live], 1e-300), np.inf)
        leaf = free < th
        # a leaf met on this stretch
        li = live[leaf]
        rl = t[li] + _EPS + free[leaf]
        mu = np.sqrt(rng.random(len(li)))
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
