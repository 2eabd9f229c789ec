"""simulate: procedural animation — integrators, forces, particles, collisions, cloth, boids.

Modules (one concept each):

* :mod:`simulate.integrators` — ``step``, ``integrate``, ``integrate_adaptive`` over
  ``f(t, y)``; ``stability_limit``, ``check_step``; ``METHODS``.
* :mod:`simulate.forces` — ``Gravity``, ``Wind``, ``Damping``, ``Turbulence`` (Perlin or
  curl noise), ``Attractor``, ``Vortex``, ``Buoyancy``, ``Pairwise`` (neighbour grid),
  ``Springs``, ``ForceSet``.
* :mod:`simulate.emitters` — shapes (point, disc, box, mesh surface), ``VelocityDist``,
  ``Emitter``, ``birth_count``.
* :mod:`simulate.particles` — ``ParticleSystem`` (births, fused RK4 kernel, collisions,
  deaths, attributes), ``Ramp``, ``Look``, ``Sink``, ``KillPlane``, ``NonFiniteStateError``.
* :mod:`simulate.collisions` — ``collide`` (exact time of impact, restitution, friction,
  resting contact, several bounces per step), ``ContactParams``.
* :mod:`simulate.cloth` — ``Cloth``, ``ClothSpec`` (stretch/shear/bend springs, pins,
  Provot strain limiting).
* :mod:`simulate.recipes` — shipped TOML recipes and their builders.

Shared pieces: :mod:`simulate.colliders` (MeshCollider over Open3D's RaycastingScene)
and :mod:`simulate.series_io` (VTP/.pvd series). simulate imports only procgen.
"""
