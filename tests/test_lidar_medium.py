"""Foliage as a turbid medium: sub-rays through a layer of leaves of known leaf area index
cross it as Beer-Lambert says, and a pulse's echoes spread over the layer's depth."""

from __future__ import annotations

import numpy as np
import pytest

from acquire.lidar.labels import PARTS
from acquire.lidar.medium import G_SPHERICAL
from acquire.lidar.presets import get_preset
from acquire.lidar.simulate import LidarWorld, Scanner, fire
from acquire.render import Material, RenderScene, SceneObject
from core.meshes import make_mesh

MAT = Material(albedo=(0.5, 0.5, 0.5), lidar_reflectance=(0.4, 0.4, 0.4))


def _box(name, lo, hi, oid, part, lad=None):
    """A closed box, its faces outward."""
    import open3d as o3d

    m = o3d.geometry.TriangleMesh.create_box(*(np.subtract(hi, lo)))
    V = np.asarray(m.vertices) + np.asarray(lo, float)
    F = np.asarray(m.triangles)
    return SceneObject(name, make_mesh(V, F), MAT, object_id=oid,
                       part_labels=np.full(len(F), PARTS.index(part), np.uint8),
                       leaf_area_density=lad)


def _slab_world(lai, top=20.0, depth=8.0, half=400.0):
    ground = _box("ground", (-half, -half, -1.0), (half, half, 0.0), 1, "ground")
    layer = _box("layer", (-half, -half, top - depth), (half, half, top), 2, "leaf",
                 lad=lai / depth)
    return LidarWorld(RenderScene([ground, layer]), 1550.0)


@pytest.mark.parametrize("lai, theta", [(1.0, 0.0), (3.0, 0.0), (2.0, 40.0)])
def test_the_gap_fraction_of_a_leaf_layer_is_beer_lamberts(lai, theta):
    """Rays through a layer of leaf area index L at zenith angle theta reach the ground
    with probability exp(-G L / cos(theta)), G = 0.5 (leaves at random angles)."""
    w = _slab_world(lai)
    n = 20000
    t = np.radians(theta)
    d = np.tile([np.sin(t), 0.0, -np.cos(t)], (n, 1)).astype(np.float32)
    o = np.column_stack([np.random.default_rng(1).uniform(-50, 50, (n, 2)), np.full(n, 100.0)])
    rays = np.hstack([o, d]).astype(np.float32)
    (R, E), obj, _ = w.cast_energy(rays, np.ones(1), 0.0)
    assert np.all(np.isfinite(R)) and np.all(E > 0)
    through = np.mean(obj == 0)                   # the ground (object index 0)
    want = np.exp(-G_SPHERICAL * lai / np.cos(t))
    assert through == pytest.approx(want, abs=3 * np.sqrt(want * (1 - want) / n) + 0.002)
    # the leaves met lie in the layer, their depths exponential: mean path 1 / (G u)
    z = o[:, 2] + d[:, 2] * R
    leaf = obj == 1
    assert np.all((z[leaf] <= 20.0 + 1e-3) & (z[leaf] >= 12.0 - 1e-3))
    u = lai / 8.0
    path = (20.0 - z[leaf]) / np.cos(t)
    trunc = 8.0 / np.cos(t)                        # the exponential cut at the layer's end
    k = G_SPHERICAL * u
    mean = 1 / k - trunc * np.exp(-k * trunc) / (1 - np.exp(-k * trunc))
    assert path.mean() == pytest.approx(mean, rel=0.03)


def test_overlapping_media_add_and_a_solid_inside_still_returns():
    """Two layers overlapping over half their depth: the gap fraction is that of the sum
    of their leaf areas; a branch inside a layer is hit when the leaves leave it a ray."""
    half = 300.0
    ground = _box("ground", (-half, -half, -1.0), (half, half, 0.0), 1, "ground")
    a = _box("a", (-half, -half, 10.0), (half, half, 18.0), 2, "leaf", lad=0.25)
    b = _box("b", (-half, -half, 14.0), (half, half, 22.0), 3, "leaf", lad=0.25)
    branch = _box("branch", (-5, -5, 15.0), (5, 5, 15.5), 4, "branch")
    w = LidarWorld(RenderScene([ground, a, b, branch]), 1550.0)
    n = 20000
    o = np.column_stack([np.random.default_rng(2).uniform(-100, 100, (n, 2)), np.full(n, 50.0)])
    rays = np.hstack([o, np.tile([0, 0, -1.0], (n, 1))]).astype(np.float32)
    (R, _), obj, _ = w.cast_energy(rays, np.ones(1), 0.0)
    off = np.hypot(*o[:, :2].T) > 10
    want = np.exp(-G_SPHERICAL * (0.25 * 8 + 0.25 * 8))
    assert np.mean(obj[off] == 0) == pytest.approx(want, abs=0.01)
    o = np.column_stack([np.random.default_rng(3).uniform(-4.5, 4.5, (n, 2)), np.full(n, 50.0)])
    rays = np.hstack([o, np.tile([0, 0, -1.0], (n, 1))]).astype(np.float32)
    (R, _), obj, _ = w.cast_energy(rays, np.ones(1), 0.0)
    # above the branch's top (z 15.5): 6.5 m of b and 2.5 m of a
    to_branch = np.exp(-G_SPHERICAL * 0.25 * (6.5 + 2.5))
    assert np.mean(obj == 3) == pytest.approx(to_branch, abs=0.015)
    assert np.allclose(R[obj == 3], 50.0 - 15.5, atol=1e-3)
    assert not np.any(obj == 0)


def test_a_pulse_into_deep_foliage_gives_several_returns():
    """A 0.5 mrad pulse from 300 m (an airplane's default) into a 6 m layer of leaf area
    index 6 (a closed beech canopy): its sub-rays meet leaves at depths spread over metres,
    so most pulses give more than one echo, and a few reach the ground below."""
    w = _slab_world(6.0, top=25.0, depth=6.0)
    sc = Scanner.from_preset(get_preset("riegl-lms-q560"))
    n = 2000
    o = np.column_stack([np.random.default_rng(3).uniform(-50, 50, (n, 2)), np.full(n, 300.0)])
    e = fire(w, sc, o, np.tile([0, 0, -1.0], (n, 1)), rng=np.random.default_rng(4))
    first = e["return_number"] == 1
    several = np.mean(e["number_of_returns"][first] > 1)
    assert several > 0.5
    assert 0.0 < np.mean(e["part"] == PARTS.index("ground")) < 0.2
    # the same seed, the same echoes
    e2 = fire(w, sc, o, np.tile([0, 0, -1.0], (n, 1)), rng=np.random.default_rng(4))
    assert np.array_equal(e["z"], e2["z"])


def test_broadleaf_crowns_are_media_holding_their_leaf_area_and_conifers_keep_needles():
    """A stand's beeches carry their leaves as media in the crown's envelope, closed and
    outward: the envelope and, inside it, the sun crown (its upper third), whose densities
    add to ``sun_crown`` times the shade crown's and hold ``LAI x`` the projection in all;
    spruces keep their needle clusters; ``leaf_area_index = 0`` gives the L-system's leaf
    polygons back."""
    from scipy.spatial import ConvexHull

    from data_synth.forest import ForestConfig, build_forest

    kw = {"size": 20.0, "margin": 0.0, "density": 300.0, "species": "PIAB:0.5,FASY:0.5",
          "understory": 0.0, "relief": 0.0}
    b = build_forest(ForestConfig(leaf_area_index=6.0, sun_crown=3.0, **kw), seed=1)
    sp = dict(zip(b.trees["tree_id"].tolist(), b.trees["species"].tolist(), strict=True))
    leaves = [o for o in b.render_scene.objects if o.name.endswith(".leaf")]
    media = [o for o in leaves if o.leaf_area_density]
    sun = {o.object_id: o for o in b.render_scene.objects if o.name.endswith(".sun")}
    assert media and len(media) < len(leaves)
    assert set(sun) == {o.object_id for o in media}
    for o in leaves:
        assert (sp[o.object_id] == "FASY") == (o.leaf_area_density is not None)
    for o in media:
        V = np.asarray(o.mesh.vertices)
        s = sun[o.object_id]
        Vs = np.asarray(s.mesh.vertices)
        hull, cap = ConvexHull(V), ConvexHull(Vs)
        for m, h in ((o.mesh, hull), (s.mesh, cap)):
            assert m.is_watertight()
            P, F = np.asarray(m.vertices), np.asarray(m.triangles)
            # outward: the signed volume of the faces is positive
            a, bb, c = P[F[:, 0]], P[F[:, 1]], P[F[:, 2]]
            assert np.einsum("ij,ij->i", a, np.cross(bb, c)).sum() / 6 == pytest.approx(
                h.volume, rel=1e-9)
        # the sun crown lies strictly inside the envelope, in its upper third
        assert np.all(hull.equations[:, :3] @ Vs.T + hull.equations[:, 3:] < 0)
        top, low = V[:, 2].max(), V[:, 2].min()
        assert Vs[:, 2].min() >= top - (top - low) / 3
        # densities: three times as dense above, LAI x projection in all
        assert (o.leaf_area_density + s.leaf_area_density) / o.leaf_area_density == \
            pytest.approx(3.0)
        total = o.leaf_area_density * hull.volume + s.leaf_area_density * cap.volume
        assert total == pytest.approx(6.0 * ConvexHull(V[:, :2]).volume, rel=1e-9)
    uniform = build_forest(ForestConfig(leaf_area_index=6.0, sun_crown=1.0, **kw), seed=1)
    assert not any(o.name.endswith(".sun") for o in uniform.render_scene.objects)
    poly = build_forest(ForestConfig(leaf_area_index=0.0, **kw), seed=1)
    assert not any(o.leaf_area_density for o in poly.render_scene.objects)
    np.testing.assert_array_equal(poly.trees["x"], b.trees["x"])


def _chord(V, F, o, d):
    """Length of each ray's chord through the convex mesh ``(V, F)``."""
    import open3d as o3d

    rs = o3d.t.geometry.RaycastingScene()
    rs.add_triangles(o3d.core.Tensor(V.astype(np.float32)), o3d.core.Tensor(F.astype(np.uint32)))
    down = rs.cast_rays(o3d.core.Tensor(np.hstack([o, d]).astype(np.float32)))["t_hit"].numpy()
    far = o + 200.0 * d
    up = rs.cast_rays(o3d.core.Tensor(np.hstack([far, -d]).astype(np.float32)))["t_hit"].numpy()
    return np.where(np.isfinite(down), 200.0 - up - down, 0.0)


def test_a_sun_crown_passes_beer_lambert_on_its_columns_and_stops_rays_higher():
    """A crown as nested media (envelope + sun crown, :func:`procgen.trees.crown_media`):
    a nadir ray reaches the ground with probability ``exp(-G (u_shade L + u_sun l))``, ``L``
    and ``l`` its chords through the envelope and the sun crown; with the same leaf area
    three times as dense in the upper third, the first leaves met lie higher."""
    from procgen.trees import crown_media

    rng = np.random.default_rng(5)
    # a dome of foliage corners: an ellipsoid 8 m across and 6 m deep over z 10-16
    u = rng.normal(size=(400, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    pts = np.column_stack([4 * u[:, 0], 4 * u[:, 1], 13 + 3 * u[:, 2]])
    half = 60.0
    ground = _box("ground", (-half, -half, -1.0), (half, half, 0.0), 1, "ground")
    n = 20000
    xy = np.random.default_rng(6).uniform(-3.0, 3.0, (n, 2))
    o = np.column_stack([xy, np.full(n, 50.0)])
    d = np.tile([0, 0, -1.0], (n, 1))
    rays = np.hstack([o, d]).astype(np.float32)
    high = {}
    for ratio in (1.0, 3.0):
        layers = crown_media(pts, 3.0, sun_ratio=ratio)
        assert len(layers) == (1 if ratio == 1.0 else 2)
        objs = [ground] + [
            SceneObject(f"c{i}", make_mesh(V, F), MAT, object_id=2,
                        part_labels=np.full(len(F), PARTS.index("leaf"), np.uint8),
                        leaf_area_density=lad) for i, (V, F, lad) in enumerate(layers)]
        (R, _), obj, _ = LidarWorld(RenderScene(objs), 1550.0).cast_energy(
            rays, np.ones(1), 0.0)
        depth = sum(lad * _chord(V, F, o, d) for V, F, lad in layers)
        want = np.exp(-G_SPHERICAL * depth)
        through = np.mean(obj == 0)
        sd = float(np.sqrt(np.sum(want * (1 - want)))) / n
        assert through == pytest.approx(float(want.mean()), abs=4 * sd + 0.003)
        z = 50.0 - R[obj > 0]
        high[ratio] = np.mean(z >= 14.0)
    assert high[3.0] > high[1.0] + 0.1


def _cell_discs(i, j, k, lam, radius):
    """The leaves of lattice cell ``(i, j, k)`` drawn from its hash, unpruned (the
    kernel's draws, read in Python): centres ``(m, 3)`` and unit normals ``(m, 3)``."""
    from acquire.lidar import _kernels
    from acquire.lidar.medium import SHOOT_CELL as c

    h = np.uint64(_kernels._cell_hash(i, j, k, 0))
    u, p, n = _kernels._uniform(h, 0), np.exp(-lam), 0
    acc = p
    while u > acc and n < 256:
        n += 1
        p *= lam / n
        acc += p
    q = np.array([[_kernels._uniform(h, 1 + 5 * m + e) for e in range(5)] for m in range(n)])
    if not n:
        return np.zeros((0, 3)), np.zeros((0, 3))
    cen = np.column_stack([(i + q[:, 0]) * c, (j + q[:, 1]) * c,
                           k * c + radius + (c - 2 * radius) * q[:, 2]])
    z, phi = 2 * q[:, 3] - 1, 2 * np.pi * q[:, 4]
    s = np.sqrt(np.maximum(0.0, 1 - z * z))
    return cen, np.column_stack([s * np.cos(phi), s * np.sin(phi), z])


def test_the_leaf_walk_meets_the_nearest_leaf_of_every_cell_near_the_ray():
    """The leaf kernel reads only the cells whose leaves may reach a ray (a box for steep
    stretches, a cell walk for long ones) and passes over far leaves early: its hits equal,
    bit for bit, those of every leaf of every cell around the ray, read one by one."""
    from acquire.lidar import _kernels
    from acquire.lidar.medium import LEAF_AREA, SHOOT_CELL

    rng = np.random.default_rng(7)
    n = 60
    zen = np.concatenate([rng.uniform(0, 0.6, n // 3), rng.uniform(0.6, 1.5, n // 3),
                          np.full(n - 2 * (n // 3), np.pi / 2)])       # steep, oblique, level
    az = rng.uniform(0, 2 * np.pi, n)
    d = np.column_stack([np.sin(zen) * np.cos(az), np.sin(zen) * np.sin(az), -np.cos(zen)])
    o = np.column_stack([rng.uniform(-5, 5, (n, 2)), rng.uniform(1, 3, n)])
    t0 = rng.uniform(0.0, 0.5, n)
    t1 = t0 + rng.uniform(0.2, 1.2, n)
    lad = np.full(n, 4.0)
    t_out, mu_out = np.empty(n), np.empty(n)
    _kernels.leaf_hits(o, d, t0, t1, lad, SHOOT_CELL, LEAF_AREA, 0, t_out, mu_out)
    radius = np.sqrt(LEAF_AREA / np.pi)
    lam = 4.0 * SHOOT_CELL ** 3 / LEAF_AREA
    for r in range(n):
        a, b = o[r] + t0[r] * d[r], o[r] + t1[r] * d[r]
        lo = np.floor((np.minimum(a, b) - SHOOT_CELL) / SHOOT_CELL).astype(int)
        hi = np.floor((np.maximum(a, b) + SHOOT_CELL) / SHOOT_CELL).astype(int)
        cen, nrm = zip(*[_cell_discs(i, j, k, lam, radius)
                         for i in range(lo[0], hi[0] + 1) for j in range(lo[1], hi[1] + 1)
                         for k in range(lo[2], hi[2] + 1)], strict=True)
        cen, nrm = np.vstack(cen), np.vstack(nrm)
        den = nrm @ d[r]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.einsum("ij,ij->i", cen - o[r], nrm) / den
        hit = o[r] + t[:, None] * d[r] - cen
        ok = (np.abs(den) >= 1e-12) & (t >= t0[r]) & (t <= t1[r]) & (
            np.einsum("ij,ij->i", hit, hit) <= radius ** 2)
        if not ok.any():
            assert t_out[r] == np.inf
            continue
        m = np.flatnonzero(ok)[np.argmin(t[ok])]
        assert t_out[r] == pytest.approx(t[m], abs=1e-9)
        assert mu_out[r] == pytest.approx(abs(den[m]), abs=1e-9)
    assert 0.2 < np.mean(np.isfinite(t_out)) < 1.0       # hits and misses both tested
