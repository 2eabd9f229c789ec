"""Weber & Penn species trees where scenes plant trees: a placed tree has the height, crown
radius and dbh asked; forest stands (scene forest, LiDAR stands) grow the species named;
the city lines its streets and fills its parks with them."""

from __future__ import annotations

import numpy as np
import pytest

from core.validate import InputError
from procgen.weber_penn import grow, load_species
from procgen.weber_penn.placement import (
    SpeciesTrees,
    crown_area_radius,
    species_map,
    stem_dbh,
)


def test_species_map_reads_codes_and_names():
    assert species_map("") == {}
    assert species_map("all")["PIAB"] == "norway_spruce"
    assert species_map("fasy, QURO=CA black oak") == {"FASY": "european_beech",
                                                       "QURO": "ca_black_oak"}
    with pytest.raises(ValueError, match="unknown species 'baobab'"):
        species_map("FASY=baobab")
    with pytest.raises(ValueError, match="'QURO' has no species file"):
        species_map("QURO")


def test_a_placed_tree_has_the_height_crown_and_dbh_asked():
    trees = SpeciesTrees(lod="cards")
    t = trees.place("european_beech", position=(3.0, -2.0, 5.0), height=14.0, crown_radius=4.5,
                    dbh=0.31, azimuth=0.7, rng=np.random.default_rng(1))
    assert t.vertices[:, 2].max() == pytest.approx(19.0, abs=1e-9)
    crown = t.parts > 0
    used = np.unique(t.triangles[crown])
    assert crown_area_radius(t.vertices[used, :2]) == pytest.approx(4.5, rel=0.02)
    assert t.crown_radius == pytest.approx(4.5, rel=1e-9)
    assert t.dbh == pytest.approx(0.31, rel=0.05)
    # the trunk stands on its position: its lowest ring is centred there
    trunk = np.unique(t.triangles[t.parts == 0])
    low = trunk[t.vertices[trunk, 2] < 5.0 + 0.05]
    np.testing.assert_allclose(t.vertices[low, :2].mean(0), [3.0, -2.0], atol=0.02)
    assert set(np.unique(t.parts).tolist()) == {0, 1, 2}


def test_stem_dbh_is_the_trunk_diameter_at_breast_height():
    tree = grow(load_species("sycamore_maple"), height=12.0, rng=np.random.default_rng(0))
    sk = tree.skeleton
    a, b = sk.ptr[0], sk.ptr[1]
    z = sk.points[a:b, 2]
    i = np.searchsorted(z, 1.3)
    assert sk.radius[a + i] * 2 <= stem_dbh(tree) <= sk.radius[a + i - 1] * 2
    small = grow(load_species("sycamore_maple"), height=1.0, rng=np.random.default_rng(0))
    assert stem_dbh(small) == 2 * small.skeleton.radius[0]


def test_variants_place_scaled_copies():
    trees = SpeciesTrees(lod="cards", variants=1)
    a = trees.place("scots_pine", position=(0, 0, 0), height=10.0, rng=np.random.default_rng(0))
    b = trees.place("scots_pine", position=(0, 0, 0), height=20.0, rng=np.random.default_rng(1))
    assert len(a.vertices) == len(b.vertices)
    np.testing.assert_allclose(b.vertices, 2 * a.vertices, atol=1e-9)
    assert b.dbh == pytest.approx(2 * a.dbh) and b.crown_radius == pytest.approx(2 * a.crown_radius)


def _stand(**kw):
    from data_synth.forest import ForestConfig, build_forest

    cfg = ForestConfig(size=14.0, margin=2.0, density=300.0, species="PIAB:0.5,FASY:0.5",
                       understory=0.0, **kw)
    return build_forest(cfg, seed=5)


def test_a_forest_grows_the_species_named_with_their_heights_and_crowns():
    from core.meshes import mesh_arrays

    b = _stand(weber_penn="FASY")
    tr = b.trees
    objs = {o.name: o for o in b.render_scene.objects}
    beech = np.flatnonzero(tr["species"] == "FASY")
    spruce = np.flatnonzero(tr["species"] == "PIAB")
    assert len(beech) and len(spruce)
    for k in range(len(tr["x"])):
        v = np.vstack([mesh_arrays(o.mesh)[0] for n, o in objs.items()
                       if n.startswith(f"tree{k + 1:05d}.")])
        # every tree's top is ground + height, whichever model grew it
        assert v[:, 2].max() == pytest.approx(tr["z_ground"][k] + tr["height"][k], abs=1e-6)
        if k in beech:
            # a Weber & Penn beech: the crown radius of the truth is its projection's
            assert crown_area_radius(v[:, :2]) == pytest.approx(tr["crown_radius"][k], rel=0.05)
            leaf = mesh_arrays(objs[f"tree{k + 1:05d}.leaf"].mesh)[1]
            assert len(leaf) % 2 == 0     # leaf cards: two triangles each


def test_a_forest_refuses_an_unknown_species():
    with pytest.raises(InputError, match="forest.weber_penn.*baobab"):
        _stand(weber_penn="FASY=baobab")


@pytest.fixture(scope="module")
def treed_city():
    from procgen.city import CityConfig, generate_city

    cfg = CityConfig(size=400.0, max_segments=14, parks=1, park_radius=60.0, river_width=0.0,
                     tree_species="lombardy_poplar,ca_black_oak", tree_spacing=15.0,
                     park_trees=60.0)
    return generate_city(np.random.default_rng(3), cfg)


def test_street_trees_line_the_verges_and_park_trees_stand_in_parks(treed_city):
    from procgen.city.lots import road_area

    city, tr = treed_city, treed_city.trees
    assert {"street", "park"} <= set(tr.kind.tolist())
    xy = tr.positions[:, :2]
    # a street tree is a verge away from the nearest roadway's centreline: its half width
    # plus 1.5 m (at a bend or crossing a farther road may be nearer: most, not all)
    a, b = city.nodes[city.edges[:, 0]], city.nodes[city.edges[:, 1]]
    st = xy[tr.kind == "street"]
    d = b - a
    s = np.clip(np.einsum("kej,ej->ke", st[:, None, :] - a[None], d)
                / np.einsum("ej,ej->e", d, d), 0, 1)
    foot = a[None] + s[..., None] * d[None]
    dist = np.linalg.norm(st[:, None, :] - foot, axis=2) - city.half_widths()[None]
    assert np.mean(np.abs(dist.min(1) - 1.5) < 1e-6) > 0.8
    # none stands on a roadway, in a building or (park trees) outside a park
    import shapely
    roads = road_area(city.nodes, city.edges, city.half_widths())
    assert not shapely.intersects(roads, shapely.points(xy)).any()
    for bld in city.buildings:
        assert not shapely.Polygon(bld.footprint).buffer(0.5).intersects(
            shapely.MultiPoint(xy))
    assert np.asarray(city.park(xy[tr.kind == "park"]), bool).all()


def test_each_city_tree_has_its_species_height(treed_city):
    from procgen.weber_penn import load_species

    tr = treed_city.trees
    mesh_tops = []
    st = tr.stand
    for k in range(len(tr.positions)):
        p = load_species(str(tr.species[k]))
        lo, hi = p["Scale"] - p["ScaleV"], p["Scale"] + p["ScaleV"]
        assert lo - 1e-9 <= tr.heights[k] <= hi + 1e-9
        m = st.templates[st.template[k]]
        s = st.world_from_tree[k, 2, 2]
        mesh_tops.append(s * m.vertices[:, 2].max())
    # the instanced tree's top is its height (leaves may reach a few percent above the
    # skeleton's top)
    np.testing.assert_allclose(mesh_tops, tr.heights, rtol=0.05)
    poplars = tr.species == "lombardy_poplar"        # 25 +- 5 m against the oak's 10 +- 5 m
    assert poplars.any() and (~poplars).any()
    assert tr.heights[poplars].min() > tr.heights[~poplars].max()


def test_a_city_without_trees_is_the_city_of_before():
    from procgen.city import CityConfig, generate_city

    cfg = dict(size=300.0, max_segments=8, parks=0, river_width=0.0)
    a = generate_city(np.random.default_rng(0), CityConfig(**cfg))
    b = generate_city(np.random.default_rng(0), CityConfig(**cfg, tree_species="palm"))
    assert a.trees is None and len(b.trees.positions) > 0
    assert np.array_equal(a.vertices, b.vertices) and np.array_equal(a.triangles, b.triangles)


def test_city_cli_writes_the_trees_and_refuses_an_unknown_species(tmp_path, capsys):
    from core.io.mesh import read_labeled_mesh
    from scanamp.amplify.labels import LABELS
    from scanamp.cli import main

    out = tmp_path / "city.ply"
    args = ["procgen", "city", "--out", str(out), "--size", "300", "--max-segments", "6",
            "--parks", "0", "--river-width", "0", "--no-preview", "--seed", "1"]
    assert main([*args, "--tree-species", "baobab"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "baobab" in err[0] and not out.exists()
    assert main([*args, "--tree-species", "scots_pine"]) == 0
    labels = read_labeled_mesh(out)["labels"]
    ids = {v: k for k, v in LABELS.items()}
    assert (labels == ids["bark"]).any() and (labels == ids["leaf"]).any()


def _distance_to(v, f, pts):
    import open3d as o3d

    tm = o3d.t.geometry.TriangleMesh()
    tm.vertex.positions = o3d.core.Tensor(np.asarray(v, np.float32))
    tm.triangle.indices = o3d.core.Tensor(np.asarray(f, np.int32))
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(tm)
    return scene.compute_distance(o3d.core.Tensor(np.asarray(pts, np.float32))).numpy()


def _wall(width=6.0, height=6.0, n=30):
    from core.meshes import make_mesh
    from procgen.terrain import heightfield_to_mesh

    m = heightfield_to_mesh(np.zeros((n + 1, n + 1)), spacing=width / n)
    v = np.asarray(m.vertices)[:, [0, 2, 1]]   # the x-y grid stood up as the x-z plane
    v[:, 2] *= height / width
    return make_mesh(v, np.asarray(m.triangles)[:, ::-1])


def test_a_climbing_plant_stays_on_its_wall_and_climbs():
    from core.meshes import mesh_arrays
    from procgen.amplify.vines import LEAF_TILT_DEG, grow_vines

    wall = _wall()
    r, size = 0.01, 0.08
    res = grow_vines(wall, rng=np.random.default_rng(0), count=4, length=3.0, step=0.05,
                     radius=r, climb=0.8, branches=1.5, leaf_size=size, leaf_spacing=0.1)
    v, f = mesh_arrays(res.mesh)
    assert res.shoots > 0 and len(res.paths) == 4 + res.shoots
    # every point of stems, shoots and leaves within the bound the docstring states
    bound = 2 * r + 1.2 * size * np.sin(np.radians(LEAF_TILT_DEG))
    d = np.abs(v[:, 1])                     # the wall is the plane y = 0
    assert d.max() <= bound + 1e-9
    assert d[res.leaf].max() > 0.5 * bound   # leaves do stand off the wall
    # leaves face away from the wall (its normal is -y), on both sides of their stems
    lf = f[res.leaf[f].all(1)]
    n = np.cross(v[lf[:, 1]] - v[lf[:, 0]], v[lf[:, 2]] - v[lf[:, 0]])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    assert np.median(np.abs(n[:, 1])) > np.cos(np.radians(LEAF_TILT_DEG)) - 0.05
    # leaves every leaf_spacing along each stem: as many as the stems' length allows
    stems = sum(np.linalg.norm(np.diff(P, axis=0), axis=1).sum() for P in res.paths)
    assert abs(res.leaves - stems / 0.1) <= len(res.paths) + 1
    # main stems climb: their tips above their roots, by most of their length
    rise = [P[-1, 2] - P[0, 2] for P in res.paths[:4]]
    assert np.median(rise) > 0.5 * 3.0


def test_a_facade_grows_ivy_through_the_sweep_step(tmp_path):
    from core.io.mesh import read_labeled_mesh, write_mesh
    from core.meshes import make_mesh
    from data_synth.facades import facade_mesh
    from scanamp.amplify import run

    v, f, _ = facade_mesh(np.random.default_rng(1), width=12.0, height=9.0, floors=3, bays=4,
                          rotate=False)
    src = tmp_path / "facade.ply"
    write_mesh(src, make_mesh(v, f))
    recipe = tmp_path / "ivy.toml"
    recipe.write_text('[[step]]\nkind = "sweep"\ncount = 6\nlength = 0.3\nstep = 0.004\n'
                      'radius = 0.0008\nslope_min_deg = 60.0\nclimb = 0.6\nbranches = 0.3\n'
                      'leaf_size = 0.006\n[render]\nwidth = 64\nheight = 48\n')
    out = run(src, recipe, tmp_path / "out", seed=2, up=(0.0, 0.0, 1.0))
    rep = __import__("json").loads((out / "report.json").read_text())
    step = rep["steps"][0]
    assert step["shoots"] > 0 and step["leaves"] > 0
    m = read_labeled_mesh(out / "mesh.ply")
    ids = {name: int(k) for k, name in m["names"].items()}
    lab = m["labels"]
    assert (lab == ids["vine"]).any() and (lab == ids["leaf"]).any()
    # the ivy stays on the facade: within the flat-surface bound of it (the facade's vertex
    # noise, 1 cm, added) but where a leaf overhangs an edge (a sill into the open window,
    # the cornice),
    # and never farther than a leaf's whole reach, blade and petiole
    diag = np.linalg.norm(v.max(0) - v.min(0))
    plant = (lab == ids["vine"]) | (lab == ids["leaf"])
    d = _distance_to(v, f, m["vertices"][plant])
    flat = (2 * 0.0008 + 1.2 * 0.006 * np.sin(np.radians(20.0))) * diag + 0.03
    assert np.mean(d <= flat) > 0.95
    assert d.max() <= (2 * 0.0008 + 1.2 * 0.006 * 4 / 3) * diag + 0.03
