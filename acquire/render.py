"""The ray-cast renderer on Open3D's RaycastingScene (Embree).

Rays go through the distorted camera model; Embree finds the hit triangle in
float32 and we re-intersect it in float64 (and onto an object's analytic shape
when it has one), so ground-truth depth is exact to the geometry, not to float32.
Shading is Lambertian: ambient plus each light's irradiance where the light is
not occluded (cast shadows). Anti-aliasing by s x s supersampling; ground truth
(z-depth, normals, object ids, mask, points) from each pixel's centre ray.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from acquire.camera import Camera
from acquire.scene import RenderScene

log = logging.getLogger(__name__)

__all__ = ["Hits", "Render", "cast", "render", "shade"]


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


def cast(scene: RenderScene, origins: np.ndarray, directions: np.ndarray) -> Hits:
    """Cast rays ``origins + t * directions`` (both (n, 3) float64) into the scene."""
    import open3d as o3d

    rs, parts, lut = scene.raycasting()
    n = len(origins)
    rays = np.concatenate([origins, directions], axis=1).astype(np.float32)
    ans = rs.cast_rays(o3d.core.Tensor(rays))
    t32 = ans["t_hit"].numpy()
    hit = np.isfinite(t32)
    gid = ans["geometry_ids"].numpy().astype(np.int64)
    pid = ans["primitive_ids"].numpy().astype(np.int64)
    obj = np.full(n, -1, np.int64)
    obj[hit] = lut[gid[hit]]
    tri = np.where(hit, pid, -1)
    t = np.full(n, np.inf)
    points = np.zeros((n, 3))
    normals = np.zeros((n, 3))
    geo = np.zeros((n, 3))
    bary = np.zeros((n, 2))
    for i, (vw, f, vn) in enumerate(parts):
        sel = np.flatnonzero(obj == i)
        if sel.size == 0:
            continue
        o = origins[sel]
        d = directions[sel]
        tris = f[tri[sel]]
        a, b, c = vw[tris[:, 0]], vw[tris[:, 1]], vw[tris[:, 2]]
        # Moller-Trumbore in float64 on the triangle Embree found.
        e1, e2 = b - a, c - a
        pv = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, pv)
        det = np.where(np.abs(det) < 1e-300, 1e-300, det)
        tv = o - a
        u = np.einsum("ij,ij->i", tv, pv) / det
        qv = np.cross(tv, e1)
        v = np.einsum("ij,ij->i", d, qv) / det
        tt = np.einsum("ij,ij->i", e2, qv) / det
        gn = np.cross(e1, e2)
        gn /= np.maximum(np.linalg.norm(gn, axis=1, keepdims=True), 1e-300)
        w = 1.0 - u - v
        sn = w[:, None] * vn[tris[:, 0]] + u[:, None] * vn[tris[:, 1]] + v[:, None] * vn[tris[:, 2]]
        ana = scene.objects[i].analytic
        if ana is not None:
            tt, sn, gn = _refine_analytic(ana, scene.objects[i].world_from_object, o, d, tt)
        sn /= np.maximum(np.linalg.norm(sn, axis=1, keepdims=True), 1e-300)
        # two-sided: normals face the ray origin
        flip = np.einsum("ij,ij->i", gn, d) > 0
        gn[flip] *= -1
        sflip = np.einsum("ij,ij->i", sn, d) > 0
        sn[sflip] *= -1
        t[sel] = tt
        points[sel] = o + tt[:, None] * d
        normals[sel] = sn
        geo[sel] = gn
        bary[sel] = np.stack([u, v], axis=1)
    return Hits(hit, t, points, normals, geo, obj, tri, bary)


def _refine_analytic(ana, T, o, d, t_mesh):
    """Exact t and normals on an analytic sphere or plane (object frame -> world)."""
    kind = ana.get("type")
    R, tr = T[:3, :3], T[:3, 3]
    if kind == "sphere":
        c = R @ np.asarray(ana["center"], float) + tr
        r = float(ana["radius"]) * np.cbrt(abs(np.linalg.det(R)))
        oc = o - c
        A = np.einsum("ij,ij->i", d, d)
        B = 2 * np.einsum("ij,ij->i", oc, d)
        C = np.einsum("ij,ij->i", oc, oc) - r * r
        disc = np.maximum(B * B - 4 * A * C, 0.0)
        sq = np.sqrt(disc)
        t1 = (-B - sq) / (2 * A)
        t2 = (-B + sq) / (2 * A)
        # From outside the sphere the first hit is the entry point (the faceted mesh
        # lies inside the sphere, so the mesh hit never precedes it); from inside, the exit.
        tt = np.where(C > 0, t1, t2)
        n = o + tt[:, None] * d - c
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        return tt, n, n.copy()
    if kind == "plane":
        p0 = R @ np.asarray(ana["point"], float) + tr
        nn = R @ np.asarray(ana["normal"], float)
        nn /= np.linalg.norm(nn)
        tt = ((p0 - o) @ nn) / (d @ nn)
        n = np.broadcast_to(nn, o.shape).copy()
        return tt, n, n.copy()
    raise ValueError(f"analytic.type: expected 'sphere' or 'plane', got {kind!r}")


def albedo(scene: RenderScene, hits: Hits) -> np.ndarray:
    """Material albedo ``(n, 3)`` at the hits (0 on misses)."""
    out = np.zeros((len(hits.hit), 3))
    _, parts, _ = scene.raycasting()
    for i, obj in enumerate(scene.objects):
        sel = np.flatnonzero(hits.obj == i)
        if sel.size == 0:
            continue
        Tinv = np.linalg.inv(obj.world_from_object)
        p_obj = hits.points[sel] @ Tinv[:3, :3].T + Tinv[:3, 3]
        uvs = None
        if obj.vertex_uvs is not None:
            f = parts[i][1][hits.tri[sel]]
            u, v = hits.bary[sel, 0:1], hits.bary[sel, 1:2]
            uvs = ((1 - u - v) * obj.vertex_uvs[f[:, 0]] + u * obj.vertex_uvs[f[:, 1]]
                   + v * obj.vertex_uvs[f[:, 2]])
        out[sel] = obj.material.albedo_at(p_obj, uvs)
    return out


def visibility(scene: RenderScene, light, points: np.ndarray, geo_normals: np.ndarray,
               *, offset: float = 1e-5) -> np.ndarray:
    """``(n,) bool``: True where ``light`` reaches the surface points unoccluded."""
    import open3d as o3d

    if len(points) == 0:
        return np.zeros(0, bool)
    rs, _, _ = scene.raycasting()
    dirs, max_t = light.shadow_rays(points)
    # Start on the side of the surface that faces the light.
    side = np.sign(np.einsum("ij,ij->i", geo_normals, dirs))[:, None]
    origins = points + offset * side * geo_normals
    scaled = dirs * max_t[:, None]
    rays = np.concatenate([origins, scaled], axis=1).astype(np.float32)
    occluded = rs.test_occlusions(o3d.core.Tensor(rays), tnear=0.0, tfar=1.0 - 1e-6).numpy()
    return ~occluded.astype(bool)


def shade(scene: RenderScene, hits: Hits, *, lights=None, ambient=None) -> np.ndarray:
    """Lambertian radiance ``(n, 3)`` at the hits; the scene background on misses."""
    lights = scene.lights if lights is None else lights
    ambient = scene.ambient if ambient is None else ambient
    n = len(hits.hit)
    out = np.broadcast_to(scene.background, (n, 3)).astype(np.float64).copy()
    h = np.flatnonzero(hits.hit)
    if h.size == 0:
        return out
    P, N, G = hits.points[h], hits.normals[h], hits.geo_normals[h]
    E = np.full((h.size, 3), float(ambient))
    for light in lights:
        irr = light.irradiance(P, N)
        lit = np.flatnonzero(np.any(irr > 0, axis=1))
        if lit.size:
            vis = visibility(scene, light, P[lit], G[lit])
            E[lit[vis]] += irr[lit[vis]]
    out[h] = albedo(scene, hits)[h] * E
    return out


def render(scene: RenderScene, camera: Camera, *, supersample: int = 2, lights=None,
           ambient=None) -> Render:
    """Render ``scene`` from ``camera``.

    Parameters
    ----------
    scene : RenderScene
    camera : Camera
    supersample : int
        s x s rays per pixel for anti-aliasing (1 = one centre ray).
    lights, ambient : optional
        Override the scene's lights / ambient term (e.g. the laser alone).
    """
    s = int(supersample)
    H, W = camera.height, camera.width
    px = camera.pixel_grid(supersample=s)
    o, d = camera.rays(px)
    hits = cast(scene, o, d)
    rad = shade(scene, hits, lights=lights, ambient=ambient)
    radiance = rad.reshape(H, W, s * s, 3).mean(axis=2).astype(np.float32)
    if s == 1:
        centre = hits
    else:
        o, d = camera.rays(camera.pixel_grid(supersample=1))
        centre = cast(scene, o, d)
    mask = centre.hit.reshape(H, W)
    depth = np.where(centre.hit, centre.t, 0.0).reshape(H, W).astype(np.float32)
    ids_lut = np.array([ob.object_id for ob in scene.objects] + [-1], np.int32)
    oid = ids_lut[centre.obj].reshape(H, W)
    return Render(radiance=radiance, depth=depth,
                  normals=centre.normals.reshape(H, W, 3).astype(np.float32),
                  object_id=oid, mask=mask,
                  points=centre.points.reshape(H, W, 3).astype(np.float32))
