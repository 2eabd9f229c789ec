"""City: local constraints hold on the grown road network; CSG buildings on free lots."""

import numpy as np
import pytest

from procgen.city import (
    Box,
    CityConfig,
    Cylinder,
    Difference,
    Union,
    csg_mesh,
    generate_city,
    segments_cross,
)
from procgen.sweeps import mesh_volume


@pytest.fixture(scope="module")
def city():
    cfg = CityConfig(size=1000, max_segments=80, voxel=3.0, centres=2, parks=1,
                     park_radius=80)
    return generate_city(np.random.default_rng(5), cfg)


def test_roads_respect_local_constraints(city):
    N, E = city.nodes, city.edges
    assert len(E) > 20
    a, b = N[E[:, 0]], N[E[:, 1]]
    # no road end in water or in a park; no road runs through water
    assert not city.water(N).any()
    assert not city.park(N).any()
    for t in np.linspace(0, 1, 9):
        assert not city.water(a + t * (b - a)).any()
    # planar: segments meet only at shared intersections
    for k in range(len(E)):
        t = segments_cross(a[k], b[k], a, b)
        assert not np.isfinite(t).any()
    # snapping: no two intersections closer than a fraction of the snap radius
    d = np.linalg.norm(N[:, None] - N[None], axis=-1) + np.eye(len(N)) * 1e9
    assert d.min() > 0.3 * city.config.snap_radius * 0.99


def test_lots_are_free(city):
    assert len(city.buildings) > 5
    fp = city.footprints
    c = fp[:, :2]
    r = np.hypot(fp[:, 2], fp[:, 3])
    d = np.linalg.norm(c[:, None] - c[None], axis=-1) + np.eye(len(c)) * 1e9
    assert np.all(d >= (r[:, None] + r[None]) - 1e-9)
    assert not city.water(c).any()


def test_csg_volume():
    # union of two boxes sharing a face plus a cylinder, minus a notch: closed form
    solid = Difference(Union((Box((0, 0, 5), (5, 5, 5)), Box((0, 0, 12), (3, 3, 2)),
                              Cylinder((0, 0, 15), 2.0, 1.0))),
                       Box((0, -5, 1), (2, 1, 1.5)))
    want = 1000 + 144 + np.pi * 4 * 2 - 4 * 1 * 2.5  # notch: x 4, y 1 (inside), z 2.5
    v, f = csg_mesh(solid, voxel=0.25)
    assert mesh_volume(v, f) == pytest.approx(want, rel=0.02)


def test_roads_follow_the_population_global_goal(city):
    # global goal: roads grow toward dense areas, so road nodes sit on denser ground than
    # the land (not water, not park) at large
    half = city.config.size / 2
    p = np.random.default_rng(0).uniform(-half, half, (4000, 2))
    land = p[~city.water(p) & ~city.park(p)]
    assert city.density(city.nodes).mean() > 1.2 * city.density(land).mean()


def test_road_graph_is_connected(city):
    """One network: every intersection reaches every other along the roads."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = len(city.nodes)
    e = city.edges
    graph = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n))
    used = np.unique(e)
    count, label = connected_components(graph, directed=False)
    assert len(np.unique(label[used])) == 1


def test_buildings_stand_inside_their_lots_clear_of_roads_and_each_other(city):
    from procgen.city import HIGHWAY_HALF_WIDTH, STREET_HALF_WIDTH, _point_segment_distance

    cfg, fp, fr = city.config, city.footprints, city.lot_frames
    a, b = city.nodes[city.edges[:, 0]], city.nodes[city.edges[:, 1]]
    halfw = np.where(city.highway, HIGHWAY_HALF_WIDTH, STREET_HALF_WIDTH)
    for (cx, cy, hx, hy), (angle, _) in zip(fp, fr, strict=True):
        # the building's base box is the footprint: inside the lot (width x depth)
        assert hx <= cfg.lot_width / 2 and hy <= cfg.lot_depth / 2
        d, n = np.array([np.cos(angle), np.sin(angle)]), np.array([-np.sin(angle),
                                                                    np.cos(angle)])
        corners = [np.array([cx, cy]) + i * hx * d + j * hy * n for i in (-1, 1)
                   for j in (-1, 1)]
        for c in corners:   # clear of every road ribbon (highways wider than streets)
            dist, _ = _point_segment_distance(c, a, b)
            assert np.min(dist - halfw) > 0.0
    # the first building's mesh lies within its footprint (CSG, meshed)
    v, _ = csg_mesh(city.buildings[0], voxel=1.0)
    hx, hy = fp[0, 2], fp[0, 3]
    assert np.abs(v[:, 0]).max() <= hx + 1.0 and np.abs(v[:, 1]).max() <= hy + 1.0


def test_building_heights_follow_the_population(city):
    from scipy.stats import spearmanr

    pop = city.density(city.footprints[:, :2])
    rho = spearmanr(pop, city.heights).statistic
    assert rho >= 0.7, rho
