"""acquire: how virtual captures are made.

Shared by every method (imported by the method rooms, never the reverse):

- :mod:`acquire.camera` the OpenCV pinhole camera with distortion;
- :mod:`acquire.sensor` sensor noise (shot, read, quantisation);
- :mod:`acquire.targets` calibration boards;
- :mod:`acquire.capture_io` capture folders (``capture.json``);
- :mod:`acquire.render` the ray-cast renderer, materials, lights, the scene, speckle.

One room per acquisition method: :mod:`acquire.laser` (sheet of light),
:mod:`acquire.stereo` (stereo and structured light), :mod:`acquire.sfm` (camera paths
for structure from motion). docs/architecture.md has the picture and where a new
method's files go.

The names docs and notebooks use most are served here too, loaded on first use:
``Camera``, ``Sensor``, ``render``, ``cast``, ``Material``, ``RenderScene``,
``SceneObject``, ``PointLight``, ``DirectionalLight``, ``load_capture``.
"""

from core.lazy import lazy_exports

_EXPORTS = {
    "Camera": "camera",
    "Sensor": "sensor",
    "load_capture": "capture_io",
    "render": "render.renderer",
    "cast": "render.renderer",
    "Material": "render.materials",
    "RenderScene": "render.scene",
    "SceneObject": "render.scene",
    "PointLight": "render.lights",
    "DirectionalLight": "render.lights",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
