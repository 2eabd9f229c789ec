"""The laser line projector (a sheet of light) and its fast frame renderer.

A line laser spreads a beam into a planar fan: the sheet. Across the sheet the
intensity is Gaussian (standard deviation ``thickness``, metres); along it the fan
covers ``fan_angle`` radians around the central direction and spreads as ``1/r``.
:class:`LaserSheet` implements the light protocol of :mod:`acquire.render.lights`, so it
renders with :func:`acquire.render.renderer.render` like any lamp.

:class:`LaserRenderer` renders a scan's frames, the hot path: one camera ray per pixel, the
ambient term from the albedo alone, and a shadow ray toward the laser only for the
pixels within a few ``thickness`` of the sheet (the others receive no laser light).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from core.validate import check_array, check_positive, check_range, check_unit_vector

__all__ = ["LaserSheet", "LaserFrame", "LaserRenderer", "camera_directions", "plane_of"]

_CUTOFF = 4.0  # sheet half-thickness rendered, in sigmas (exp(-8) = 3e-4 of the peak)


@dataclass
class LaserSheet:
    """A line laser.

    Parameters
    ----------
    origin : (3,) float64
        The emitter (apex of the fan), world metres.
    normal : (3,) float64
        Normal of the sheet's plane.
    direction : (3,) float64
        Central direction of the fan; projected into the sheet's plane.
    fan_angle : float
        Full opening of the fan in radians.
    thickness : float
        Gaussian standard deviation of the sheet across its plane, metres.
    power : float
        Peak irradiance on a surface facing the laser 1 m away (radiance units of
        :mod:`acquire.render.lights`); falls off as ``1/r`` along the fan.
    color : (3,) float64
        Spectral colour (red for the usual 635-660 nm diode).
    speckle : float
        Speckle contrast (0 = off, 1 = fully developed speckle). Applied by the frame
        renderer: with ``speckle_grain`` as an image of grains that size
        (:func:`acquire.render.speckle.speckle_field`), else as independent unit-mean gamma noise
        per pixel of that contrast.
    speckle_grain : float
        Speckle grain diameter on the sensor, pixels (``2.44 lambda N / pitch``:
        :func:`acquire.render.speckle.grain_px`); 0: independent pixels.
    """

    origin: np.ndarray
    normal: np.ndarray
    direction: np.ndarray
    fan_angle: float = np.radians(40.0)
    thickness: float = 0.4e-3
    power: float = 0.35
    color: np.ndarray = None
    speckle: float = 0.0
    speckle_grain: float = 0.0

    def __post_init__(self):
        self.origin = check_array(self.origin, "origin", shape=(3,))
        self.normal = check_unit_vector(self.normal, "normal")
        d = check_unit_vector(self.direction, "direction")
        d = d - (d @ self.normal) * self.normal
        if np.linalg.norm(d) < 1e-9:
            raise ValueError("direction: expected a direction inside the sheet, got its normal")
        self.direction = d / np.linalg.norm(d)
        self.fan_angle = check_range(self.fan_angle, "fan_angle", 0, np.pi, lo_open=True,
                                     hi_open=True)
        self.thickness = check_positive(self.thickness, "thickness")
        self.power = check_positive(self.power, "power", allow_zero=True)
        self.color = (np.array([1.0, 0.0, 0.0]) if self.color is None
                      else check_array(self.color, "color", shape=(3,)))
        self.speckle = check_range(self.speckle, "speckle", 0.0, 2.0)
        self.speckle_grain = check_range(self.speckle_grain, "speckle_grain", 0.0, None)

    # -- geometry ---------------------------------------------------------------------
    @property
    def plane(self) -> tuple[np.ndarray, float]:
        """``(n (3,), d)`` with ``n . x = d`` on the sheet's central plane (world)."""
        return self.normal.copy(), float(self.normal @ self.origin)

    def transformed(self, new_from_old: np.ndarray) -> LaserSheet:
        """The same laser moved by the rigid transform ``new_from_old`` (4, 4)."""
        R, t = new_from_old[:3, :3], new_from_old[:3, 3]
        return LaserSheet(R @ self.origin + t, R @ self.normal, R @ self.direction,
                          self.fan_angle, self.thickness, self.power, self.color, self.speckle,
                          self.speckle_grain)

    def fan(self, points: np.ndarray) -> np.ndarray:
        """The sheet's peak irradiance factor ``(n,)`` at ``points (n, 3)``: ``power / r``
        inside the fan, 0 outside, without the Gaussian across the sheet or the cosine
        (what a translucent surface spreads around the stripe)."""
        d = points - self.origin
        along = d @ self.direction
        side = np.cross(self.normal, self.direction)
        lateral = d @ side
        r = np.sqrt(along * along + lateral * lateral)
        in_fan = (along > 0) & (np.abs(np.arctan2(lateral, along)) <= 0.5 * self.fan_angle)
        return np.where(in_fan, self.power / np.maximum(r, 1e-9), 0.0)

    def profile(self, points: np.ndarray) -> np.ndarray:
        """Unshadowed, cosine-free irradiance factor ``(n,)`` at ``points (n, 3)``."""
        s = (points - self.origin) @ self.normal
        g = np.exp(-0.5 * (s / self.thickness) ** 2)
        g[np.abs(s) > _CUTOFF * self.thickness] = 0.0
        return self.fan(points) * g

    # -- light protocol ---------------------------------------------------------------
    def irradiance(self, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
        to = self.origin - points
        cos = np.einsum("ij,ij->i", to, normals) / np.maximum(np.linalg.norm(to, axis=1), 1e-12)
        e = self.profile(points) * np.clip(cos, 0.0, None)
        return e[:, None] * self.color

    def shadow_rays(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.origin - points, np.ones(len(points))

    # -- serialization ----------------------------------------------------------------
    def to_dict(self) -> dict:
        return {"origin": self.origin.tolist(), "normal": self.normal.tolist(),
                "direction": self.direction.tolist(),
                "fan_angle_deg": float(np.degrees(self.fan_angle)),
                "thickness": self.thickness, "power": self.power, "color": self.color.tolist(),
                "speckle": self.speckle, "speckle_grain": self.speckle_grain}

    @classmethod
    def from_dict(cls, d: dict) -> LaserSheet:
        return cls(d["origin"], d["normal"], d["direction"], np.radians(d["fan_angle_deg"]),
                   d["thickness"], d["power"], d.get("color"), d.get("speckle", 0.0),
                   d.get("speckle_grain", 0.0))


def plane_of(laser: LaserSheet) -> np.ndarray:
    """The sheet's plane as ``(4,)``: ``(nx, ny, nz, d)`` with ``n . x = d``."""
    n, d = laser.plane
    return np.append(n, d)


@dataclass
class LaserFrame:
    """One rendered laser frame.

    Attributes
    ----------
    radiance : (H, W) float32
        Radiance in the laser's colour channel (ambient included).
    stripe : (k, 2) float64
        Ground truth: ``(row, col)`` where the sheet's central plane crosses the visible,
        lit surface along each image row (sub-pixel, linear between pixel centres).
    depth : (H, W) float32
        Ground-truth z-depth (0 = no hit).
    lit : int
        Number of pixels that receive laser light.
    """

    radiance: np.ndarray
    stripe: np.ndarray
    depth: np.ndarray
    lit: int


@numba.njit(cache=True, nogil=True)
def _make_rays(dirs_cam, R, origin):
    n = dirs_cam.shape[0]
    rays = np.empty((n, 6), np.float32)
    for i in range(n):
        for a in range(3):
            rays[i, a] = origin[a]
            rays[i, 3 + a] = (R[a, 0] * dirs_cam[i, 0] + R[a, 1] * dirs_cam[i, 1]
                              + R[a, 2] * dirs_cam[i, 2])
    return rays


@numba.njit(cache=True, nogil=True)
def _near_sheet(t, rays, normal, d, cutoff):
    """Signed distance to the plane at the hit pixels, and the pixels near the sheet."""
    n = t.shape[0]
    s = np.zeros(n)
    near = np.empty(n, np.int64)
    k = 0
    for i in range(n):
        ti = t[i]
        if np.isfinite(ti):
            acc = -d
            for a in range(3):
                acc += normal[a] * (rays[i, a] + ti * rays[i, 3 + a])
            s[i] = acc
            if abs(acc) < cutoff:
                near[k] = i
                k += 1
    return s, near[:k]


class LaserRenderer:
    """Renders the frames of a scan, caching what does not change between frames.

    Parameters
    ----------
    scene : acquire.render.scene.RenderScene
        Geometry, materials and ambient term (its lights are not used). The scene stays
        fixed; a turntable scan moves the camera and laser around it instead (see
        :mod:`acquire.laser.capture` for why that is equivalent).
    camera : acquire.camera.Camera
        Intrinsics and distortion (the pose is given per frame).
    dirs_cam : (H*W, 3) float64, optional
        The camera's :func:`camera_directions`, when already computed for another scene.
    exact_ambient : bool
        Evaluate the albedo exactly at every hit pixel for the ambient term. The default
        interpolates per-vertex albedo for the ambient term only (far cheaper for
        procedural solid textures); laser-lit pixels always get the exact albedo, and
        image-textured objects (calibration boards) always take the exact path.
    bounces : {0, 1}
        1: the stripe's light also comes back by one bounce off glossy surfaces (metal,
        coated dielectrics): the ghost stripes a concave shiny part shows. Every pixel
        on a glossy object draws one direction by its material
        (:func:`acquire.render.renderer.bounce_rays`); where it meets the sheet's light, that light
        is reflected once more. Needs ``rng`` in :meth:`frame`.
    """

    def __init__(self, scene, camera, *, exact_ambient: bool = False,
                 dirs_cam: np.ndarray | None = None, bounces: int = 0):
        self.scene = scene
        self.camera = camera
        if dirs_cam is None:
            dirs_cam = camera_directions(camera)
        self.dirs_cam = dirs_cam
        self.exact = exact_ambient or any(o.material.kind == "image" for o in scene.objects)
        self._vertex_albedo = None
        self._reach = None   # how far from the sheet translucent objects glow (m)
        if bounces not in (0, 1):
            raise ValueError(f"bounces: expected 0 or 1, got {bounces!r}")
        self.bounces = int(bounces)

    def _ambient_albedo(self, hit_idx, points, ans, ch):
        from acquire.render.renderer import Hits, albedo

        _, parts, lut = self.scene.raycasting()
        obj = lut[ans["geometry_ids"].numpy()[hit_idx].astype(np.int64)]
        tri = ans["primitive_ids"].numpy()[hit_idx].astype(np.int64)
        bary = ans["primitive_uvs"].numpy()[hit_idx].astype(np.float64)
        if self.exact:
            hits = Hits(np.ones(hit_idx.size, bool), None, points, None, None, obj, tri, bary)
            return albedo(self.scene, hits)[:, ch]
        if self._vertex_albedo is None:
            self._vertex_albedo = [
                o.material.albedo_at(np.asarray(o.mesh.vertices, dtype=np.float64),
                                     o.vertex_uvs)[:, ch] for o in self.scene.objects]
        out = np.empty(hit_idx.size)
        for i, (_, f, _) in enumerate(parts):
            sel = np.flatnonzero(obj == i)
            if sel.size == 0:
                continue
            va = self._vertex_albedo[i]
            tr = f[tri[sel]]
            u, v = bary[sel, 0], bary[sel, 1]
            out[sel] = (1 - u - v) * va[tr[:, 0]] + u * va[tr[:, 1]] + v * va[tr[:, 2]]
        return out

    def _sheet_light(self, laser: LaserSheet, directions: np.ndarray, origin: np.ndarray,
                     ch: int, rng) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Of the pixels near the sheet (rays ``directions`` from ``origin``): which the
        laser lights and their radiance, and every pixel's exact signed distance to the
        sheet's plane (float64 hits, NaN where nothing is hit; speckle drawn here).

        Surfaces reflect by their material (:meth:`acquire.render.materials.Material.reflectance`:
        Lambertian, or GGX seen from the camera); subsurface materials spread the stripe
        by their dipole profile (:func:`_subsurface_light`)."""
        from acquire.render.renderer import albedo, cast, visibility

        scene = self.scene
        n_pl, d_pl = laser.plane
        dn = directions.astype(np.float64)
        hits = cast(scene, np.broadcast_to(origin, dn.shape), dn)
        ok = np.flatnonzero(hits.hit)
        P, N, G = hits.points[ok], hits.normals[ok], hits.geo_normals[ok]
        signed = np.full(len(dn), np.nan)
        signed[ok] = P @ n_pl - d_pl
        alb = albedo(scene, hits.take(ok))
        obj = hits.obj[ok]
        rad = np.zeros(len(dn))
        translucent = np.isin(obj, [i for i, o in enumerate(scene.objects)
                                    if o.material.brdf == "subsurface"])
        # surfaces: the irradiance where the sheet falls, reflected toward the camera; a
        # thin translucent sheet is lit from either side (from behind, it lets through)
        thin = np.isin(obj, [i for i, o in enumerate(scene.objects)
                             if o.material.brdf == "translucent"])
        back = thin & (np.einsum("ij,ij->i", laser.origin - P, N) < 0)
        e = np.where(translucent, 0.0,
                     laser.irradiance(P, np.where(back[:, None], -N, N))[:, ch])
        has = np.flatnonzero(e > 0)
        if has.size:
            has = has[visibility(scene, laser, P[has], G[has])]
            wi = laser.origin - P[has]
            wi /= np.linalg.norm(wi, axis=1, keepdims=True)
            wo = -dn[ok[has]] / np.linalg.norm(dn[ok[has]], axis=1, keepdims=True)
            for i, o in enumerate(scene.objects):
                k = has[obj[has] == i]
                if k.size:
                    j = np.searchsorted(has, k)
                    rad[ok[k]] = e[k] * o.material.reflectance(wi[j], wo[j], N[k],
                                                               alb[k])[:, ch]
        if translucent.any():
            k = np.flatnonzero(translucent)
            wo = -dn[ok[k]] / np.linalg.norm(dn[ok[k]], axis=1, keepdims=True)
            rad[ok[k]] = _subsurface_light(scene, laser, P[k], N[k], G[k], obj[k], alb[k, ch],
                                           signed[ok[k]], ch, wo)
        if laser.speckle > 0 and laser.speckle_grain == 0:   # independent pixels
            if rng is None:
                raise ValueError("rng: a laser with speckle needs a random generator")
            kk = 1.0 / laser.speckle ** 2
            rad = rad * rng.gamma(kk, 1.0 / kk, size=rad.shape)
        sel = np.flatnonzero(rad > 0)
        return sel, rad[sel], signed

    def _ghosts(self, laser: LaserSheet, rays, hit_idx, origin, ch, rng) -> np.ndarray:
        """The stripe's light coming back by one bounce off the glossy pixels."""
        from acquire.render.renderer import bounce_rays, cast

        scene = self.scene
        out = np.zeros(len(rays))
        glossy = [i for i, o in enumerate(scene.objects)
                  if o.material.brdf in ("conductor", "dielectric")]
        if not glossy:
            return out
        dn = rays[hit_idx, 3:].astype(np.float64)
        hits = cast(scene, np.broadcast_to(origin, dn.shape), dn)
        rows = np.flatnonzero(hits.hit & np.isin(hits.obj, glossy))
        if rows.size == 0:
            return out
        b = bounce_rays(scene, hits, rows, dn[rows], rng=rng)
        k = np.flatnonzero(b.hits.hit)
        if k.size:
            L = _laser_reflected(scene, laser, b.hits, k, b.wi[k], ch)
            out[hit_idx[rows[b.rows[k]]]] = b.weight[k, ch] * L
        return out

    def frame(self, cam_from_world: np.ndarray, laser: LaserSheet | None, *,
              ambient: float | None = None, rng: np.random.Generator | None = None,
              channel: int = 0) -> LaserFrame:
        """Render one frame from the camera at ``cam_from_world`` lit by ``laser``.

        Parameters
        ----------
        cam_from_world : (4, 4) float64
        laser : LaserSheet or None
            None renders the laser-off (ambient only) frame.
        ambient : float, optional
            Ambient irradiance (default: the scene's).
        rng : numpy.random.Generator, optional
            Needed when the laser has speckle.
        channel : int
            Colour channel rendered when ``laser`` is None (else the laser's own).

        Notes
        -----
        Shading is ``albedo * (ambient + laser irradiance * visibility)`` in the laser's
        colour channel; vertex normals interpolated at the exact (float64) hit give the
        incidence cosine. Ground truth (the stripe's true crossing per row) is where the
        signed distance to the sheet's plane changes sign between two neighbouring pixels
        of a row that both see a continuous, lit surface.
        """
        import open3d as o3d


        scene, cam = self.scene, self.camera
        H, W = cam.height, cam.width
        amb = scene.ambient if ambient is None else float(ambient)
        Tw = np.linalg.inv(np.asarray(cam_from_world, float))
        origin = np.ascontiguousarray(Tw[:3, 3])
        rays = _make_rays(self.dirs_cam, np.ascontiguousarray(Tw[:3, :3]), origin)
        rs, _, _ = scene.raycasting()
        ans = rs.cast_rays(o3d.core.Tensor(rays))
        t = ans["t_hit"].numpy()
        hit_idx = np.flatnonzero(np.isfinite(t))
        rad = np.zeros(H * W)
        depth = np.zeros(H * W, np.float32)
        depth[hit_idx] = t[hit_idx]  # directions have z = 1: t is the z-depth
        lit = 0
        stripe = np.zeros((0, 2))
        ch = channel if laser is None else int(np.argmax(laser.color))
        if laser is not None:
            n_pl, d_pl = laser.plane
            if self._reach is None:
                self._reach = subsurface_reach(scene, ch)
            s, near = _near_sheet(t, rays, n_pl, d_pl,
                                  _CUTOFF * laser.thickness + self._reach)
        else:
            near = np.zeros(0, np.int64)
        if near.size:
            sel, rad_sel, signed = self._sheet_light(laser, rays[near, 3:], origin, ch, rng)
            hit = np.isfinite(signed)
            s[near[hit]] = signed[hit]
            if laser.speckle > 0 and laser.speckle_grain > 0 and sel.size:
                rad_sel = rad_sel * _grains(near[sel], W, laser, rng)
            rad[near[sel]] = rad_sel
            lit = int(sel.size)
            stripe = _true_stripe(s, depth, near[sel], H, W)
        if laser is not None and self.bounces and hit_idx.size:
            if rng is None:
                raise ValueError("rng: a laser frame with bounces needs a random generator")
            rad += self._ghosts(laser, rays, hit_idx, origin, ch, rng)
            lit = int(np.count_nonzero(rad))
        if amb > 0 and hit_idx.size:
            pts = None
            if self.exact:
                pts = origin + t[hit_idx, None].astype(np.float64) * rays[hit_idx, 3:]
            rad[hit_idx] += amb * self._ambient_albedo(hit_idx, pts, ans, ch)
        return LaserFrame(rad.reshape(H, W).astype(np.float32), stripe, depth.reshape(H, W), lit)


def subsurface_reach(scene, channel: int, *, fraction: float = 0.01) -> float:
    """How far (m) from the sheet's plane a translucent object of ``scene`` still sends
    light back: the largest :meth:`acquire.render.subsurface.Dipole.reach` (0 without one)."""
    reach = [o.material.dipole(channel).reach(fraction) for o in scene.objects
             if o.material.brdf == "subsurface"]
    return max(reach, default=0.0)


def _subsurface_light(scene, laser: LaserSheet, P, N, G, obj, alb, s, ch, wo):
    """Exit radiance of the sheet's light that entered a translucent surface, at the
    points ``P`` (normals ``N``, geometric ``G``) of objects ``obj`` with albedo ``alb``
    in channel ``ch`` and signed distances ``s`` to the sheet's plane, seen along ``wo``.

    Locally the surface is its tangent plane and the stripe the line where the sheet
    crosses it; the light enters along that line, lit where the stripe's point nearest
    the exit point sees the laser (its shadow ray), and leaves by the dipole's line
    profile shifted along the refracted ray (:func:`acquire.render.subsurface.stripe_radiance`,
    weighted at its entry and exit by :meth:`acquire.render.subsurface.Dipole.diffusion_entry`),
    plus the light scattered once, which leaves where it entered
    (:meth:`acquire.render.materials.Material.single_scattering`, the sheet's profile).
    A textured albedo scales the exit light by its ratio to the material's base albedo.
    """
    from acquire.render.renderer import visibility
    from acquire.render.subsurface import stripe_radiance

    n_pl = laser.normal
    mt = n_pl[None, :] - (N @ n_pl)[:, None] * N          # sheet normal along the surface
    across = np.linalg.norm(mt, axis=1)
    u_hat = mt / np.maximum(across, 1e-12)[:, None]
    entry = P - (s / np.maximum(across, 1e-6) ** 2)[:, None] * mt   # the stripe, nearest
    d_in = entry - laser.origin
    d_in /= np.maximum(np.linalg.norm(d_in, axis=1, keepdims=True), 1e-300)
    cos_i = np.clip(-np.einsum("ij,ij->i", d_in, N), 0.0, 1.0)
    tang = d_in + cos_i[:, None] * N                     # the ray's direction in the surface
    tlen = np.linalg.norm(tang, axis=1)
    e0 = laser.fan(entry) * cos_i
    lit = np.flatnonzero(e0 > 0)
    out = np.zeros(len(P))
    if lit.size == 0:
        return out
    lit = lit[visibility(scene, laser, entry[lit], G[lit])]
    for i, o in enumerate(scene.objects):
        k = lit[obj[lit] == i]
        if k.size == 0:
            continue
        m = o.material
        dip = m.dipole(ch)
        sin_t = np.sqrt(1.0 - cos_i[k] ** 2) / m.ior        # Snell, into the material
        shift = m.mfp * sin_t * np.einsum("ij,ij->i", tang[k], u_hat[k]) / np.maximum(
            tlen[k], 1e-12)
        tex = alb[k] / max(float(m.albedo[ch]), 1e-12)
        once = (m.single_scattering(-d_in[k], wo[k], N[k])[:, ch] * dip.albedo
                * np.exp(-0.5 * (s[k] / laser.thickness) ** 2))
        weight = (dip.diffusion_entry(cos_i[k])
                  * dip.diffusion_entry(np.einsum("ij,ij->i", wo[k], N[k])) / dip.entry_mean)
        out[k] = e0[k] * tex * (weight * stripe_radiance(dip, s[k], across[k], shift,
                                                         laser.thickness) + once)
    return out


def _grains(idx: np.ndarray, W: int, laser: LaserSheet, rng) -> np.ndarray:
    """The speckle factor at flat pixel indices ``idx`` of a ``W``-wide image: a field of
    the laser's grain drawn over their bounding box (speckle is stationary, so the box
    is all that is needed)."""
    from acquire.render.speckle import speckle_field

    if rng is None:
        raise ValueError("rng: a laser with speckle needs a random generator")
    r, c = idx // W, idx % W
    r0, c0 = int(r.min()), int(c.min())
    field = speckle_field((int(r.max()) - r0 + 1, int(c.max()) - c0 + 1),
                          laser.speckle_grain, laser.speckle, rng)
    return field[r - r0, c - c0]


def _laser_reflected(scene, laser: LaserSheet, hits, rows, view_dirs, ch):
    """Radiance ``(len(rows),)`` the sheet's direct light leaves at the hits ``rows``
    back along the rays ``view_dirs`` that reached them."""
    from acquire.render.renderer import reflect_toward, visibility

    out = np.zeros(len(rows))
    P, N, G = hits.points[rows], hits.normals[rows], hits.geo_normals[rows]
    e = laser.irradiance(P, N)[:, ch]
    k = np.flatnonzero(e > 0)
    if k.size == 0:
        return out
    k = k[visibility(scene, laser, P[k], G[k])]
    refl = reflect_toward(scene, hits, rows[k], laser.origin, view_dirs[k])[:, ch]
    out[k] = e[k] * refl
    return out


def _true_stripe(s, depth, lit_idx, H, W):
    """Sub-pixel ``(row, col)`` crossings of the sheet's plane along rows (ground truth)."""
    lit = np.zeros(H * W, bool)
    lit[lit_idx] = True
    s2, l2, z2 = s.reshape(H, W), lit.reshape(H, W), depth.reshape(H, W)
    a, b = s2[:, :-1], s2[:, 1:]
    zc = (l2[:, :-1] & l2[:, 1:] & (np.sign(a) != np.sign(b))
          & (np.abs(z2[:, :-1] - z2[:, 1:]) < 0.01 * np.maximum(z2[:, :-1], 1e-9)))
    r, c = np.nonzero(zc)
    u = c + a[r, c] / (a[r, c] - b[r, c])
    return np.stack([r.astype(np.float64), u], axis=1)


def camera_directions(camera) -> np.ndarray:
    """Camera-frame directions ``(H*W, 3)`` (z = 1) through the pixel centres, row-major."""
    xy = camera.normalized(camera.pixel_grid(supersample=1))
    return np.ascontiguousarray(np.concatenate([xy, np.ones((len(xy), 1))], axis=1))
