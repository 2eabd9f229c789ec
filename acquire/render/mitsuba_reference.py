"""Mitsuba 3 as the reference renderer: a render scene and a camera described to Mitsuba,
rendered on the CPU, and the agreement of two images measured.

Mitsuba 3 (pip ``mitsuba``, the ``scalar_rgb`` variant: no GPU, no LLVM) is a physically
based renderer; the light-transport work of this package is checked against it at
matched settings. What is described, and how:

- camera: a pinhole ``perspective`` sensor with the same horizontal field of view, pose
  and principal point (centred), a box pixel filter like our supersampling;
- objects: their world-frame triangles with vertex normals (a PLY each), or an exact
  ``sphere`` where the object has an analytic sphere;
- materials: ``lambert`` -> ``diffuse``; ``conductor`` -> ``roughconductor`` (GGX,
  ``alpha = roughness^2``, a perfect conductor tinted by the albedo);
  ``dielectric`` -> ``roughplastic`` (GGX coat of the same index over the albedo);
  ``subsurface`` (index-matched, ``ior`` within 1e-3 of 1) -> a ``null`` boundary around
  a ``homogeneous`` medium with an isotropic phase function, extinction ``1 / mfp`` and
  the single-scattering albedo whose semi-infinite medium reflects the material's
  albedo (:func:`medium_albedo`), rendered by the ``volpath`` integrator: the exact
  transport that the dipole and the single term approximate. A refracting boundary is
  not described (behind a smooth dielectric a point light is out of a path tracer's
  reach), nor an anisotropic phase function (``medium_albedo`` is isotropic's);
  (Mitsuba 3 has no diffuse transmitter, so thin translucent sheets are not described);
- lights: point and directional lights, with the unit conversion of
  :mod:`acquire.render.lights` (our unit intensity head-on on white gives radiance 1, so
  Mitsuba's intensity is ``pi`` times ours); a pattern projector as Mitsuba's
  ``projector`` with the same pinhole, its pattern as the irradiance texture (bilinear,
  pixel centres matched) times ``cos^3`` of each pixel's angle off the axis: ours gives
  every projector pixel the same intensity, Mitsuba's texture is the irradiance on the
  plane one unit ahead, which falls off as ``cos^3`` for the same intensity.
  The laser sheet is not described: its ``1/r`` fan of constant thickness is no
  Mitsuba emitter (a projected line is, and is checked as a projector pattern).

Where the two differ on purpose (stated, and measured in ``docs/materials.md``):

- the conductor's Fresnel: ours is Schlick's from ``F0`` = albedo (it whitens toward
  grazing), Mitsuba's tinted perfect conductor is ``F0`` at every angle; they agree
  exactly for a white conductor, which the reference scenes use;
- masking-shadowing: ours is the height-correlated Smith term, Mitsuba's the separable
  product ``G1(wi) G1(wo)`` (slightly darker at grazing angles);
- the plastic: Mitsuba's ``roughplastic`` scatters light inside the coat
  (``1 / (1 - F_dr R)`` and an ``eta^-2`` factor), ours is a single transmission in and
  out of the coat;
- no ambient term: ours adds an unoccluded constant, which no physical light gives;
- subsurface: ours is the diffusion dipole plus the closed-form single scattering of a
  deep medium, the irradiance spread over the image; Mitsuba follows every scattering
  event (the multiple scattering's exact angular distribution and profile, light carried
  around the curvature).

References: M. Pharr, W. Jakob, G. Humphreys, *Physically Based Rendering*, 4th ed.
(2023); W. Jakob et al., Mitsuba 3 (2022), https://mitsuba.readthedocs.io;
S. Chandrasekhar, *Radiative Transfer* (1950), ch. V (the H-function).
"""

from __future__ import annotations

import logging
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from acquire.camera import Camera
from acquire.render.lights import DirectionalLight, PointLight
from acquire.render.projector import PatternProjector
from acquire.render.scene import RenderScene

log = logging.getLogger(__name__)

__all__ = ["mitsuba_available", "scene_dict", "render_reference", "Agreement", "agreement",
           "tone_map", "corner_scene", "medium_albedo", "REFERENCE_MATERIALS"]

# Mitsuba's camera looks along +z with +y up and +x to the left; ours (OpenCV) has +x
# right and +y down: the two frames differ by a half turn about z.
_CV_TO_MITSUBA = np.diag([-1.0, -1.0, 1.0, 1.0])


def mitsuba_available() -> bool:
    """Whether Mitsuba 3 imports (the ``dev`` extra installs it)."""
    try:
        import mitsuba  # noqa: F401
    except ImportError:
        return False
    return True


def _mitsuba():
    import mitsuba as mi

    if mi.variant() is None:
        mi.set_variant("scalar_rgb")
    return mi


def _rgb(value) -> dict:
    return {"type": "rgb", "value": [float(x) for x in np.asarray(value, float)]}


def _h_function(w: float, n: int = 64):
    """Chandrasekhar's H-function of isotropic scattering with single-scattering albedo
    ``w``, on ``n`` Gauss-Legendre nodes ``mu`` of [0, 1]: ``(mu, weights, H(mu))``, by
    iterating ``1 / H(mu) = sqrt(1 - w) + w / 2 int_0^1 mu' H(mu') / (mu + mu') dmu'``."""
    x, wt = np.polynomial.legendre.leggauss(n)
    mu, wt = 0.5 * (x + 1.0), 0.5 * wt
    k = mu[None, :] * wt[None, :] / (mu[:, None] + mu[None, :])
    h = np.ones(n)
    for _ in range(10_000):
        new = 1.0 / (np.sqrt(1.0 - w) + 0.5 * w * (k * h[None, :]).sum(1))
        if np.max(np.abs(new - h)) < 1e-12:
            return mu, wt, new
        h = new
    return mu, wt, h


def medium_albedo(albedo: float) -> float:
    """The single-scattering albedo of an isotropic, index-matched, semi-infinite medium
    whose bihemispherical reflectance is ``albedo``. A beam at incidence ``mu0`` is
    reflected by ``1 - H(mu0) sqrt(1 - w)`` of its power (Chandrasekhar); averaged over
    cosine-weighted incidence, that is the albedo a user measures under broad light, as
    the subsurface material's albedo is defined."""
    from scipy.optimize import brentq

    def bihemispherical(w):
        mu, wt, h = _h_function(w)
        return 2.0 * float(np.sum((1.0 - h * np.sqrt(1.0 - w)) * mu * wt))

    a = float(albedo)
    if not 0.0 < a < 1.0:
        raise ValueError(f"albedo: expected a value in (0, 1), got {a!r}")
    return float(brentq(lambda w: bihemispherical(w) - a, 1e-9, 1.0 - 1e-12, xtol=1e-12))


def _medium(material) -> dict:
    return {"type": "homogeneous", "sigma_t": 1.0 / float(material.mfp),
            "albedo": _rgb([medium_albedo(a) for a in material.albedo]),
            "phase": {"type": "isotropic"}}


def _bsdf(material) -> dict:
    if material.kind != "constant":
        raise ValueError(f"material: only constant albedos are described to Mitsuba, got "
                         f"kind {material.kind!r}")
    alpha = float(material.roughness) ** 2
    if material.brdf == "subsurface":
        if abs(float(material.ior) - 1.0) > 1e-3:
            raise ValueError(f"material.ior: the reference subsurface material is "
                             f"index-matched (ior within 1e-3 of 1), got {material.ior!r}")
        if material.anisotropy != 0.0:
            raise ValueError(f"material.anisotropy: the reference subsurface material "
                             f"scatters isotropically (0), got {material.anisotropy!r}")
        return {"type": "null"}
    if material.brdf == "lambert":
        return {"type": "diffuse", "reflectance": _rgb(material.albedo)}
    if material.brdf == "conductor":
        return {"type": "roughconductor", "distribution": "ggx", "alpha": alpha,
                "material": "none", "specular_reflectance": _rgb(material.albedo)}
    if material.brdf != "dielectric":
        raise ValueError(f"material.brdf: {material.brdf!r} is not described to Mitsuba "
                         f"(lambert, conductor, dielectric and subsurface are)")
    return {"type": "roughplastic", "distribution": "ggx", "alpha": alpha,
            "int_ior": float(material.ior), "ext_ior": 1.0, "nonlinear": False,
            "diffuse_reflectance": _rgb(material.albedo)}


def _light(light) -> dict:
    if isinstance(light, PointLight):
        return {"type": "point", "position": [float(x) for x in light.position],
                "intensity": _rgb(np.pi * light.intensity * light.color)}
    if isinstance(light, DirectionalLight):
        return {"type": "directional", "direction": [float(x) for x in light.direction],
                "irradiance": _rgb(np.pi * light.intensity * light.color)}
    if isinstance(light, PatternProjector):
        cam = light.camera
        if np.any(cam.dist != 0) or abs(cam.fx - cam.fy) > 1e-9 * cam.fx or \
                abs(cam.cx - (cam.width - 1) / 2) > 1e-6 or \
                abs(cam.cy - (cam.height - 1) / 2) > 1e-6:
            raise ValueError("projector.camera: the reference projector is a centred "
                             "pinhole without distortion and with square pixels")
        u = (np.arange(cam.width) - cam.cx) / cam.fx
        v = (np.arange(cam.height) - cam.cy) / cam.fy
        cos3 = (1.0 + u[None, :] ** 2 + v[:, None] ** 2) ** -1.5
        tex = (light.pattern * cos3 * light.intensity)[:, :, None] * light.color
        mi = _mitsuba()
        return {"type": "projector", "scale": 1.0,
                "fov": float(np.degrees(2.0 * np.arctan(0.5 * cam.width / cam.fx))),
                "to_world": mi.ScalarTransform4f((cam.world_from_cam @ _CV_TO_MITSUBA)
                                                 .tolist()),
                "irradiance": {"type": "bitmap", "raw": True, "filter_type": "bilinear",
                               "bitmap": mi.Bitmap(np.ascontiguousarray(tex, np.float32))}}
    raise ValueError(f"lights: {type(light).__name__} is not described to Mitsuba "
                     f"(point, directional and pattern projector lights are)")


def scene_dict(scene: RenderScene, camera: Camera, folder, *, spp: int = 64,
               bounces: int = 0, seed: int = 0) -> dict:
    """The Mitsuba scene dictionary of ``scene`` seen by ``camera``; meshes are written
    as PLY files into ``folder``. ``bounces``: indirect bounces after the direct light
    (0: direct only)."""
    from core.io.mesh import write_mesh
    from core.meshes import make_mesh

    if np.any(camera.dist != 0):
        raise ValueError("camera.dist: the reference camera is a pinhole without distortion")
    if abs(camera.fx - camera.fy) > 1e-9 * camera.fx:
        raise ValueError("camera: the reference camera needs square pixels (fx = fy)")
    if float(scene.ambient) != 0.0:
        raise ValueError("ambient: the reference scenes have no ambient term (set it to 0)")
    fov = float(np.degrees(2.0 * np.arctan(0.5 * camera.width / camera.fx)))
    volume = any(o.material.brdf == "subsurface" for o in scene.objects)
    if volume and len(scene.objects) > 1:
        raise ValueError("objects: a subsurface reference object is alone in its scene "
                         "(the volumetric path tracer cannot stop after the direct light "
                         "without stopping the walk inside the medium)")
    integrator = ({"type": "volpath", "max_depth": -1, "hide_emitters": True} if volume
                  else {"type": "path", "max_depth": int(bounces) + 2, "hide_emitters": True})
    d = {"type": "scene",
         "integrator": integrator,
         "sensor": {"type": "perspective", "fov": fov, "fov_axis": "x",
                    "principal_point_offset_x": ((camera.width - 1) / 2 - camera.cx)
                    / camera.width,
                    "principal_point_offset_y": ((camera.height - 1) / 2 - camera.cy)
                    / camera.height,
                    "to_world": _mitsuba().ScalarTransform4f(
                        (camera.world_from_cam @ _CV_TO_MITSUBA).tolist()),
                    "film": {"type": "hdrfilm", "width": camera.width,
                             "height": camera.height, "rfilter": {"type": "box"},
                             "pixel_format": "rgb"},
                    "sampler": {"type": "independent", "sample_count": int(spp),
                                "seed": int(seed)}}}
    for i, obj in enumerate(scene.objects):
        bsdf = _bsdf(obj.material)
        ana = obj.analytic or {}
        if ana.get("type") == "sphere":
            R, t = obj.world_from_object[:3, :3], obj.world_from_object[:3, 3]
            d[f"obj{i}"] = {"type": "sphere",
                            "center": [float(x) for x in R @ np.asarray(ana["center"]) + t],
                            "radius": float(ana["radius"]) * float(np.cbrt(abs(
                                np.linalg.det(R)))), "bsdf": bsdf}
        else:
            v, f, n = obj.world_arrays()
            mesh = make_mesh(v, f)
            mesh.vertex_normals = type(mesh.vertex_normals)(n)
            path = write_mesh(Path(folder) / f"obj{i}.ply", mesh)
            d[f"obj{i}"] = {"type": "ply", "filename": str(path), "face_normals": False,
                            "bsdf": bsdf}
        if obj.material.brdf == "subsurface":
            d[f"obj{i}"]["interior"] = _medium(obj.material)
    for k, light in enumerate(scene.lights):
        d[f"light{k}"] = _light(light)
    return d


def render_reference(scene: RenderScene, camera: Camera, *, spp: int = 64, bounces: int = 0,
                     seed: int = 0) -> np.ndarray:
    """Linear radiance ``(H, W, 3)`` float64 of ``scene`` by Mitsuba 3, in our units."""
    mi = _mitsuba()
    with tempfile.TemporaryDirectory(prefix="scanamp-mitsuba-") as td:
        ms = mi.load_dict(scene_dict(scene, camera, td, spp=spp, bounces=bounces, seed=seed))
        img = np.asarray(mi.render(ms, spp=int(spp), seed=int(seed)), dtype=np.float64)
    return img.reshape(camera.height, camera.width, 3)


def tone_map(radiance: np.ndarray) -> np.ndarray:
    """The shared display transform of a comparison: Reinhard ``x / (1 + x)`` then the
    sRGB-like gamma 1/2.2, so highlights do not dominate the error."""
    x = np.clip(np.asarray(radiance, np.float64), 0.0, None)
    return (x / (1.0 + x)) ** (1.0 / 2.2)


@dataclass
class Agreement:
    """How two renders agree over the compared pixels.

    Attributes
    ----------
    relative_l1 : float
        ``sum |a - b| / sum b`` of the tone-mapped images (the mean relative error).
    relative_l1_linear : float
        The same on linear radiance.
    pixels : int
        Pixels compared (inside objects, off silhouettes).
    """

    relative_l1: float
    relative_l1_linear: float
    pixels: int


def agreement(ours: np.ndarray, reference: np.ndarray, object_id: np.ndarray) -> Agreement:
    """Compare ``ours`` with ``reference`` (both ``(H, W, 3)`` linear) over the pixels
    whose 3 x 3 neighbourhood sees one object (``object_id``, -1 background): silhouette
    pixels mix surfaces differently in every renderer (their anti-aliasing samples), so
    they are left out."""
    from scipy import ndimage

    ids = np.asarray(object_id)
    m = (ids >= 0) & (ndimage.minimum_filter(ids, size=3, mode="nearest")
                      == ndimage.maximum_filter(ids, size=3, mode="nearest"))
    if not m.any():
        raise ValueError("mask: no pixel left to compare")
    a, b = np.asarray(ours, np.float64)[m], np.asarray(reference, np.float64)[m]
    ta, tb = tone_map(a), tone_map(b)
    return Agreement(relative_l1=float(np.abs(ta - tb).sum() / max(tb.sum(), 1e-300)),
                     relative_l1_linear=float(np.abs(a - b).sum() / max(b.sum(), 1e-300)),
                     pixels=int(m.sum()))


def _materials() -> dict:
    from acquire.render.materials import Material

    white = np.ones(3)
    return {"lambert": Material(albedo=np.array([0.9, 0.3, 0.2])),
            "conductor r0.1": Material(albedo=white, brdf="conductor", roughness=0.1),
            "conductor r0.3": Material(albedo=white, brdf="conductor", roughness=0.3),
            "conductor r0.6": Material(albedo=white, brdf="conductor", roughness=0.6),
            "dielectric r0.3": Material(albedo=np.array([0.2, 0.4, 0.9]), brdf="dielectric",
                                        roughness=0.3),
            "subsurface 10mm": Material(albedo=np.array([0.8, 0.5, 0.3]), brdf="subsurface",
                                        mfp=0.01, ior=1.0001, anisotropy=0.0)}


REFERENCE_MATERIALS = tuple(_materials())
"""Names of the materials of the reference spheres (:func:`corner_scene`)."""


def corner_scene(material: str = "lambert", *, light: str = "point", width: int = 160,
                 height: int = 120) -> tuple[RenderScene, Camera]:
    """A reference scene: a sphere of ``material`` (one of :data:`REFERENCE_MATERIALS`)
    in the corner of a matte floor and a matte wall, lit by a point light (``"point"``)
    or by a projector showing vertical stripes (``"projector"``), and its camera. The
    subsurface sphere is alone, without the corner (:func:`scene_dict`)."""
    import open3d as o3d

    from acquire.render.materials import Material
    from acquire.render.scene import SceneObject
    from core.meshes import make_mesh
    from core.validate import check_choice

    mats = _materials()
    check_choice(material, "material", tuple(mats))
    check_choice(light, "light", ("point", "projector"))

    def quad(corners):
        return make_mesh(np.array(corners, float), np.array([[0, 1, 2], [0, 2, 3]]))

    ball = o3d.geometry.TriangleMesh.create_sphere(0.35, resolution=64)
    ball.translate((0.0, 0.3, 0.35))
    objects = [
        SceneObject("floor", quad([[-1.5, -1.5, 0], [1.5, -1.5, 0], [1.5, 1, 0], [-1.5, 1, 0]]),
                    material=Material(albedo=np.array([0.8, 0.8, 0.8])), object_id=0,
                    analytic={"type": "plane", "point": (0, 0, 0), "normal": (0, 0, 1)}),
        SceneObject("wall", quad([[-1.5, 1, 0], [1.5, 1, 0], [1.5, 1, 2], [-1.5, 1, 2]]),
                    material=Material(albedo=np.array([0.6, 0.7, 0.8])), object_id=1,
                    analytic={"type": "plane", "point": (0, 1, 0), "normal": (0, -1, 0)}),
        SceneObject("ball", ball, material=mats[material], object_id=2,
                    analytic={"type": "sphere", "center": (0, 0.3, 0.35), "radius": 0.35})]
    if mats[material].brdf == "subsurface":
        objects = objects[2:]
    if light == "point":
        lamp = PointLight(np.array([0.9, -0.8, 1.6]), intensity=2.0)
    else:
        pc = Camera.look_at([-0.8, -1.2, 1.4], [0.0, 0.4, 0.3], width=64, height=48,
                            fov_deg=55)
        stripes = (np.arange(64) // 4 % 2).astype(float)
        lamp = PatternProjector(pc, np.tile(0.15 + 0.85 * stripes, (48, 1)), intensity=2.5)
    cam = Camera.look_at([0.3, -2.4, 1.3], [0.0, 0.3, 0.35], width=width, height=height,
                         fov_deg=50)
    return RenderScene(objects, lights=[lamp], ambient=0.0), cam

