"""The ray-cast renderer on Open3D's RaycastingScene (Embree).

Rays go through the distorted camera model; Embree finds the hit triangle in
float32 and we re-intersect it in float64 (and onto an object's analytic shape
when it has one), so ground-truth depth is exact to the geometry, not to float32.
Shading is by each object's material (:mod:`acquire.render.materials`: Lambertian, GGX metal
or coated dielectric, thin translucent, subsurface): an ambient term plus each light's
irradiance where the light is not occluded (cast shadows), reflected toward the camera,
and on request one bounce of indirect light, importance-sampled and seeded
(:func:`one_bounce`). Checked against Mitsuba 3 (:mod:`acquire.render.mitsuba_reference`).
Anti-aliasing by s x s supersampling; ground truth (z-depth, normals, object ids, mask,
points) from each pixel's centre ray.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass

import numba
import numpy as np

from acquire.camera import Camera
from acquire.render._kernels import block_rows, n_blocks
from acquire.render.scene import RenderScene

log = logging.getLogger(__name__)

_SHADOW_OFFSET = 1e-5  # shadow rays start this far off the surface (m)

__all__ = ["Hits", "Render", "Bounce", "cast", "render", "shade", "one_bounce",
           "bounce_rays", "reflect_toward", "camera_rays", "centre_hits", "subsurface_spread",
           "SubsurfaceAngular", "subsurface_angular", "subsurface_weights", "exit_weights"]


@dataclass
class Hits:
    """Ray hits, float64. Arrays have one row per ray; misses have ``hit = False``.

    Attributes
    ----------
    hit : (n,) bool
    t : (n,) float64          ray parameter (inf on a miss)
    points : (n, 3) float64   world hit points
    normals : (n, 3) float64  unit shading normals, facing the ray origin
    geo_normals : (n, 3)      unit geometric normals, facing the ray origin
    obj : (n,) int64          index into scene.objects (-1 on a miss)
    tri : (n,) int64          triangle of that object (-1 on a miss)
    bary : (n, 2) float64     barycentric (u, v) in the triangle
    """

    hit: np.ndarray
    t: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    geo_normals: np.ndarray
    obj: np.ndarray
    tri: np.ndarray
    bary: np.ndarray

    def take(self, rows: np.ndarray) -> Hits:
        """The hits ``rows`` only (any index or mask)."""
        return Hits(*(getattr(self, f.name)[rows] for f in dataclasses.fields(self)))


@dataclass
class Render:
    """A rendered view.

    Attributes
    ----------
    radiance : (H, W, 3) float32   linear radiance (before the sensor)
    depth : (H, W) float32         z-depth in metres, 0 where nothing was hit
    normals : (H, W, 3) float32    world unit normals, 0 where nothing was hit
    object_id : (H, W) int32       SceneObject.object_id, -1 for background
    mask : (H, W) bool             valid (hit) pixels
    points : (H, W, 3) float32     world hit points
    """

    radiance: np.ndarray
    depth: np.ndarray
    normals: np.ndarray
    object_id: np.ndarray
    mask: np.ndarray
    points: np.ndarray


@numba.njit(parallel=True, cache=True)
def _refine_hits(o, d, hit, obj, face, V, F, N, ana_kind, ana_p, ana_n, ana_r,
                 t, points, normals, geo, bary):  # pragma: no cover
    """Moller-Trumbore in float64 on the triangle Embree found for each hit ray, the
    smooth (interpolated) and geometric normals, both turned toward the ray origin; on
    an object with an analytic shape (``ana_kind`` 1 sphere: centre ``ana_p``, radius
    ``ana_r``; 2 plane: point ``ana_p``, unit normal ``ana_n``; world frame), the exact
    intersection and normal instead. Misses get t = inf and zeros."""
    nrays = o.shape[0]
    for blk in numba.prange(n_blocks(nrays)):
        lo, hi = block_rows(blk, nrays)
        for j in range(lo, hi):
            if not hit[j]:
                t[j] = np.inf
                for a in range(3):
                    points[j, a] = 0.0
                    normals[j, a] = 0.0
                    geo[j, a] = 0.0
                bary[j, 0], bary[j, 1] = 0.0, 0.0
                continue
            f = face[j]
            i0, i1, i2 = F[f, 0], F[f, 1], F[f, 2]
            a0, a1, a2 = V[i1, 0] - V[i0, 0], V[i1, 1] - V[i0, 1], V[i1, 2] - V[i0, 2]   # e1
            b0, b1, b2 = V[i2, 0] - V[i0, 0], V[i2, 1] - V[i0, 1], V[i2, 2] - V[i0, 2]   # e2
            c0, c1, c2 = o[j, 0] - V[i0, 0], o[j, 1] - V[i0, 1], o[j, 2] - V[i0, 2]      # o - v0
            pv0 = d[j, 1] * b2 - d[j, 2] * b1
            pv1 = d[j, 2] * b0 - d[j, 0] * b2
            pv2 = d[j, 0] * b1 - d[j, 1] * b0
            det = a0 * pv0 + a1 * pv1 + a2 * pv2
            if abs(det) < 1e-300:
                det = 1e-300
            u = (c0 * pv0 + c1 * pv1 + c2 * pv2) / det
            q0 = c1 * a2 - c2 * a1
            q1 = c2 * a0 - c0 * a2
            q2 = c0 * a1 - c1 * a0
            v = (d[j, 0] * q0 + d[j, 1] * q1 + d[j, 2] * q2) / det
            tt = (b0 * q0 + b1 * q1 + b2 * q2) / det
            g0 = a1 * b2 - a2 * b1
            g1 = a2 * b0 - a0 * b2
            g2 = a0 * b1 - a1 * b0
            w = 1.0 - u - v
            s0 = w * N[i0, 0] + u * N[i1, 0] + v * N[i2, 0]
            s1 = w * N[i0, 1] + u * N[i1, 1] + v * N[i2, 1]
            s2 = w * N[i0, 2] + u * N[i1, 2] + v * N[i2, 2]
            kind = ana_kind[obj[j]]
            if kind == 1:  # from outside the first root (the faceted mesh lies inside the
                # sphere, so its hit never precedes it); from inside, the exit
                c = ana_p[obj[j]]
                oc0, oc1, oc2 = o[j, 0] - c[0], o[j, 1] - c[1], o[j, 2] - c[2]
                A = d[j, 0] * d[j, 0] + d[j, 1] * d[j, 1] + d[j, 2] * d[j, 2]
                B = 2.0 * (oc0 * d[j, 0] + oc1 * d[j, 1] + oc2 * d[j, 2])
                C = oc0 * oc0 + oc1 * oc1 + oc2 * oc2 - ana_r[obj[j]] ** 2
                sq = np.sqrt(max(B * B - 4.0 * A * C, 0.0))
                tt = (-B - sq) / (2.0 * A) if C > 0 else (-B + sq) / (2.0 * A)
                g0 = o[j, 0] + tt * d[j, 0] - c[0]
                g1 = o[j, 1] + tt * d[j, 1] - c[1]
                g2 = o[j, 2] + tt * d[j, 2] - c[2]
                s0, s1, s2 = g0, g1, g2
            elif kind == 2:
                p0, nn = ana_p[obj[j]], ana_n[obj[j]]
                tt = (((p0[0] - o[j, 0]) * nn[0] + (p0[1] - o[j, 1]) * nn[1]
                       + (p0[2] - o[j, 2]) * nn[2])
                      / (d[j, 0] * nn[0] + d[j, 1] * nn[1] + d[j, 2] * nn[2]))
                g0, g1, g2 = nn[0], nn[1], nn[2]
                s0, s1, s2 = g0, g1, g2
            gl = max(np.sqrt(g0 * g0 + g1 * g1 + g2 * g2), 1e-300)
            sl = max(np.sqrt(s0 * s0 + s1 * s1 + s2 * s2), 1e-300)
            gs = -1.0 if (g0 * d[j, 0] + g1 * d[j, 1] + g2 * d[j, 2]) / gl > 0 else 1.0
            ss = -1.0 if (s0 * d[j, 0] + s1 * d[j, 1] + s2 * d[j, 2]) / sl > 0 else 1.0
            t[j] = tt
            for a in range(3):
                points[j, a] = o[j, a] + tt * d[j, a]
            geo[j, 0], geo[j, 1], geo[j, 2] = gs * g0 / gl, gs * g1 / gl, gs * g2 / gl
            normals[j, 0], normals[j, 1], normals[j, 2] = ss * s0 / sl, ss * s1 / sl, ss * s2 / sl
            bary[j, 0], bary[j, 1] = u, v


def cast(scene: RenderScene, origins: np.ndarray, directions: np.ndarray) -> Hits:
    """Cast rays ``origins + t * directions`` (both (n, 3) float64) into the scene."""
    origins = np.asarray(origins, np.float64)    # may be one origin broadcast to all
    directions = np.ascontiguousarray(directions, np.float64)
    return _refine(scene, origins, directions, *_embree_hits(scene, origins, directions))


def _embree_hits(scene: RenderScene, origins: np.ndarray, directions: np.ndarray):
    """Embree's answer for the rays, resolved to ``(hit, obj, tri, face)``: whether each
    hits, the object, its triangle in the object and in :meth:`RenderScene.flat_arrays`."""
    import open3d as o3d

    from acquire.render import _kernels as rk

    rs, _, lut = scene.raycasting()
    face_offset = scene.flat_arrays()[3]
    n = len(origins)
    rays = np.empty((n, 6), np.float32)
    rk.pack_rays(origins, directions, rays)
    ans = rs.cast_rays(o3d.core.Tensor.from_numpy(rays))
    hit = np.empty(n, bool)
    obj = np.empty(n, np.int64)
    tri = np.empty(n, np.int64)
    face = np.empty(n, np.int64)
    rk.resolve_hits(ans["t_hit"].numpy(), ans["geometry_ids"].numpy(),
                    ans["primitive_ids"].numpy(), lut, face_offset, hit, obj, tri, face)
    return hit, obj, tri, face


def _refine(scene: RenderScene, origins: np.ndarray, directions: np.ndarray,
            hit: np.ndarray, obj: np.ndarray, tri: np.ndarray, face: np.ndarray) -> Hits:
    """The hits of rays whose triangles are known, intersected in float64."""
    V, F, N, _ = scene.flat_arrays()
    n = len(hit)
    t, bary = np.empty(n), np.empty((n, 2))     # the kernel writes every row
    points, normals, geo = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
    kind, ana_p, ana_n, ana_r = _analytic_arrays(scene)
    _refine_hits(origins, directions, hit, obj, face, V, F, N, kind, ana_p, ana_n, ana_r, t,
                 points, normals, geo, bary)
    return Hits(hit, t, points, normals, geo, obj, tri, bary)


def centre_hits(scene: RenderScene, camera: Camera, hits: Hits, supersample: int) -> Hits:
    """The hits of each pixel's centre ray, given its ``s x s`` rays' ``hits`` (a
    pixel's rays consecutive, as :func:`camera_rays`). Where all of a pixel's rays meet
    the same triangle (or the same analytic shape), the centre ray, inside their cone,
    meets it too, and is intersected in float64 without Embree; where they all miss, it
    misses. Only the other pixels (edges) are cast. The one difference from casting every
    centre ray: a surface narrower than the rays' spacing (half a pixel at 2 x 2) that all
    of them miss is not in the ground truth either, as it is not in the image. (On an
    analytic shape the hit and normal are the shape's; the triangle and barycentrics are
    those of the pixel's first ray.)"""
    from acquire.render import _kernels as rk

    ss = int(supersample) ** 2
    o, d = camera_rays(camera, 1)
    n = len(d)
    hit, obj, tri, face = (np.empty(n, bool), np.empty(n, np.int64), np.empty(n, np.int64),
                           np.empty(n, np.int64))
    todo = np.empty(n, bool)
    rk.centre_from_rays(hits.hit, hits.obj, hits.tri, ss, _analytic_arrays(scene)[0],
                        scene.flat_arrays()[3], hit, obj, tri, face, todo)
    rows = np.flatnonzero(todo)
    if rows.size:
        h2, o2, t2, f2 = _embree_hits(scene, o[rows], d[rows])
        hit[rows], obj[rows], tri[rows], face[rows] = h2, o2, t2, f2
    return _refine(scene, o, d, hit, obj, tri, face)


def _analytic_arrays(scene: RenderScene):
    """Per object: analytic kind (0 none, 1 sphere, 2 plane), point (sphere centre or a
    plane point), unit plane normal and sphere radius, all in the world frame."""
    k = len(scene.objects)
    kind = np.zeros(k, np.int64)
    pt, nrm, rad = np.zeros((k, 3)), np.zeros((k, 3)), np.zeros(k)
    for i, ob in enumerate(scene.objects):
        ana = ob.analytic
        if ana is None:
            continue
        R, tr = ob.world_from_object[:3, :3], ob.world_from_object[:3, 3]
        typ = ana.get("type")
        if typ == "sphere":
            kind[i], pt[i] = 1, R @ np.asarray(ana["center"], float) + tr
            rad[i] = float(ana["radius"]) * np.cbrt(abs(np.linalg.det(R)))
        elif typ == "plane":
            kind[i], pt[i] = 2, R @ np.asarray(ana["point"], float) + tr
            nrm[i] = R @ np.asarray(ana["normal"], float)
            nrm[i] /= np.linalg.norm(nrm[i])
        else:
            raise ValueError(f"analytic.type: expected 'sphere' or 'plane', got {typ!r}")
    return kind, pt, nrm, rad


def _albedo_tables(scene: RenderScene):
    """Per object, what :func:`acquire.render._kernels.albedo_fast` needs: the albedo
    code (constant, 'fbm', or other), the object-from-world transform, the texture's
    scale, contrast, colour and permutation."""
    from acquire.render import _kernels as rk
    from procgen.noise.perlin import perm_table

    k = len(scene.objects)
    code = np.zeros(k, np.int64)
    Tinv = np.zeros((k, 3, 4))
    scale, contrast = np.zeros(k), np.zeros(k)
    base = np.zeros((k, 3))
    perms = np.zeros((k, 512), np.int64)
    for i, obj in enumerate(scene.objects):
        m = obj.material
        Tinv[i] = np.linalg.inv(obj.world_from_object)[:3]
        scale[i], contrast[i], base[i] = m.scale, m.contrast, m.albedo
        if m.kind == "constant":
            code[i] = rk.CONSTANT
        elif m.kind == "solid" and m.texture == "fbm":
            code[i] = rk.FBM
            perms[i] = perm_table(m.seed)
    return code, Tinv, scale, contrast, base, perms


def albedo(scene: RenderScene, hits: Hits) -> np.ndarray:
    """Material albedo ``(n, 3)`` at the hits (0 on misses)."""
    from acquire.render.materials import FBM_OCTAVES
    from acquire.render import _kernels as rk

    out = np.zeros((len(hits.hit), 3))
    code, Tinv, scale, contrast, base, perms = _albedo_tables(scene)
    if np.any(code != rk.OTHER):
        rk.albedo_fast(hits.points, hits.hit, np.maximum(hits.obj, 0), code, Tinv, scale,
                       contrast, base, perms, FBM_OCTAVES, out)
    _, parts, _ = scene.raycasting()
    for i, obj in enumerate(scene.objects):
        if code[i] != rk.OTHER:
            continue
        sel = np.flatnonzero(hits.obj == i)
        if sel.size == 0:
            continue
        p_obj = hits.points[sel] @ Tinv[i, :, :3].T + Tinv[i, :, 3]
        uvs = None
        if obj.vertex_uvs is not None:
            f = parts[i][1][hits.tri[sel]]
            u, v = hits.bary[sel, 0:1], hits.bary[sel, 1:2]
            uvs = ((1 - u - v) * obj.vertex_uvs[f[:, 0]] + u * obj.vertex_uvs[f[:, 1]]
                   + v * obj.vertex_uvs[f[:, 2]])
        out[sel] = obj.material.albedo_at(p_obj, uvs)
    return out


@numba.njit(parallel=True, cache=True)
def _shadow_rays(points, geo, dirs, max_t, offset):  # pragma: no cover
    """float32 ``(n, 6)`` rays from each point, nudged by ``offset`` off the surface on the
    side that faces the light, to the light (``dirs * max_t``: t = 1 at the light)."""
    n = points.shape[0]
    rays = np.empty((n, 6), np.float32)
    for i in numba.prange(n):
        c = geo[i, 0] * dirs[i, 0] + geo[i, 1] * dirs[i, 1] + geo[i, 2] * dirs[i, 2]
        k = offset * (1.0 if c > 0 else (-1.0 if c < 0 else 0.0))
        for a in range(3):
            rays[i, a] = points[i, a] + k * geo[i, a]
            rays[i, 3 + a] = dirs[i, a] * max_t[i]
    return rays


def visibility(scene: RenderScene, light, points: np.ndarray, geo_normals: np.ndarray,
               *, offset: float = _SHADOW_OFFSET) -> np.ndarray:
    """``(n,) bool``: True where ``light`` reaches the surface points unoccluded."""
    import open3d as o3d

    if len(points) == 0:
        return np.zeros(0, bool)
    rs, _, _ = scene.raycasting()
    dirs, max_t = light.shadow_rays(points)
    rays = _shadow_rays(np.ascontiguousarray(points, np.float64),
                        np.ascontiguousarray(geo_normals, np.float64),
                        np.ascontiguousarray(dirs, np.float64),
                        np.ascontiguousarray(max_t, np.float64), float(offset))
    occluded = rs.test_occlusions(o3d.core.Tensor(rays), tnear=0.0, tfar=1.0 - 1e-6).numpy()
    return ~occluded.astype(bool)


def shade(scene: RenderScene, hits: Hits, *, lights=None, ambient=None,
          view_dirs: np.ndarray | None = None, bounces: int = 0,
          rng: np.random.Generator | None = None) -> np.ndarray:
    """Radiance ``(n, 3)`` at the hits (direct light with shadows plus an ambient term);
    the scene background on misses.

    Lambertian surfaces reflect ``albedo * irradiance``; a GGX material
    (:class:`acquire.render.materials.Material` ``brdf``) reflects ``pi f(wi, wo) * irradiance``
    per light, which needs the rays' ``view_dirs`` (from the camera; any length).
    ``bounces = 1`` adds one bounce of indirect light (:func:`one_bounce`; needs
    ``view_dirs`` and ``rng``).
    """
    if bounces and (view_dirs is None or rng is None):
        raise ValueError("bounces: indirect light needs the view directions and an rng")
    alb = albedo(scene, hits)
    out = _direct(scene, hits, lights=lights, ambient=ambient, view_dirs=view_dirs, alb=alb)
    if bounces:
        h = np.flatnonzero(hits.hit)
        _add_one_bounce(out, h, scene, hits, h, np.asarray(view_dirs, np.float64)[h],
                        lights=lights, rng=rng, alb=alb[h])
    return out


def reflect_toward(scene: RenderScene, hits: Hits, rows: np.ndarray, source: np.ndarray,
                   view_dirs: np.ndarray, alb: np.ndarray | None = None) -> np.ndarray:
    """``pi f`` ``(len(rows), 3)`` at the hits ``rows`` for light from the point
    ``source`` (a projector's centre) seen along ``view_dirs``: a Lambertian surface's
    albedo, a glossy one's view-dependent reflectance (``alb``: their albedo, when the
    caller has it already)."""
    sub = hits.take(rows)
    alb = albedo(scene, sub) if alb is None else np.asarray(alb, np.float64)
    wi = np.asarray(source, np.float64) - sub.points
    wi /= np.maximum(np.linalg.norm(wi, axis=1, keepdims=True), 1e-300)
    wo = -view_dirs / np.linalg.norm(view_dirs, axis=1, keepdims=True)
    out = alb.copy()
    for i, o in enumerate(scene.objects):
        sel = np.flatnonzero(sub.obj == i)
        if sel.size and o.material.brdf not in ("lambert", "subsurface"):
            out[sel] = o.material.reflectance(wi[sel], wo[sel], sub.normals[sel], alb[sel])
    return out


def _p_spec(material) -> float:
    """Probability of sampling a material's specular lobe (0: cosine only)."""
    return {"conductor": 1.0, "dielectric": 0.5}.get(material.brdf, 0.0)


@dataclass
class Bounce:
    """Second-bounce rays drawn at some hits (:func:`bounce_rays`).

    Attributes
    ----------
    rows : (k,) int64
        Which of the given hits continue (the others reflect nothing indirect).
    weight : (k, 3) float64
        ``f cos / pdf`` of each (the factor on the radiance coming back along ``wi``).
    wi : (k, 3) float64
        The directions drawn, unit.
    hits : Hits
        Where they meet the scene (``hit`` False: nothing comes back).
    """

    rows: np.ndarray
    weight: np.ndarray
    wi: np.ndarray
    hits: Hits


def bounce_rays(scene: RenderScene, hits: Hits, rows: np.ndarray, view_dirs: np.ndarray, *,
                rng: np.random.Generator, alb: np.ndarray | None = None) -> Bounce:
    """One importance-sampled direction per hit of ``rows``, drawn by its material
    (:func:`acquire.render.brdf.sample_mixture`: cosine for Lambertian, GGX normals for metals,
    both for a coated dielectric), cast into the scene. What comes back along them is
    the caller's (a light's direct light for :func:`one_bounce`, each pattern's for a
    structured-light capture): the indirect radiance is ``weight * L``. ``alb``: the
    albedo at the hits ``rows``, when the caller has it already."""
    from acquire.render.brdf import sample_mixture
    from acquire.render import _kernels as rk

    rows = np.flatnonzero(rows) if np.asarray(rows).dtype == bool else rows
    rows = np.asarray(rows, np.int64)
    k = len(rows)
    view_dirs = np.ascontiguousarray(view_dirs, np.float64)
    alb = albedo(scene, hits.take(rows)) if alb is None else np.asarray(alb, np.float64)
    u = rng.random((k, 3))
    wi, pdf = np.zeros((k, 3)), np.zeros(k)
    refl = np.zeros((k, 3))
    thin = np.zeros(k, bool)
    lam = np.array([o.material.brdf == "lambert" for o in scene.objects])
    if lam.any():
        rk.cosine_bounce(hits.normals, hits.obj, rows, view_dirs, u, lam, alb, wi, pdf, refl)
    obj = hits.obj[rows] if not lam.all() else None
    for i, o in enumerate(scene.objects):
        sel = () if lam[i] else np.flatnonzero(obj == i)
        if len(sel):
            m = o.material
            N = hits.normals[rows[sel]]
            wo = -view_dirs[sel] / np.linalg.norm(view_dirs[sel], axis=1, keepdims=True)
            wi[sel], pdf[sel] = sample_mixture(wo, N, u[sel], roughness=m.roughness,
                                               p_spec=_p_spec(m))
            if m.brdf == "translucent":   # through the sheet with its transmission
                t = m.transmission
                through = u[sel, 2] < t
                cn = np.einsum("ij,ij->i", wi[sel], N)
                wi[sel[through]] -= 2.0 * (cn[through])[:, None] * N[through]
                pdf[sel] *= np.where(through, t, 1.0 - t)
                thin[sel] = True
            refl[sel] = m.reflectance(wi[sel], wo, N, alb[sel])
    go, origin = np.empty(k, bool), np.empty((k, 3))
    weight, cos = np.empty((k, 3)), np.empty(k)
    eps = 1e-6 * float(np.linalg.norm(np.ptp(scene.bounds(), axis=0))) + 1e-9
    rk.bounce_start(hits.points, hits.geo_normals, hits.normals, rows, wi, pdf, refl, thin,
                    eps, go, origin, weight, cos)
    go = np.flatnonzero(go)
    sec = cast(scene, origin[go], wi[go])
    weight = weight[go]
    return Bounce(rows=go, weight=weight, wi=wi[go], hits=sec)


def one_bounce(scene: RenderScene, hits: Hits, rows: np.ndarray, view_dirs: np.ndarray, *,
               lights=None, rng: np.random.Generator,
               alb: np.ndarray | None = None) -> np.ndarray:
    """Indirect radiance ``(len(rows), 3)`` at the hits ``rows``: light that reached
    another surface directly and is reflected once more toward ``view_dirs``
    (:func:`bounce_rays`; the surface met is lit by direct light only, no ambient, no
    further bounce). Rays that meet nothing bring nothing (the background is a backdrop,
    not a light). Averaged over the supersampled rays of a pixel; seeded by ``rng``.
    ``alb``: the albedo at the hits ``rows``, when the caller has it already.
    """
    out = np.zeros((len(rows), 3))
    _add_one_bounce(out, np.arange(len(rows)), scene, hits, rows, view_dirs, lights=lights,
                    rng=rng, alb=alb)
    return out


def _add_one_bounce(out: np.ndarray, out_rows: np.ndarray, scene: RenderScene, hits: Hits,
                    rows: np.ndarray, view_dirs: np.ndarray, *, lights, rng, alb) -> None:
    """:func:`one_bounce`'s radiance at the hits ``rows`` added into ``out[out_rows]``."""
    from acquire.render import _kernels as rk

    lights = scene.lights if lights is None else lights
    b = bounce_rays(scene, hits, rows, view_dirs, rng=rng, alb=alb)
    if b.rows.size:
        L = _direct(scene, b.hits, lights=lights, ambient=0.0, view_dirs=b.wi)
        rk.add_indirect(out, np.asarray(out_rows, np.int64), b.rows, b.weight, L, b.hits.hit)


def _direct(scene: RenderScene, hits: Hits, *, lights=None, ambient=None,
            view_dirs: np.ndarray | None = None, alb: np.ndarray | None = None) -> np.ndarray:
    """Direct light and the ambient term (see :func:`shade`); ``alb`` the albedo at every
    hit, when the caller has it."""
    lights = scene.lights if lights is None else lights
    ambient = scene.ambient if ambient is None else ambient
    n = len(hits.hit)
    glossy = [i for i, o in enumerate(scene.objects) if o.material.brdf != "lambert"]
    if not glossy or view_dirs is None:  # Lambertian only: albedo times irradiance
        return _lambert(scene, hits, lights, float(ambient),
                        albedo(scene, hits) if alb is None else alb)
    out = np.broadcast_to(scene.background, (n, 3)).astype(np.float64).copy()
    h = np.flatnonzero(hits.hit)
    if h.size == 0:
        return out
    P, N, G = hits.points[h], hits.normals[h], hits.geo_normals[h]
    alb = (albedo(scene, hits) if alb is None else alb)[h]
    wo = -np.asarray(view_dirs, np.float64)[h]
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    rad = alb * float(ambient)
    thin = np.isin(hits.obj[h], [i for i, o in enumerate(scene.objects)
                                 if o.material.brdf == "translucent"])
    for light, lit, vis, irr in _lit(scene, lights, P, N, G, two_sided=thin):
        k = lit[vis]
        wi = light.shadow_rays(P[k])[0]
        wi = wi / np.linalg.norm(wi, axis=1, keepdims=True)
        refl = np.empty((k.size, 3))
        for i, obj in enumerate(scene.objects):
            sel = np.flatnonzero(hits.obj[h[k]] == i)
            if sel.size:
                refl[sel] = obj.material.reflectance(wi[sel], wo[k[sel]], N[k[sel]],
                                                     alb[k[sel]])
        rad[k] += refl * irr[k]
    out[h] = rad
    return out


def _lambert(scene: RenderScene, hits: Hits, lights, ambient: float,
             alb: np.ndarray) -> np.ndarray:
    """Radiance of a Lambertian scene: albedo times (ambient + each light's unoccluded
    irradiance); point and directional lights in compiled kernels, any other light
    (laser sheet, projector) through the light protocol."""
    import open3d as o3d

    from acquire.render.lights import FAR, DirectionalLight, PointLight
    from acquire.render import _kernels as rk

    n = len(hits.hit)
    E = np.full((n, 3), ambient)
    others, shadowed = [], []     # shadowed: (light, irradiance, rows it reaches)
    for light in lights:
        if isinstance(light, PointLight):
            kind, vec = rk.POINT, np.asarray(light.position, np.float64)
        elif isinstance(light, DirectionalLight):
            kind, vec = rk.DIRECTIONAL, np.asarray(light.direction, np.float64)
        else:
            others.append(light)
            continue
        irr = np.empty(n)
        rk.light_irradiance(hits.points, hits.normals, hits.hit, kind, vec,
                            float(light.intensity), irr)
        rows = np.flatnonzero(irr > 0)
        if rows.size:
            shadowed.append((light, kind, vec, irr, rows))
    if shadowed:   # every light's shadow rays in one call
        ends = np.cumsum([0] + [len(r) for *_, r in shadowed])
        rays = np.empty((ends[-1], 6), np.float32)
        for (_, kind, vec, _, rows), a, b in zip(shadowed, ends[:-1], ends[1:], strict=True):
            rk.light_shadow_rays(hits.points, hits.geo_normals, rows, kind, vec, FAR,
                                 _SHADOW_OFFSET, rays[a:b])
        occluded = scene.raycasting()[0].test_occlusions(
            o3d.core.Tensor.from_numpy(rays), tnear=0.0, tfar=1.0 - 1e-6).numpy()
        for (light, _, _, irr, rows), a, b in zip(shadowed, ends[:-1], ends[1:], strict=True):
            rk.add_light(E, rows, irr, occluded[a:b], np.asarray(light.color, np.float64))
    if others:
        h = np.flatnonzero(hits.hit)
        P, N, G = hits.points[h], hits.normals[h], hits.geo_normals[h]
        for _light, lit, vis, e in _lit(scene, others, P, N, G):
            E[h[lit[vis]]] += e[lit[vis]]
    rk.lambert_out(hits.hit, np.ascontiguousarray(alb, np.float64), E,
                   np.asarray(scene.background, np.float64), E)
    return E


def _lit(scene: RenderScene, lights, P, N, G, two_sided=None):
    """Per light: itself, the hits it could light, which of those it reaches, irradiance.
    ``two_sided`` marks hits lit from either side (thin translucent surfaces: the light
    behind them arrives through them)."""
    for light in lights:
        if two_sided is not None and two_sided.any():
            back = two_sided & (np.einsum("ij,ij->i", light.shadow_rays(P)[0], N) < 0)
            irr = light.irradiance(P, np.where(back[:, None], -N, N))
        else:
            irr = light.irradiance(P, N)
        lit = np.flatnonzero(np.any(irr > 0, axis=1))
        if lit.size:
            yield light, lit, visibility(scene, light, P[lit], G[lit]), irr


def subsurface_weights(scene: RenderScene, hits: Hits, rows: np.ndarray, wi: np.ndarray,
                       wo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """At the hits ``rows`` of subsurface materials, for light from ``wi`` seen from
    ``wo`` (unit, ``(len(rows), 3)``), per unit albedo and irradiance, how the angular
    parts of the transport depart from a Lambertian surface's:

    - ``entry - 1``: the diffusion's weight at the light's incidence
      (:meth:`acquire.render.materials.Material.diffusion_weight`) less 1;
    - ``single - share``: the light scattered once
      (:meth:`~acquire.render.materials.Material.single_scattering`) less its broad-light share
      (:meth:`~acquire.render.materials.Material.subsurface_shares`);

    both ``(len(rows), 3)``, zero on other materials."""
    entry = np.zeros((len(rows), 3))
    single = np.zeros((len(rows), 3))
    obj = hits.obj[rows]
    for i, o in enumerate(scene.objects):
        m = o.material
        if m.brdf != "subsurface":
            continue
        k = np.flatnonzero(obj == i)
        if k.size:
            n = hits.normals[rows[k]]
            entry[k] = m.diffusion_weight(np.einsum("ij,ij->i", wi[k], n)) - 1.0
            single[k] = (m.single_scattering(wi[k], wo[k], n)
                         - m.subsurface_shares()[1][None, :])
    return entry, single


@dataclass
class SubsurfaceAngular:
    """The angular parts of subsurface transport on the rows of a view's hits
    (:func:`subsurface_angular`), for :func:`subsurface_spread`: ``entry``, irradiance
    to add to what the diffusion receives; ``exit``, the diffusion's weight toward the
    viewer; ``single``, radiance scattered once beyond its broad-light share. ``(n,)``
    (monochrome) or ``(n, 3)``."""

    entry: np.ndarray
    exit: np.ndarray
    single: np.ndarray


def exit_weights(scene: RenderScene, hits: Hits, view_dirs: np.ndarray) -> np.ndarray:
    """``(n, 3)``: the diffusion's weight toward the viewer at every hit of a subsurface
    material (1 elsewhere), for rays along ``view_dirs``."""
    out = np.ones((len(hits.hit), 3))
    for i, o in enumerate(scene.objects):
        if o.material.brdf != "subsurface":
            continue
        k = np.flatnonzero(hits.hit & (hits.obj == i))
        if k.size:
            d = np.asarray(view_dirs, np.float64)[k]
            mu = -np.einsum("ij,ij->i", d, hits.normals[k]) / np.linalg.norm(d, axis=1)
            out[k] = o.material.diffusion_weight(mu)
    return out


def subsurface_angular(scene: RenderScene, hits: Hits, view_dirs: np.ndarray, *,
                       lights=None, alb: np.ndarray | None = None) -> SubsurfaceAngular:
    """The :class:`SubsurfaceAngular` parts of ``lights`` (the scene's by default) on
    the hits of subsurface materials: each light's irradiance (with its shadow) times
    :func:`subsurface_weights` (and the albedo, for the single scattering), summed over
    the lights; the exit weights of :func:`exit_weights`. Light that arrives broad
    (ambient, the bounce) enters with weight 1 and scatters once by its share."""
    lights = scene.lights if lights is None else lights
    n = len(hits.hit)
    entry, single = np.zeros((n, 3)), np.zeros((n, 3))
    sub = [i for i, o in enumerate(scene.objects) if o.material.brdf == "subsurface"]
    h = np.flatnonzero(hits.hit & np.isin(hits.obj, sub))
    if h.size:
        alb = (albedo(scene, hits) if alb is None else alb)[h]
        P, N, G = hits.points[h], hits.normals[h], hits.geo_normals[h]
        wo = -np.asarray(view_dirs, np.float64)[h]
        wo /= np.linalg.norm(wo, axis=1, keepdims=True)
        for light, lit, vis, irr in _lit(scene, lights, P, N, G):
            k = lit[vis]
            wi = light.shadow_rays(P[k])[0]
            wi = wi / np.linalg.norm(wi, axis=1, keepdims=True)
            e, s1 = subsurface_weights(scene, hits, h[k], wi, wo[k])
            entry[h[k]] += irr[k] * e
            single[h[k]] += alb[k] * irr[k] * s1
    return SubsurfaceAngular(entry, exit_weights(scene, hits, view_dirs), single)


def subsurface_spread(scene: RenderScene, camera: Camera, hits: Hits, supersample: int,
                      rad: np.ndarray, alb: np.ndarray, *,
                      angular: SubsurfaceAngular | None = None) -> np.ndarray:
    """The radiance ``rad`` (``(n,)`` or ``(n, 3)``, one row per ray of
    ``camera.pixel_grid(supersample)``, subsurface materials shaded as Lambertian) with
    the light falling on subsurface materials carried under their surface
    (:mod:`acquire.render.subsurface`): on each such object the irradiance ``rad / alb`` is
    spread by its dipole's Gaussian mixture (:func:`acquire.render.subsurface.spread_irradiance`,
    per colour channel, or on the mean albedo for a monochrome ``rad``), weighted by the
    diffusion's share of the albedo; the single-scattering share stays where the light
    fell; both are multiplied back by the albedo there, so the texture stays sharp while
    light patterns blur, and an evenly lit surface reflects as much as a Lambertian one.
    ``angular`` (:func:`subsurface_angular`) adds the angular shapes: the diffusion's
    weights at the entry and toward the viewer, and the single scattering's. The spread
    is in the image, at the object's median depth, within the
    object's pixels: foreshortening and light crossing between parts of one object that
    are far apart in depth are not modelled."""
    from acquire.render.subsurface import gaussian_mixture, spread_irradiance

    idx = [i for i, o in enumerate(scene.objects) if o.material.brdf == "subsurface"]
    if not idx:
        return rad
    s = int(supersample)
    H, W = camera.height, camera.width
    mono = rad.ndim == 1
    a = np.asarray(alb, np.float64)
    a = a.mean(axis=1) if (mono and a.ndim == 2) else a
    E = np.where(a > 1e-12, rad / np.maximum(a, 1e-12), 0.0)
    E = E[:, None] if mono else E
    c = E.shape[1]

    def rows(x):      # an angular part as (n, c)
        x = np.asarray(x, np.float64)
        if mono and x.ndim == 2:
            x = x.mean(axis=1)
        return x[:, None] if x.ndim == 1 else x

    E_in = E if angular is None else E + rows(angular.entry)

    def grid(x):      # rows of the rays -> the (H s, W s, ...) image of the sub-samples
        return x.reshape(H, W, s, s, *x.shape[1:]).swapaxes(1, 2).reshape(
            H * s, W * s, *x.shape[1:])

    Eg = grid(E_in)
    out = np.array(rad, np.float64, copy=True)
    for i in idx:
        m = scene.objects[i].material
        sel = hits.obj == i
        if not sel.any():
            continue
        px_per_m = camera.fx * s / float(np.median(hits.t[sel]))
        mask = grid(sel)
        multiple, once = m.subsurface_shares()
        dipoles = ([dataclasses.replace(m.dipole(0), albedo=max(float(np.mean(m.albedo)),
                                                                1e-3))]
                   if mono else [m.dipole(k) for k in range(3)])
        spread = np.empty_like(Eg)
        for k, dip in enumerate(dipoles):
            sig, w = gaussian_mixture(dip)
            spread[..., k] = spread_irradiance(Eg[..., k], mask, sig * px_per_m, w)
        back = spread.reshape(H, s, W, s, c).swapaxes(1, 2).reshape(-1, c)
        if angular is not None:
            back = back * rows(angular.exit)
        if mono:
            back = back[:, 0] * float(np.mean(multiple)) + E[:, 0] * float(np.mean(once))
        else:
            back = back * multiple + E * once
        out[sel] = (back * a)[sel]
    if angular is not None:
        out += rows(angular.single)[:, 0] if mono else rows(angular.single)
    return out


def camera_rays(camera: Camera, supersample: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """``camera.rays(camera.pixel_grid(supersample=s))``: origins and directions of the
    s x s rays of every pixel (a compiled kernel for an undistorted camera, whose
    origins are one read-only row broadcast to every ray)."""
    from acquire.render import _kernels as rk

    s = int(supersample)
    if np.any(camera.dist) or s < 1:
        return camera.rays(camera.pixel_grid(supersample=s))
    n = camera.height * camera.width * s * s
    d = np.empty((n, 3))
    Tw = camera.world_from_cam
    rk.pinhole_rays(camera.height, camera.width, s, float(camera.fx), float(camera.fy),
                    float(camera.cx), float(camera.cy), np.ascontiguousarray(Tw[:3, :3]), d)
    return np.broadcast_to(Tw[:3, 3].astype(np.float64), (n, 3)), d


def render(scene: RenderScene, camera: Camera, *, supersample: int = 2, lights=None,
           ambient=None, bounces: int = 0, seed: int = 0) -> Render:
    """Render ``scene`` from ``camera``.

    Parameters
    ----------
    scene : RenderScene
    camera : Camera
    supersample : int
        s x s rays per pixel for anti-aliasing (1 = one centre ray).
    lights, ambient : optional
        Override the scene's lights / ambient term (e.g. the laser alone).
    bounces : {0, 1}
        One bounce of indirect light (inter-reflections), one importance-sampled
        direction per supersampled ray: noise falls as ``1 / supersample``.
    seed : int
        Seeds the indirect directions (same seed, same bytes).
    """
    from acquire.render import _kernels as rk

    if bounces not in (0, 1):
        raise ValueError(f"bounces: expected 0 or 1, got {bounces!r}")
    s = int(supersample)
    H, W = camera.height, camera.width
    o, d = camera_rays(camera, s)
    hits = cast(scene, o, d)
    rad = shade(scene, hits, lights=lights, ambient=ambient, view_dirs=d, bounces=bounces,
                rng=np.random.default_rng(seed) if bounces else None)
    if any(o.material.brdf == "subsurface" for o in scene.objects):
        alb = albedo(scene, hits)
        rad = subsurface_spread(scene, camera, hits, s, rad, alb, angular=subsurface_angular(
            scene, hits, d, lights=lights, alb=alb))
    radiance = np.empty((H * W, 3), np.float32)
    rk.pixel_mean(rad, s * s, radiance)
    radiance = radiance.reshape(H, W, 3)
    centre = hits if s == 1 else centre_hits(scene, camera, hits, s)
    ids = np.array([ob.object_id for ob in scene.objects] + [-1], np.int32)
    depth, oid = np.empty(H * W, np.float32), np.empty(H * W, np.int32)
    normals, points = np.empty((H * W, 3), np.float32), np.empty((H * W, 3), np.float32)
    rk.ground_truth(centre.hit, centre.t, centre.obj, centre.normals, centre.points, ids,
                    depth, oid, normals, points)
    return Render(radiance=radiance, depth=depth.reshape(H, W),
                  normals=normals.reshape(H, W, 3), object_id=oid.reshape(H, W),
                  mask=centre.hit.reshape(H, W), points=points.reshape(H, W, 3))
