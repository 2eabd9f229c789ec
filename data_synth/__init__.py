"""data_synth: scenes (specs -> ground-truth meshes + materials), calibration targets as
scene objects, and fixture datasets for tests — rendered virtual captures.

Public API: :func:`data_synth.scenes.build_scene`, :func:`~data_synth.scenes.write_scene`,
:func:`~data_synth.scenes.load_scene`, :func:`~data_synth.scenes.scene_names`.
"""
