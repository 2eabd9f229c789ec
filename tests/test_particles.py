import logging

import numpy as np
import open3d as o3d
import pytest

from simulate.colliders import MeshCollider
from simulate.forces import ForceSet, Gravity, Wind
from simulate.particles import KillPlane, Look, NonFiniteStateError, ParticleSystem, Ramp, Sink
from simulate.particles.emitters import (
    BoxShape,
    DiscShape,
    Emitter,
    MeshSurface,
    VelocityDist,
    birth_count,
    birth_count_moments,
)


@pytest.mark.parametrize("mean,std", [(20.0, 5.0), (1.0, 2.0)])
def test_birth_counts_mean_and_variance(mean, std):
    rng = np.random.default_rng(3)
    n = 40_000
    k = np.array([birth_count(rng, mean, std) for _ in range(n)])
    m, var = birth_count_moments(mean, std)
    assert k.min() >= 0
    # 5 standard errors (mean: sqrt(var / n); variance: ~ var sqrt(2 / n) for near-normal)
    assert abs(k.mean() - m) < 5 * np.sqrt(var / n)
    assert abs(k.var() - var) < 5 * var * np.sqrt(2 / n) + 5 * np.sqrt(var / n)


def test_mesh_surface_sampling_is_area_weighted(rng):
    # two triangles, areas 1 and 3 in the z = 0 plane
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 2, 0], [5, 0, 0], [8, 0, 0], [5, 2, 0]], float)
    f = np.array([[0, 1, 2], [3, 4, 5]])
    pts, nrm = MeshSurface(v, f).sample(40_000, rng)
    frac_second = np.mean(pts[:, 0] >= 5)
    assert frac_second == pytest.approx(0.75, abs=0.01)
    np.testing.assert_allclose(nrm, np.tile([0, 0, 1.0], (40_000, 1)))


def test_velocity_cone_stays_in_cone(rng):
    vd = VelocityDist(kind="cone", direction=(0, 0, 2), speed=3.0, spread_deg=20)
    vel = vd.sample(np.zeros((5000, 3)), rng)
    np.testing.assert_allclose(np.linalg.norm(vel, axis=1), 3.0)
    cos = vel[:, 2] / 3.0
    assert cos.min() >= np.cos(np.radians(20)) - 1e-12
    # uniform on the cap: mean cos = (1 + cos_max) / 2
    assert cos.mean() == pytest.approx((1 + np.cos(np.radians(20))) / 2, abs=2e-3)


def _system(seed, **kw):
    em = Emitter(shape=DiscShape(radius=0.2), rate=30, rate_std=5,
                 velocity=VelocityDist(speed=4.0, speed_std=0.5), lifetime=1.0,
                 lifetime_std=0.2, name="jet")
    opts = {"forces": ForceSet([Gravity(), Wind((1, 0, 0), 0.05)]), "dt": 1 / 24,
            "substeps": 2, "looks": {"jet": Look(color=Ramp((0, 1), ((1, 1, 1), (1, 0, 0))),
                                                 size=Ramp((0, 1), (0.02, 0.0)))}}
    opts.update(kw)
    return ParticleSystem([em], rng=np.random.default_rng(seed), **opts)


def test_deaths_by_age_and_kill_plane_and_reproducible():
    a = _system(5, kill_planes=[KillPlane((0, 0, -0.5), (0, 0, 1))])
    stats = [a.step_frame() for _ in range(60)]
    s = a.state
    assert np.all(s["age"] < s["lifetime"]) and np.all(s["x"][:, 2] >= -0.5)
    assert sum(st.died for st in stats) > 0
    assert sum(st.born for st in stats) - sum(st.died for st in stats) == a.count
    b = _system(5, kill_planes=[KillPlane((0, 0, -0.5), (0, 0, 1))])
    for _ in range(60):
        b.step_frame()
    np.testing.assert_array_equal(a.state["x"], b.state["x"])
    fr = a.frame()
    assert fr["colors"].shape == (a.count, 3) and np.all(fr["sizes"] <= 0.02)
    # ids are unique and increase with birth
    assert len(np.unique(fr["ids"])) == a.count


def test_sink_removes_particles():
    """A sink deletes exactly the particles that enter it: beside a twin system without the
    sink (same seed), the survivors are the twin's particles that never entered, with the
    same positions, and nothing else is lost."""
    box = Sink(kind="box", lo=(-5, -5, 0.3), hi=(5, 5, 5))
    a = _system(1, sinks=[box])
    free = _system(1)
    entered: set[int] = set()
    for _ in range(20):
        a.step_frame()
        free.step_frame()
        entered |= set(free.state["id"][box.contains(free.state["x"])].tolist())
        assert not box.contains(a.state["x"]).any()
    ids_a, ids_free = a.state["id"], free.state["id"]
    assert entered and 0 < len(ids_a) < len(ids_free)
    expect = np.array(sorted(set(ids_free.tolist()) - entered))
    np.testing.assert_array_equal(np.sort(ids_a), expect)
    xa = a.state["x"][np.argsort(ids_a)]
    xf = free.state["x"][np.isin(ids_free, expect)][np.argsort(ids_free[np.isin(ids_free,
                                                                                 expect)])]
    np.testing.assert_allclose(xa, xf, atol=1e-12)


def test_bursts_on_death():
    rocket = Emitter(rate=1, velocity=VelocityDist(speed=10), lifetime=0.5, name="rocket",
                     stop=0.01)
    spark = Emitter(rate=50, velocity=VelocityDist(kind="sphere", speed=2.0), lifetime=0.3,
                    burst_of="rocket", name="spark")
    ps = ParticleSystem([rocket, spark], ForceSet([Gravity()]), np.random.default_rng(0),
                        dt=0.05, looks={"spark": Look(palette=((1, 0, 0), (0, 1, 0)))})
    counts = [ps.step_frame().alive for _ in range(12)]
    assert max(counts) == 50 and counts[0] == 1
    with pytest.raises(ValueError, match="burst_of"):
        ParticleSystem([Emitter(burst_of="nope")], ForceSet([]), np.random.default_rng(0))


def test_non_finite_state_stops_with_step_and_particle():
    ps = _system(2)
    for _ in range(3):
        ps.step_frame()
    ps.state["v"][4] = np.inf  # e.g. a force that blew up
    bad_id = int(ps.state["id"][4])
    with pytest.raises(NonFiniteStateError, match=rf"step 7 .*particle id {bad_id}\b") as info:
        ps.step_frame()
    assert info.value.particle == bad_id


def test_collider_keeps_particles_and_reports_escapes():
    sphere = MeshCollider(o3d.geometry.TriangleMesh.create_sphere(1.0, 16))
    em = Emitter(shape=BoxShape((-0.3,) * 3, (0.3,) * 3), rate=50,
                 velocity=VelocityDist(kind="sphere", speed=8.0), lifetime=10, name="gas")
    ps = ParticleSystem([em], ForceSet([Gravity()]), np.random.default_rng(0), substeps=2,
                        collider=sphere)
    stats = [ps.step_frame() for _ in range(30)]
    assert sum(s.impacts for s in stats) > 100
    assert sum(s.escapes for s in stats) == 0
    assert sphere.signed_distance(ps.state["x"]).max() < 1e-6


def test_step_size_warning(caplog):
    with caplog.at_level(logging.WARNING):
        _system(0, forces=ForceSet([Wind(drag=100.0)]), method="euler", substeps=1)
    assert "stability limit" in caplog.text


def test_package_names_its_public_api():
    import simulate
    from simulate.boids import step

    assert all(getattr(simulate, name) is not None for name in simulate.__all__)
    assert simulate.step_flock is step and simulate.ParticleSystem is ParticleSystem
    with pytest.raises(AttributeError):
        simulate.no_such_name  # noqa: B018


def test_attributes_follow_age_and_temperature():
    # temperature cools exponentially to ambient; colour is a ramp of temperature,
    # mass a ramp of age: every particle's attributes are the closed forms of its own age
    em = Emitter(shape=DiscShape(radius=0.1), rate=20, velocity=VelocityDist(speed=0.0),
                 lifetime=10.0, mass=2.0, temperature=1000.0, name="hot")
    look = Look(color=Ramp((300.0, 1000.0), ((0.2, 0.2, 0.2), (1.0, 0.5, 0.0)), by="temperature"),
                mass=Ramp((0.0, 1.0), (1.0, 0.5), by="age"))
    ps = ParticleSystem([em], forces=ForceSet([]), dt=0.1, substeps=1, looks={"hot": look},
                        cooling_time=0.5, ambient=300.0, rng=np.random.default_rng(0))
    for _ in range(8):
        ps.step_frame()
    fr = ps.frame()
    age = fr["age"]
    assert len(np.unique(np.round(age, 9))) > 3
    temp = 300.0 + 700.0 * np.exp(-age / 0.5)
    np.testing.assert_allclose(fr["temperature"], temp, rtol=1e-12)
    f = (temp - 300.0) / 700.0
    np.testing.assert_allclose(fr["colors"][:, 0], 0.2 + 0.8 * f, atol=1e-12)
    np.testing.assert_allclose(fr["colors"][:, 1], 0.2 + 0.3 * f, atol=1e-12)
    np.testing.assert_allclose(ps.state["mass"], 2.0 * np.interp(age, [0, 1], [1.0, 0.5]),
                               rtol=1e-12)
