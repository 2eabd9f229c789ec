"""City: roads by pattern with their local constraints, lots that front a street, buildings
from the split grammar, Boeing's street statistics, and the GIS files."""

import json

import numpy as np
import pytest

from core.validate import InputError
from procgen.city import (
    Box,
    CityConfig,
    Cylinder,
    Difference,
    Union,
    check_cityjson,
    city_cityjson,
    city_geojson,
    csg_mesh,
    generate_city,
    overlaps,
    parse_grammar,
    segments_cross,
    street_statistics,
)
from procgen.city.roads import city_maps, grow_roads
from procgen.sweeps import mesh_volume


@pytest.fixture(scope="module")
def city():
    cfg = CityConfig(size=800, max_segments=110, centres=2, parks=1, park_radius=80)
    return generate_city(np.random.default_rng(5), cfg)


def test_roads_respect_local_constraints(city):
    N, E = city.nodes, city.edges
    assert len(E) > 40
    a, b = N[E[:, 0]], N[E[:, 1]]
    assert not city.water(N).any()
    assert not city.park(N).any()
    for t in np.linspace(0, 1, 17):          # no road runs through water
        assert not city.water(a + t * (b - a)).any()
    for k in range(len(E)):                  # planar: segments meet only at nodes
        assert not np.isfinite(segments_cross(a[k], b[k], a, b)).any()
    d = np.linalg.norm(N[:, None] - N[None], axis=-1) + np.eye(len(N)) * 1e9
    assert d.min() > 0.3 * city.config.snap_radius * 0.99


def test_road_graph_is_connected(city):
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n, e = len(city.nodes), city.edges
    graph = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n))
    assert connected_components(graph, directed=False)[0] == 1


@pytest.mark.parametrize("pattern", ["grid", "radial", "organic", "elevation"])
def test_street_statistics_of_each_pattern_within_real_cities_ranges(pattern):
    """Boeing (2019): mean degree 2.5-3.6, dead ends <= 30 %, circuity 1.0-1.2; grids are
    ordered (phi >= 0.6, Chicago 0.90), organic towns not (phi <= 0.2, Charlotte 0.002)."""
    cfg = CityConfig(size=1000, max_segments=220, pattern=pattern)
    rng = np.random.default_rng(3)
    nodes, edges, _ = grow_roads(cfg, rng, city_maps(cfg, rng))
    s = street_statistics(nodes, edges)
    assert 2.5 <= s["mean_degree"] <= 3.6, s
    assert s["dead_end_share"] <= 0.3, s
    assert 1.0 <= s["circuity"] <= 1.2, s
    if pattern == "grid":
        assert s["orientation_order"] >= 0.6, s
    if pattern == "organic":
        assert s["orientation_order"] <= 0.2, s


def test_street_statistics_closed_forms():
    # a ring of 36 straight streets through degree-3 junctions with a spoke each: every
    # bearing bin once -> no order; spokes are dead ends (half the nodes)
    ang = np.radians(np.arange(36) * 10 + 5)
    ring = 100 * np.stack([np.cos(ang), np.sin(ang)], 1)
    spokes = 1.2 * ring
    nodes = np.vstack([ring, spokes])
    edges = [(i, (i + 1) % 36) for i in range(36)] + [(i, 36 + i) for i in range(36)]
    s = street_statistics(nodes, np.array(edges))
    assert s["orientation_order"] < 0.05
    assert s["dead_end_share"] == pytest.approx(0.5)
    assert s["mean_degree"] == pytest.approx(2.0)          # (36 * 3 + 36) / 72
    # a street bent through a degree-2 node: one street, circuity = path / chord
    s = street_statistics(np.array([[0.0, 0], [3, 4], [6, 0]]), np.array([[0, 1], [1, 2]]))
    assert s["streets"] == 1 and s["circuity"] == pytest.approx(10 / 6)


def test_lots_front_a_street_and_nothing_overlaps(city):
    from procgen.city.lots import road_area

    roads = road_area(city.nodes, city.edges, city.half_widths())
    assert len(city.lots) > 30
    for lot in city.lots:
        assert lot.polygon.distance(roads) < 0.6              # it touches a road
        assert lot.polygon.intersection(roads).area < 1e-6     # and stands beside it
        assert not city.water(np.asarray(lot.polygon.exterior.coords)).any()
    bad = overlaps(city)
    assert bad == {"building_building_m2": 0.0, "building_road_m2": 0.0,
                   "road_in_water_m": 0.0}


def test_every_building_has_floors_a_roof_and_windows_on_its_street_sides(city):
    from shapely.geometry import Point

    from procgen.city import ELEMENTS
    from procgen.city.lots import road_area

    roads = road_area(city.nodes, city.edges, city.half_widths())
    assert len(city.buildings) > 20
    roof_code = ELEMENTS.index("roof")
    for k, b in enumerate(city.buildings):
        assert b.floors >= 1 and b.height >= 3.0
        tris = city.triangles[city.owner[city.triangles[:, 0]] == k]
        el = city.element[city.owner[city.triangles[:, 0]] == k]
        assert np.any(el == roof_code) and len(tris)
        assert b.ridge >= b.height
        fp = b.footprint
        # a facade faces a street when a road lies within 15 m straight out of its middle
        names = ["front", "right", "back", "left"]
        for i, name in enumerate(names):
            p, q = fp[i], fp[(i + 1) % 4]
            out = np.array([q[1] - p[1], p[0] - q[0]]) / np.hypot(*(q - p))
            mid = 0.5 * (p + q)
            if roads.intersects(Point(*(mid + 15 * out)).buffer(1.0)):
                assert b.windows.get(name, 0) > 0, (k, name, b.windows)
        assert b.doors.get("front", 0) >= 1


def test_building_heights_follow_the_population(city):
    from scipy.stats import spearmanr

    pop = city.density(city.footprints[:, :2])
    assert spearmanr(pop, city.heights).statistic >= 0.6


def test_cityjson_solids_are_closed_outward_and_hold_the_roof_volume(city):
    from procgen.city.io import _lod2_surfaces

    doc = city_cityjson(city)
    assert check_cityjson(doc) == []
    kinds = {b.roof for b in city.buildings}
    assert kinds >= {"flat", "gable"}
    for b in city.buildings[:40]:
        polys, _ = _lod2_surfaces(b)
        vol = sum(np.dot(p[0], np.cross(p[k], p[k + 1])) / 6.0 for p in polys
                  for k in range(1, len(p) - 1))
        L, W = sorted([np.linalg.norm(b.footprint[1] - b.footprint[0]),
                       np.linalg.norm(b.footprint[3] - b.footprint[0])], reverse=True)
        h = b.ridge - b.height
        roof = {"flat": 0.0, "gable": 0.5 * L * W * h, "hip": W * h * (3 * L - W) / 6}[b.roof]
        assert vol == pytest.approx(L * W * b.height + roof, rel=1e-6)
    # a broken shell is caught
    obj = next(iter(doc["CityObjects"].values()))
    obj["geometry"][0]["boundaries"][0].pop()
    assert any("not closed" in e for e in check_cityjson(doc))


def test_geojson_is_read_by_gdal(city, tmp_path):
    import pyogrio

    gj = city_geojson(city)
    assert {f["properties"]["kind"] for f in gj["roads"]["features"]} <= {"highway", "street"}
    for name in ("roads", "lots", "buildings"):
        path = tmp_path / f"c.{name}.geojson"
        path.write_text(json.dumps(gj[name]))
        info = pyogrio.read_info(path)
        assert info["features"] == len(gj[name]["features"])
    meta, _, geom, fields = pyogrio.raw.read(tmp_path / "c.buildings.geojson")
    assert "floors" in list(meta["fields"]) and len(geom) == len(city.buildings)


def test_split_grammar_sizes_and_repeats():
    from procgen.city.cga import build

    rules = {"axiom": "Lot", "attributes": {"floor_height": 3.0},
             "rules": {"Lot": {"op": "extrude", "height": "height", "then": "Mass"},
                       "Mass": {"op": "comp", "front": "F", "top": "Top"},
                       "Top": {"op": "roof", "kind": "flat"},
                       "F": {"op": "split", "axis": "y", "parts": [
                           {"size": 4.0, "then": "G"},
                           {"size": "~floor_height", "then": "Fl", "repeat": True}]},
                       "G": {"op": "door"},
                       "Fl": {"op": "split", "axis": "x", "parts": [
                           {"size": "~2.5", "then": "W", "repeat": True}]},
                       "W": {"op": "window", "depth": 0.2}}}
    g = parse_grammar(rules)
    fp = np.array([[0.0, 0], [10, 0], [10, 8], [0, 8]])
    geo = build(g, fp, floors=4, height=4.0 + 3 * 3.0, rng=np.random.default_rng(0))
    # 3 upper floors of 3 m, each 10 m cut into 4 tiles of 2.5 m: 12 windows, one door
    assert geo.windows == {"front": 12} and geo.doors == {"front": 1}
    v, f, lab = geo.mesh()
    win = f[lab == 1]
    area = 0.5 * np.linalg.norm(np.cross(v[win[:, 1]] - v[win[:, 0]],
                                         v[win[:, 2]] - v[win[:, 0]]), axis=1).sum()
    assert area == pytest.approx(9.0 * 10.0)        # the windows fill the upper floors
    # the facade is the plane y = 0 facing -y: windows are recessed 0.2 m behind it
    assert np.allclose(v[f[lab == 1].ravel(), 1], 0.2)


def test_rule_file_errors_name_the_field():
    with pytest.raises(InputError, match=r"rules\.F\.op.*unknown shape operation 'spilt'"):
        parse_grammar({"rules": {"Lot": {"op": "extrude", "then": "F"},
                                 "F": {"op": "spilt", "axis": "y"}}}, source="x.toml")
    with pytest.raises(InputError, match=r"rules\.Lot\.then.*no rule named 'Nope'"):
        parse_grammar({"rules": {"Lot": {"op": "extrude", "then": "Nope"}}})
    with pytest.raises(InputError, match=r"parts\[0\]\.size.*unknown attribute 'tile'"):
        parse_grammar({"rules": {"Lot": {"op": "split", "axis": "x",
                                         "parts": [{"size": "~tile"}]}}})


def test_maps_of_the_wrong_size_are_refused():
    cfg = CityConfig(size=600)
    with pytest.raises(InputError, match="population.*square"):
        city_maps(cfg, np.random.default_rng(0), population=np.ones((20, 30)),
                  paths={"population": "pop.npy"})
    with pytest.raises(InputError, match=r"water.*shape of the population map \(20, 20\)"):
        city_maps(cfg, np.random.default_rng(0), population=np.ones((20, 20)),
                  water=np.zeros((40, 40)))


def test_a_population_map_steers_the_roads():
    """Population only in the east half: roads grow there."""
    pop = np.zeros((64, 64))
    pop[:, 40:] = 1.0
    cfg = CityConfig(size=800, max_segments=80, river_width=0, parks=0)
    rng = np.random.default_rng(1)
    maps = city_maps(cfg, rng, population=pop)
    nodes, _, _ = grow_roads(cfg, rng, maps)
    assert np.mean(nodes[:, 0] > 0) > 0.7


def test_csg_volume():
    solid = Difference(Union((Box((0, 0, 5), (5, 5, 5)), Box((0, 0, 12), (3, 3, 2)),
                              Cylinder((0, 0, 15), 2.0, 1.0))),
                       Box((0, -5, 1), (2, 1, 1.5)))
    want = 1000 + 144 + np.pi * 4 * 2 - 4 * 1 * 2.5
    v, f = csg_mesh(solid, voxel=0.25)
    assert mesh_volume(v, f) == pytest.approx(want, rel=0.02)
