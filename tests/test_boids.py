import numpy as np
import open3d as o3d
import pytest

from simulate.boids import BoidParams, FlockState, init_flock, load_recipe, step
from simulate.boids.metrics import milling, polarization
from simulate.colliders import MeshCollider
from simulate.stand_ins import stand_in_mesh


def _copy(s):
    return FlockState(s.positions, s.velocities, s.wander)


def _run(params, n, steps, seed, *, collider=None, method="grid", radius=4.0, centre=(0, 0, 0)):
    rng = np.random.default_rng(seed)
    s = init_flock(n, params, rng=rng, radius=radius, centre=centre)
    out = []
    for _ in range(steps):
        step(s, params, rng=rng, collider=collider, method=method)
        out.append((polarization(s.velocities), milling(s.positions, s.velocities)))
    return s, np.array(out)


FULL = dict(fov_deg=250, wander_weight=0.4, goal=(6.0, 0, 0), goal_weight=0.5, leaders=3,
            leader_weight=1.0, bounds=((-8, -8, -8), (8, 8, 8)))


@pytest.mark.parametrize("params", [
    BoidParams(**FULL),
    BoidParams(model="couzin", zor=0.6, zoo=1.5, zoa=4.0, fov_deg=270,
               bounds=((-8, -8, -8), (8, 8, 8))),
    BoidParams(fov_deg=360, bounds=None),
], ids=["reynolds-all-behaviours", "couzin", "reynolds-open"])
def test_grid_agrees_with_all_pairs_reference(params):
    rng = np.random.default_rng(5)
    s = init_flock(600, params, rng=rng, radius=5.0)
    a, b = _copy(s), _copy(s)
    ra, rb = np.random.default_rng(9), np.random.default_rng(9)
    for _ in range(8):
        step(a, params, rng=ra)
        step(b, params, rng=rb, method="reference")
        np.testing.assert_allclose(a.positions, b.positions, rtol=0, atol=1e-10)
        np.testing.assert_allclose(a.velocities, b.velocities, rtol=0, atol=1e-10)


def test_parallel_path_agrees_with_reference():
    # above the one-thread threshold: prange over cell-sorted boids
    p = BoidParams(bounds=((-12, -12, -12), (12, 12, 12)))
    rng = np.random.default_rng(2)
    s = init_flock(5000, p, rng=rng, radius=11.0)
    a, b = _copy(s), _copy(s)
    step(a, p, rng=np.random.default_rng(0))
    step(b, p, rng=np.random.default_rng(0), method="reference")
    np.testing.assert_allclose(a.velocities, b.velocities, rtol=0, atol=1e-10)


def test_same_seed_same_bytes():
    p = BoidParams(**FULL)
    a, _ = _run(p, 300, 20, 3)
    b, _ = _run(p, 300, 20, 3)
    assert a.positions.tobytes() == b.positions.tobytes()
    assert a.velocities.tobytes() == b.velocities.tobytes()


def test_cohesive_flock_aligns_from_random_headings():
    # no noise, no wander; cohesion and alignment reach across the start ball
    p = BoidParams(separation_radius=0.5, alignment_radius=3.0, cohesion_radius=4.0,
                   fov_deg=360, max_speed=2.0, min_speed=1.0, max_force=2.0, bounds=None)
    _, pm = _run(p, 150, 500, 11, radius=3.0)
    assert pm[0, 0] < 0.4
    assert pm[:, 0].max() >= 0.95
    assert pm[-1, 0] >= 0.95


@pytest.mark.parametrize("phase", ["swarm", "torus", "parallel"])
def test_couzin_phases(phase):
    r = load_recipe(phase)
    _, pm = _run(r.params, r.n, 900, 1, radius=r.init_radius)
    P, M = pm[600:].mean(axis=0)  # time averages after the transient
    if phase == "swarm":
        assert P < 0.35 and M < 0.35
    elif phase == "torus":
        assert P < 0.35 and M > 0.7
    else:
        assert P > 0.9 and M < 0.15


def _crossings(collider, x0, x1):
    h = collider.cast(x0, x1 - x0)
    return int(np.count_nonzero(h.hit & (h.t <= 1.0)))


@pytest.mark.slow
@pytest.mark.parametrize("avoid", [6.0, 0.0], ids=["avoiding", "guarantee-only"])
def test_no_boid_passes_through_a_scan(avoid):
    # 1000 boids x 500 steps, twice: 10^6 boid-steps around a bumpy closed scan, all
    # seeking a goal inside it (the worst case: they press on the surface all the time)
    col = MeshCollider(stand_in_mesh("scan", 3.0))
    p = BoidParams(dt=0.05, separation_radius=0.4, alignment_radius=1.0, cohesion_radius=1.5,
                   goal=(0.0, 0, 0), goal_weight=1.0, max_speed=4.0, min_speed=1.0,
                   max_force=6.0, wander_weight=0.3, avoid_weight=avoid,
                   bounds=((-12, -12, -12), (12, 12, 12)))
    rng = np.random.default_rng(4)
    s = init_flock(3000, p, rng=rng, radius=10.0)
    keep = np.nonzero(~col.inside(s.positions) & (col.distance(s.positions) > 0.05))[0][:1000]
    s = FlockState(s.positions[keep], s.velocities[keep], s.wander[keep])
    crossings = inside = 0
    for k in range(500):
        x0 = s.positions.copy()
        step(s, p, rng=rng, collider=col)
        crossings += _crossings(col, x0, s.positions)  # any path through crosses a face
        if k % 10 == 0:
            inside += int(col.inside(s.positions).sum())
    assert crossings == 0 and inside == 0
    if avoid == 0:
        assert s.collisions > 1000  # the swept-segment guarantee was exercised


def test_avoidance_steers_before_contact():
    col = MeshCollider(o3d.geometry.TriangleMesh.create_sphere(radius=2.0, resolution=30))
    hits = {}
    for w in (0.0, 8.0):
        p = BoidParams(alignment_weight=0, cohesion_weight=0, separation_weight=0,
                       max_speed=2.0, min_speed=2.0, max_force=8.0, avoid_weight=w,
                       look_ahead=1.5, bounds=None, dt=0.05)
        x = np.c_[np.full(50, -6.0), np.linspace(-1, 1, 50), np.zeros(50)]
        s = FlockState(x, np.tile([2.0, 0, 0], (50, 1)), np.tile([1.0, 0, 0], (50, 1)))
        rng = np.random.default_rng(0)
        for _ in range(80):
            step(s, p, rng=rng, collider=col)
        hits[w] = s.collisions
    assert hits[0.0] >= 50 and hits[8.0] == 0


def test_world_bounds_hold():
    p = BoidParams(max_speed=5.0, min_speed=4.0, bounds=((-3, -3, -3), (3, 3, 3)),
                   bounds_margin=0.5, wander_weight=1.0)
    s, _ = _run(p, 300, 200, 0, radius=2.5)
    assert np.all(np.abs(s.positions) <= 3.0)


def test_bad_input():
    with pytest.raises(ValueError, match="separation_radius"):
        BoidParams(separation_radius=0)
    with pytest.raises(ValueError, match="cohesion_weight"):
        BoidParams(cohesion_weight=-1)
    with pytest.raises(ValueError, match="fov_deg"):
        BoidParams(fov_deg=400)
    with pytest.raises(ValueError, match="zor, zoo, zoa"):
        BoidParams(model="couzin", zor=2, zoo=1, zoa=3)
    with pytest.raises(ValueError, match="model"):
        BoidParams(model="vicsek")
    with pytest.raises(ValueError, match="min_speed"):
        BoidParams(min_speed=3, max_speed=2)
    with pytest.raises(ValueError, match="bounds"):
        BoidParams(bounds=((0, 0, 0), (1, 1, 1)))
    with pytest.raises(ValueError, match="probe_rays"):
        BoidParams(probe_rays=0)
    with pytest.raises(ValueError, match="n"):
        init_flock(0, BoidParams(), rng=np.random.default_rng(0))
    p = BoidParams()
    s = init_flock(5, p, rng=np.random.default_rng(0))
    s.velocities[2, 1] = np.nan
    with pytest.raises(ValueError, match="finite"):
        step(s, p, rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match="positions"):
        FlockState(np.full((2, 3), np.inf), np.zeros((2, 3)), np.zeros((2, 3)))
    with pytest.raises(ValueError, match="method"):
        step(init_flock(5, p, rng=np.random.default_rng(0)), p,
             rng=np.random.default_rng(0), method="kdtree")
    with pytest.raises(ValueError, match="faces"):
        MeshCollider(o3d.geometry.TriangleMesh())


def test_goal_seeking_and_leader_following():
    # one leader seeks a goal; the others follow a point behind it
    p = BoidParams(separation_radius=0.3, alignment_weight=0, cohesion_weight=0,
                   goal=(20.0, 0, 0), goal_weight=1.0, leaders=1, leader_weight=1.0,
                   leader_distance=1.0, max_speed=3.0, min_speed=0.0, max_force=4.0,
                   bounds=None)
    rng = np.random.default_rng(0)
    s = init_flock(30, p, rng=rng, radius=3.0)
    for _ in range(300):
        step(s, p, rng=rng)
    leader = s.positions[0]
    assert np.linalg.norm(leader - [20, 0, 0]) < 2.0  # circles the goal within a turn radius
    d = np.linalg.norm(s.positions[1:] - leader, axis=1)
    assert np.median(d) < 3.0


@pytest.mark.parametrize("fov", [180.0, 360.0])
def test_field_of_view_cone_hides_boids_behind(fov):
    # A at the origin and B 1 m behind it, both flying +x; cohesion only. With a 180 deg
    # cone A cannot see B (straight behind) while B sees A ahead; all round both steer.
    p = BoidParams(fov_deg=fov, separation_weight=0.0, alignment_weight=0.0,
                   cohesion_weight=1.0, cohesion_radius=3.0, min_speed=0.0, max_speed=5.0,
                   max_force=10.0, bounds=None)
    s = FlockState(np.array([[0.0, 0, 0], [-1.0, 0, 0]]), np.array([[1.0, 0, 0], [1.0, 0, 0]]),
                   np.zeros((2, 3)))
    step(s, p, rng=np.random.default_rng(0))
    assert s.velocities[1, 0] > 1.0 + 1e-3  # B speeds up toward A
    if fov == 180.0:
        assert s.velocities[0, 0] == 1.0  # A saw nothing
    else:
        assert s.velocities[0, 0] < 1.0 - 1e-3  # A turns back toward B
