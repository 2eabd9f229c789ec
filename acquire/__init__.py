"""acquire: cameras, lights, materials, the ray-cast renderer, sensor noise, targets,
rigs and capture folders.

Public API: :class:`acquire.camera.Camera`, :mod:`acquire.lights`,
:class:`acquire.materials.Material`, :class:`acquire.scene.RenderScene` /
:class:`acquire.scene.SceneObject`, :func:`acquire.render.render` /
:func:`acquire.render.cast`, :class:`acquire.sensor.Sensor`,
:mod:`acquire.targets`, :mod:`acquire.capture_io`.
"""
