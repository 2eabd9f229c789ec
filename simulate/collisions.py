"""Collision response of point particles against a triangle mesh.

Each step's motion from ``(x0, v0)`` to ``(x1, v1)`` is modelled as the quadratic
path ``x(s) = x0 + v0 s + a s^2 / 2`` through both end points (``a = 2 (x1 - x0 - v0 h)
/ h^2``; the exact path under constant forces, which every integrator of order >= 2
reproduces). The chord ``x0 -> x1`` is cast against the mesh (a swept segment:
nothing tunnels); for the triangle hit, the time of impact is the root of the
quadratic ``n . x(s) = d`` in float64 — exact for ballistic motion, and independent
of Embree's float32 hit distance, which only picks the triangle. At impact:

* velocity ``v = v_t - e v_n`` with ``e`` the restitution, and Coulomb friction
  removing up to ``mu (1 + e) |v_n|`` of the tangential speed;
* if the rebound speed ``e |v_n|`` is below ``rest_speed`` the contact is resting:
  the normal velocity and the acceleration into the surface are removed, and
  friction works against the pressing acceleration for the rest of the step;
* the particle continues for the remaining time from the contact point (a few
  ``skin`` off the surface, on the side it came from), cast again, up to
  ``max_bounces`` impacts within one step.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numba as nb
import numpy as np

from core.validate import check_int, check_positive, check_range

log = logging.getLogger(__name__)

__all__ = ["ContactParams", "CollisionStats", "collide"]


@dataclass(frozen=True)
class ContactParams:
    """Contact model.

    Attributes
    ----------
    restitution : float in [0, 1]
        ``e``: normal speed after / before.
    friction : float >= 0
        Coulomb coefficient ``mu``.
    rest_speed : float >= 0
        Rebounds slower than this (m/s) become resting contact.
    max_bounces : int >= 1
        Impacts resolved within one step.
    skin : float >= 0
        Distance (as a fraction of the collider's bounding-box diagonal) kept
        between a contact point and the surface.
    """

    restitution: float = 0.5
    friction: float = 0.0
    rest_speed: float = 1e-3
    max_bounces: int = 8
    skin: float = 1e-10

    def __post_init__(self):
        check_range(self.restitution, "restitution", 0.0, 1.0)
        check_positive(self.friction, "friction", allow_zero=True)
        check_positive(self.rest_speed, "rest_speed", allow_zero=True)
        check_positive(self.skin, "skin", allow_zero=True)
        check_int(self.max_bounces, "max_bounces")


@dataclass
class CollisionStats:
    """Counters of one :func:`collide` call."""

    impacts: int = 0
    resting: int = 0
    overflow: int = 0  # particles that used up max_bounces
    casts: int = 0  # rays cast in total


def _plane_toi(s0, b, c, rem, sigma_known, tol_s, tol_tau):
    """Smallest impact time in [0, rem] of ``s(t) = s0 + b t + c t^2`` (vectorized).

    ``sigma_known`` is the side (+1 / -1) each particle belongs to, or 0 where unknown
    (then the side it is on, or, on the plane, the side it moves to). A particle on
    the wrong side of its plane is treated as on the plane. Returns ``tau`` (nan
    where no impact) and the side ``sigma``.
    """
    known = sigma_known != 0
    on_plane = (np.abs(s0) <= tol_s) | (known & (sigma_known * s0 < 0))
    motion = np.where(b != 0, np.sign(b), -np.sign(c))
    sigma = np.where(known, sigma_known, np.where(on_plane, motion, np.sign(s0)))
    s0 = np.where(on_plane, 0.0, s0)
    cand = np.full((len(s0), 2), np.nan)
    lin = np.abs(c) * rem * rem <= 1e-14 * (np.abs(b) * rem + np.abs(s0) + 1e-300)
    with np.errstate(divide="ignore", invalid="ignore"):
        cand[lin, 0] = np.where(b[lin] != 0, -s0[lin] / b[lin], np.nan)
        cand[lin, 1] = np.where(on_plane[lin], 0.0, np.nan)
        q = ~lin
        disc = b[q] ** 2 - 4.0 * c[q] * s0[q]
        disc = np.where((disc < 0) & (disc > -1e-12 * b[q] ** 2), 0.0, disc)
        sq = np.sqrt(disc)
        qq = -0.5 * (b[q] + np.where(b[q] >= 0, 1.0, -1.0) * sq)
        cand[q, 0] = qq / c[q]
        cand[q, 1] = np.where(qq != 0, s0[q] / qq, 0.0)  # qq == 0 only when b == s0 == 0
    # on the plane and leaving toward its own side: the root t = 0 is not an impact
    lo = np.where(on_plane & (sigma * b > 0), tol_tau, -tol_tau)
    ds = b[:, None] + 2.0 * c[:, None] * cand
    ok = (cand >= lo[:, None]) & (cand <= rem[:, None] * (1 + 1e-12)) & \
         (sigma[:, None] * ds <= 0) & np.isfinite(cand)
    best = np.where(ok, cand, np.inf).min(axis=1)
    tau = np.where(np.isfinite(best), np.clip(best, 0.0, rem), np.nan)
    return tau, sigma, on_plane


@nb.njit(cache=True)
def _clamp_to_triangles(p, v, f, tri):
    """Closest points on triangles ``tri (n,)`` to points ``p (n, 3)`` (Ericson 5.1.5)."""
    out = np.empty_like(p)
    for i in range(p.shape[0]):
        a = v[f[tri[i], 0]]
        b = v[f[tri[i], 1]]
        c = v[f[tri[i], 2]]
        q = p[i]
        ab = b - a
        ac = c - a
        ap = q - a
        d1 = ab @ ap
        d2 = ac @ ap
        if d1 <= 0.0 and d2 <= 0.0:
            out[i] = a
            continue
        bp = q - b
        d3 = ab @ bp
        d4 = ac @ bp
        if d3 >= 0.0 and d4 <= d3:
            out[i] = b
            continue
        vc = d1 * d4 - d3 * d2
        if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
            out[i] = a + (d1 / (d1 - d3)) * ab
            continue
        cp = q - c
        d5 = ab @ cp
        d6 = ac @ cp
        if d6 >= 0.0 and d5 <= d6:
            out[i] = c
            continue
        vb = d5 * d2 - d1 * d6
        if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
            out[i] = a + (d2 / (d2 - d6)) * ac
            continue
        va = d3 * d6 - d5 * d4
        if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
            out[i] = b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b)
            continue
        den = 1.0 / (va + vb + vc)
        out[i] = a + ab * (vb * den) + ac * (vc * den)
    return out


@nb.njit(parallel=True, cache=True)
def _chord_rays(x0, x1, cast_skin):
    """Float32 rays along each step's chord, reaching a few ulps past both ends."""
    n = x0.shape[0]
    rays = np.zeros((n, 6), np.float32)
    for i in nb.prange(n):
        cl = 0.0
        for k in range(3):
            cl += (x1[i, k] - x0[i, k]) ** 2
        cl = np.sqrt(cl)
        if cl == 0.0:
            continue  # zero direction: never a hit
        back = cast_skin / cl
        for k in range(3):
            d = x1[i, k] - x0[i, k]
            rays[i, k] = x0[i, k] - back * d
            rays[i, 3 + k] = (1.0 + 2.0 * back) * d
    return rays


def collide(collider, x0: np.ndarray, v0: np.ndarray, x1: np.ndarray, v1: np.ndarray,
            h: float, params: ContactParams = ContactParams(), *,
            inside: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, CollisionStats]:
    """Resolve one step of motion against ``collider`` (a :class:`MeshCollider`).

    Parameters
    ----------
    collider : simulate.colliders.MeshCollider
    x0, v0 : (n, 3) float64
        State at the start of the step (assumed not penetrating).
    x1, v1 : (n, 3) float64
        The integrator's state at the end of the step, ignoring the mesh.
    h : float
        Step size (s).
    params : ContactParams
    inside : (n,) bool, optional
        For a closed collider: which particles belong inside. Their side of every
        face is then fixed (robust at edges and against float32 rounding); without
        it, the side is the one each particle is on.

    Returns
    -------
    x, v : (n, 3) float64
        Resolved end state (new arrays).
    stats : CollisionStats
    """
    x = np.array(x1, dtype=np.float64)
    v = np.array(v1, dtype=np.float64)
    stats = CollisionStats()
    n = len(x)
    if n == 0:
        return x, v, stats
    x0 = np.asarray(x0, np.float64)
    v0 = np.asarray(v0, np.float64)
    scale = float(np.linalg.norm(collider.bounds[1] - collider.bounds[0])) or 1.0
    x_max = max(float(x0.max(initial=0.0)), -float(x0.min(initial=0.0)))
    tol_s = 1e-12 * max(scale, x_max)
    skin = params.skin * scale
    # float32 (Embree) resolution around the particles, times a safety factor
    cast_skin = 16.0 * np.finfo(np.float32).eps * (scale + x_max)
    e, mu = float(params.restitution), float(params.friction)
    # One any-hit test of every chord; only particles whose chord meets the mesh go on
    # (the others keep the integrator's state exactly).
    idx = np.nonzero(collider.segments_hit(_chord_rays(x0, x, cast_skin)))[0]
    stats.casts += n
    hh = float(h)
    o = x0[idx]
    vel = v0[idx]
    # the constant acceleration of each path that reproduces the integrator's end point,
    # and the velocity correction that makes it reproduce its end velocity too
    a = 2.0 * (x[idx] - o - vel * hh) / (hh * hh)
    dv_fix = np.zeros_like(x)
    dv_fix[idx] = v[idx] - (vel + a * hh)
    side = np.zeros(n)
    if inside is not None:
        side[idx] = np.where(np.asarray(inside, bool)[idx], -1.0, 1.0)
    rem = np.full(len(idx), float(h))
    bounces = np.zeros(len(idx), np.int64)
    tri_v = collider.vertices
    tri_f = collider.triangles
    normals = collider.face_normals
    last_n = np.zeros((len(idx), 3))  # sigma * normal of each particle's last contact
    while len(idx):
        end = o + vel * rem[:, None] + 0.5 * a * (rem * rem)[:, None]
        chord = end - o
        # Cast origins a few float32 ulps behind the particle along its chord and off
        # the surface it last touched: a path leaving a surface at an edge then
        # crosses the neighbouring face at t > 0, where Embree sees it.
        clen = np.linalg.norm(chord, axis=1, keepdims=True)
        offset = cast_skin * (last_n - np.divide(chord, clen, out=np.zeros_like(chord),
                                                 where=clen > 0))
        tau = np.full(len(idx), np.nan)
        sigma = np.zeros(len(idx))
        nrm = np.zeros((len(idx), 3))
        dpl = np.zeros(len(idx))
        tri_hit = np.zeros(len(idx), np.int64)
        todo = np.nonzero(np.any(chord != 0, axis=1))[0]
        for attempt in range(4):  # recast past spurious hits (the surface just left)
            if not len(todo):
                break
            oc = o[todo] + offset[todo]
            ray = end[todo] - oc
            # ... and a few ulps past the end: a path ending within float32 precision
            # behind a face is still seen (and judged in float64)
            rl = np.linalg.norm(ray, axis=1, keepdims=True)
            ray = ray + cast_skin * np.divide(ray, rl, out=np.zeros_like(ray), where=rl > 0)
            hits = collider.cast(oc, ray)
            stats.casts += len(todo)
            got = hits.hit & (hits.t <= 1.0)
            todo = todo[got]
            if not len(todo):
                break
            tri = hits.triangle[got]
            nn = normals[tri]
            d = np.einsum("ij,ij->i", nn, tri_v[tri_f[tri, 0]])
            s0 = np.einsum("ij,ij->i", nn, o[todo]) - d
            b = np.einsum("ij,ij->i", nn, vel[todo])
            c = 0.5 * np.einsum("ij,ij->i", nn, a[todo])
            tt, sg, on_plane = _plane_toi(s0, b, c, rem[todo], side[idx[todo]], tol_s,
                                          1e-12 * rem[todo])
            ok = np.isfinite(tt)
            # a chord crossing whose quadratic root was lost to rounding: trust the chord
            chord_cross = ~ok & ~on_plane & (sg * np.einsum("ij,ij->i", nn, chord[todo]) < 0)
            tt = np.where(chord_cross, hits.t[got] * rem[todo], tt)
            ok |= chord_cross
            k = todo[ok]
            tau[k], sigma[k], nrm[k], dpl[k], tri_hit[k] = tt[ok], sg[ok], nn[ok], d[ok], tri[ok]
            # Spurious: the particle sits on this face (to float32 precision) and leaves
            # it, or passes near a ridge behind the face's plane. Cast again: clearly
            # on one side of the plane, from a few float32 ulps off it on that side;
            # else from just past the hit point along the ray (doubling each attempt).
            bad = ~ok
            sg_bad = np.where(sg[bad] == 0, 1.0, sg[bad])
            far = np.abs(s0[bad]) >= cast_skin
            t_b = hits.t[got][bad]
            ray_b = ray[got][bad]
            rl = np.linalg.norm(ray_b, axis=1)
            step = np.divide(cast_skin * 2.0 ** attempt, rl, out=np.zeros_like(rl),
                             where=rl > 0)
            past = oc[got][bad] + (t_b + step)[:, None] * ray_b
            todo = todo[bad]
            offset[todo] = np.where(far[:, None],
                                    offset[todo] + (sg_bad * cast_skin)[:, None] * nn[bad],
                                    past - o[todo])
        hit = np.isfinite(tau)
        # particles without a further impact: the path ends where the model puts it
        free = ~hit
        fi = idx[free]
        x[fi] = end[free]
        v[fi] = vel[free] + a[free] * rem[free, None] + dv_fix[fi]
        if not hit.any():
            break
        idx, o, vel, a, rem, tau = idx[hit], o[hit], vel[hit], a[hit], rem[hit], tau[hit]
        last_n = last_n[hit]
        bounces, sigma, nrm, dpl = bounces[hit], sigma[hit], nrm[hit], dpl[hit]
        stats.impacts += len(idx)
        xc = o + vel * tau[:, None] + 0.5 * a * (tau * tau)[:, None]
        # on the triangle itself (the path may cross its plane just beyond an edge)
        xc = _clamp_to_triangles(xc, tri_v, tri_f, tri_hit[hit])
        vc = vel + a * tau[:, None]
        vn_s = np.einsum("ij,ij->i", vc, nrm)
        vt = vc - vn_s[:, None] * nrm
        speed_n = np.abs(vn_s)
        an = np.einsum("ij,ij->i", a, nrm)
        rem = np.maximum(rem - tau, 0.0)
        resting = e * speed_n < params.rest_speed
        # Bounces sit `skin` off the face (exact ballistics); resting contacts sit a
        # float32-resolvable distance off it, so that sliding and settling particles
        # never sink below the face by less than Embree can see.
        gap = np.where(resting, max(skin, cast_skin), skin)
        xc += (dpl - np.einsum("ij,ij->i", nrm, xc) + sigma * gap)[:, None] * nrm
        stats.resting += int(resting.sum())
        pressing = resting & (sigma * an < 0)
        a = a - np.where(pressing, an, 0.0)[:, None] * nrm
        lose = mu * (1.0 + np.where(resting, 0.0, e)) * speed_n + \
            np.where(pressing, mu * np.abs(an) * rem, 0.0)
        vt_len = np.linalg.norm(vt, axis=1)
        keep = np.where(vt_len > 0, np.clip(1.0 - lose / np.where(vt_len > 0, vt_len, 1.0),
                                            0.0, 1.0), 0.0)
        vel = vt * keep[:, None] - np.where(resting, 0.0, e * vn_s)[:, None] * nrm
        o = xc
        last_n = sigma[:, None] * nrm
        bounces += 1
        over = bounces >= params.max_bounces
        if over.any():
            stats.overflow += int(over.sum())
            oi = idx[over]
            # out of bounces: stop at the last contact, a resolvable gap off its face
            x[oi] = o[over] + (max(skin, cast_skin) - skin) * last_n[over]
            vn_over = np.einsum("ij,ij->i", vel[over], nrm[over])
            v[oi] = vel[over] - np.where(sigma[over] * vn_over < 0, vn_over, 0.0)[:, None] * \
                nrm[over]
            keep_mask = ~over
            idx, o, vel, a, rem, bounces = (idx[keep_mask], o[keep_mask], vel[keep_mask],
                                            a[keep_mask], rem[keep_mask], bounces[keep_mask])
            last_n = last_n[keep_mask]
    return x, v, stats
