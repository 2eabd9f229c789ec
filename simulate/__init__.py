"""simulate: procedural animation — integrators, forces, particles, collisions, cloth, boids.

Shared pieces: :mod:`simulate.colliders` (MeshCollider over Open3D's RaycastingScene)
and :mod:`simulate.series_io` (VTP/.pvd series). simulate imports only procgen.
"""
