"""Particle throughput (RK4 under gravity, drag and turbulence; fused kernel) against the
10 M particle-steps/s target, and a mesh-collision step against the bare ray casting of
its segments (same run)."""

import numpy as np
from _timing import best_of, report


def main():
    import open3d as o3d

    from simulate.colliders import MeshCollider
    from simulate.collisions import ContactParams, collide
    from simulate.forces import ForceSet, Gravity, Turbulence, Wind
    from simulate.particles import advance_local

    n, sub = 1_000_000, 4
    rng = np.random.default_rng(0)
    x0 = rng.uniform(-1, 1, (n, 3))
    for kind in ("perlin", "curl"):
        fs = ForceSet([Gravity(), Wind((1.0, 0, 0), 0.2), Turbulence(2.0, 0.5, kind=kind,
                                                                      speed=0.3)])
        x, v = x0.copy(), np.zeros((n, 3))
        sec = best_of(lambda fs=fs, x=x, v=v: advance_local(fs, 0.0, x, v, 1.0, 1e-3,
                                                             method="rk4", substeps=sub))
        rate = n * sub / sec
        print(f"   RK4 + gravity + drag + {kind} turbulence: {rate / 1e6:.1f} M particle-steps/s")
        report(f"RK4 {kind} turbulence vs 10 M particle-steps/s", rate, 10e6, 1.0)

    col = MeshCollider(o3d.geometry.TriangleMesh.create_sphere(1.0, 40))
    m = 200_000
    p = rng.uniform(-0.6, 0.6, (m, 3))
    vel = rng.normal(size=(m, 3)) * 20
    h = 0.01
    fs = ForceSet([Gravity()])
    x1, v1 = p.copy(), vel.copy()
    advance_local(fs, 0, x1, v1, 1.0, h)
    inside = np.ones(m, bool)
    params = ContactParams(restitution=0.8)
    ours = best_of(lambda: collide(col, p, vel, x1, v1, h, params, inside=inside))
    peer = best_of(lambda: col.cast(p, x1 - p))
    _, _, st = collide(col, p, vel, x1, v1, h, params, inside=inside)
    print(f"   collision step: {m} particles, {st.impacts} impacts, {st.casts} casts; "
          f"{ours * 1e3:.0f} ms vs bare casting {peer * 1e3:.0f} ms")
    report("collision step / bare segment casting", ours, peer, 2.0, higher_is_better=False)


if __name__ == "__main__":
    main()
