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
