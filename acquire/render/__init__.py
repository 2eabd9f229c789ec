"""acquire.render: the ray-cast renderer and what it renders: materials, BRDFs, subsurface
transport, lights (the pattern projector is one), the scene description, laser speckle,
point splats and glyphs, and the Mitsuba 3 reference.

Modules: ``brdf``, ``glyphs``, ``lights``, ``materials``, ``mitsuba_reference``,
``projector``, ``renderer``, ``scene``, ``speckle``, ``splats``, ``subsurface``.

Every name below is importable from the room (``from acquire.render import NAME``), loaded
on first use.

Names defined by more than one module are reached through their module: ``BRDFS``.
"""

from core.lazy import lazy_exports

_EXPORTS = {
    "dielectric_f0": "brdf",
    "ggx": "brdf",
    "ggx_d": "brdf",
    "lambert": "brdf",
    "mixture_pdf": "brdf",
    "sample_mixture": "brdf",
    "schlick": "brdf",
    "smith_g": "brdf",
    "glyph_triangles": "glyphs",
    "heading_colors": "glyphs",
    "render_glyphs": "glyphs",
    "DirectionalLight": "lights",
    "Light": "lights",
    "PointLight": "lights",
    "MATERIAL_KINDS": "materials",
    "MATERIAL_PRESETS": "materials",
    "Material": "materials",
    "Agreement": "mitsuba_reference",
    "REFERENCE_MATERIALS": "mitsuba_reference",
    "agreement": "mitsuba_reference",
    "corner_scene": "mitsuba_reference",
    "medium_albedo": "mitsuba_reference",
    "mitsuba_available": "mitsuba_reference",
    "render_reference": "mitsuba_reference",
    "scene_dict": "mitsuba_reference",
    "tone_map": "mitsuba_reference",
    "PatternProjector": "projector",
    "sample_bilinear": "projector",
    "Bounce": "renderer",
    "Hits": "renderer",
    "Render": "renderer",
    "SubsurfaceAngular": "renderer",
    "bounce_rays": "renderer",
    "camera_rays": "renderer",
    "cast": "renderer",
    "centre_hits": "renderer",
    "exit_weights": "renderer",
    "one_bounce": "renderer",
    "reflect_toward": "renderer",
    "render": "renderer",
    "shade": "renderer",
    "subsurface_angular": "renderer",
    "subsurface_spread": "renderer",
    "subsurface_weights": "renderer",
    "RenderScene": "scene",
    "SceneObject": "scene",
    "grain_px": "speckle",
    "intensity_covariance": "speckle",
    "speckle_field": "speckle",
    "composite_splats": "splats",
    "render_splats": "splats",
    "DEFAULT_ANISOTROPY": "subsurface",
    "Dipole": "subsurface",
    "diffuse_fresnel": "subsurface",
    "fresnel_transmittance": "subsurface",
    "gaussian_mixture": "subsurface",
    "hg_phase": "subsurface",
    "line_profile": "subsurface",
    "reduced_albedo": "subsurface",
    "single_scattering": "subsurface",
    "single_scattering_directional": "subsurface",
    "single_scattering_share": "subsurface",
    "spread_irradiance": "subsurface",
    "stripe_radiance": "subsurface",
    "total_reflectance": "subsurface",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
