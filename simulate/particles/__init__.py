"""Particle systems: births from emitters, forces, integration, collisions, deaths and
attributes over age.

- :mod:`simulate.particles.system` the particle system and its fused compiled stepper;
- :mod:`simulate.particles.emitters` emitter shapes, velocity distributions, birth counts.

>>> from simulate.particles import ParticleSystem, Emitter
>>> ParticleSystem.__name__, Emitter.__name__
('ParticleSystem', 'Emitter')
"""

from core.lazy import lazy_exports

_EXPORTS = {
    **dict.fromkeys(["ParticleSystem", "Ramp", "Look", "Sink", "KillPlane", "NonFiniteStateError",
                     "advance_local", "FrameStats"], "system"),
    **dict.fromkeys(["PointShape", "DiscShape", "BoxShape", "MeshSurface", "VelocityDist",
                     "Emitter", "birth_count", "normal_clamped", "birth_count_moments"],
                    "emitters"),
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
