"""simulate: procedural animation — integrators, forces, particles, collisions, cloth, boids.

The public API, importable from ``simulate`` directly (each name is loaded from its
module on first use, so ``import simulate`` stays cheap):

* integrators (:mod:`simulate.integrators`): ``step``, ``integrate``,
  ``integrate_adaptive``, ``AdaptiveStats``, ``stability_limit``, ``check_step``,
  ``METHODS``;
* forces (:mod:`simulate.forces`): ``Gravity``, ``Wind``, ``Damping``, ``Turbulence``
  (Perlin or curl noise), ``Attractor``, ``Vortex``, ``Buoyancy``, ``Pairwise``
  (neighbour grid), ``Springs``, ``ForceSet``, ``pairwise_accel``,
  ``pairwise_accel_reference``;
* emitters (:mod:`simulate.particles.emitters`): ``PointShape``, ``DiscShape``, ``BoxShape``,
  ``MeshSurface``, ``VelocityDist``, ``Emitter``, ``birth_count``;
* particle systems (:mod:`simulate.particles.system`): ``ParticleSystem``, ``advance_local``
  (the fused kernel), ``Ramp``, ``Look``, ``Sink``, ``KillPlane``, ``FrameStats``,
  ``NonFiniteStateError``;
* collisions with meshes: ``MeshCollider`` (:mod:`simulate.colliders`, Open3D's
  RaycastingScene), ``collide`` and ``ContactParams`` (:mod:`simulate.collisions`:
  swept segments, time of impact, restitution, friction, resting contact);
* cloth (:mod:`simulate.cloth.mass_spring`): ``Cloth``, ``ClothSpec``, ``grid_cloth``;
* boids (:mod:`simulate.boids.flock`): ``BoidParams``, ``FlockState``, ``init_flock``,
  ``step_flock`` (``simulate.boids.step``), ``BoidRecipe`` (``simulate.boids.Recipe``),
  ``load_boid_recipe``; measures (:mod:`simulate.boids.metrics`): ``flock_metrics``,
  ``polarization``, ``milling``, ``nearest_neighbour_distances``, ``groups``;
* neighbour search (:mod:`simulate.neighbours`): ``build_grid``, ``neighbour_lists``,
  ``neighbour_lists_reference``;
* recipes and stand-ins: ``RECIPES``, ``load_recipe``, ``build_particles``,
  ``build_cloth``, ``procedural_scan`` (:mod:`simulate.recipes`); ``stand_in_mesh``,
  ``lumpy_sphere`` (:mod:`simulate.stand_ins`);
* output: ``SeriesWriter``, ``write_vtp``, ``write_pvd`` (:mod:`simulate.series_io`,
  VTP frames and the ``.pvd`` series for ParaView).

simulate imports only procgen.

>>> import simulate
>>> simulate.Gravity().g
(0.0, 0.0, -9.81)
"""

from __future__ import annotations

import importlib

_EXPORTS = {
    "integrators": ["step", "integrate", "integrate_adaptive", "AdaptiveStats",
                    "stability_limit", "check_step", "METHODS"],
    "forces": ["Gravity", "Wind", "Damping", "Turbulence", "Attractor", "Vortex", "Buoyancy",
               "Pairwise", "Springs", "ForceSet", "pairwise_accel", "pairwise_accel_reference"],
    "particles.emitters": ["PointShape", "DiscShape", "BoxShape", "MeshSurface",
                           "VelocityDist", "Emitter", "birth_count"],
    "particles.system": ["ParticleSystem", "advance_local", "Ramp", "Look", "Sink",
                         "KillPlane", "FrameStats", "NonFiniteStateError"],
    "colliders": ["MeshCollider"],
    "collisions": ["collide", "ContactParams"],
    "cloth.mass_spring": ["Cloth", "ClothSpec", "grid_cloth"],
    "boids.flock": ["BoidParams", "FlockState", "init_flock"],
    "boids.metrics": ["flock_metrics", "polarization", "milling",
                      "nearest_neighbour_distances", "groups"],
    "neighbours": ["build_grid", "neighbour_lists", "neighbour_lists_reference"],
    "recipes": ["RECIPES", "load_recipe", "build_particles", "build_cloth", "procedural_scan"],
    "stand_ins": ["stand_in_mesh", "lumpy_sphere"],
    "series_io": ["SeriesWriter", "write_vtp", "write_pvd"],
}
# names that would clash across modules get a prefix here
_RENAMED = {"step_flock": ("boids.flock", "step"), "BoidRecipe": ("boids.recipes", "Recipe"),
            "load_boid_recipe": ("boids.recipes", "load_recipe")}
_WHERE = {name: (mod, name) for mod, names in _EXPORTS.items() for name in names}
_WHERE.update(_RENAMED)

__all__ = sorted(_WHERE)


def __getattr__(name: str):
    try:
        mod, attr = _WHERE[name]
    except KeyError:
        raise AttributeError(f"module 'simulate' has no attribute {name!r}") from None
    value = getattr(importlib.import_module(f"simulate.{mod}"), attr)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
