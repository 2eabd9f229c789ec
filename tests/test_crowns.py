"""Crowns grown by competition (procgen/crowns.py): pushed back where a neighbour's crown
is, grown into open space, their area kept; placed on a tree (place_tree's crown_reach) and
in a stand (ForestConfig.crown_competition)."""

from __future__ import annotations

import numpy as np
import pytest

from procgen.crowns import SECTORS, crown_reach, offset_reach
from procgen.trees import crown_years, grow_tree, place_tree

T = 2 * np.pi * np.arange(SECTORS) / SECTORS


def _area(r):
    return 0.5 * np.sum(r ** 2) * 2 * np.pi / len(r)


def _covered(xy, reach, pts):
    """Which crowns (star polygons of ``reach`` about ``xy``) hold each of ``pts (m, 2)``."""
    out = []
    for p, r in zip(xy, reach, strict=True):
        d = pts - p
        ang = np.mod(np.arctan2(d[:, 1], d[:, 0]), 2 * np.pi) * len(r) / (2 * np.pi)
        k0 = np.floor(ang).astype(int) % len(r)
        w = ang - np.floor(ang)
        out.append(np.hypot(d[:, 0], d[:, 1]) <= (1 - w) * r[k0] + w * r[(k0 + 1) % len(r)])
    return np.array(out)


def test_two_close_crowns_are_shorter_towards_each_other_and_a_lone_one_stays_round():
    xy = np.array([[0.0, 0.0], [4.0, 0.0], [50.0, 50.0]])
    radii = np.array([3.0, 2.0, 2.5])
    r = crown_reach(xy, radii)
    assert np.all(r[2] == 2.5)                                    # nobody near: as measured
    # towards each other: the overlap split in proportion to the radii (3 : 2 of 4 m)
    assert r[0, 0] == pytest.approx(2.4, abs=0.05) and r[1, SECTORS // 2] == pytest.approx(1.6,
                                                                                      abs=0.05)
    assert r[0, 0] + r[1, SECTORS // 2] <= 4.0 + 1e-9              # never the same space twice
    assert r[0, SECTORS // 2] > 3.0 and r[1, 0] > 2.0               # away: further
    # the area each had is kept (what it lost towards the other, it gained elsewhere)
    for i in (0, 1):
        assert _area(r[i]) == pytest.approx(np.pi * radii[i] ** 2, rel=0.02)
        assert r[i].max() <= 1.6 * radii[i] + 1e-9                  # and no further than that
    # symmetric about the line between them
    np.testing.assert_allclose(r[:2, 1:], r[:2, :0:-1], atol=1e-9)


def test_no_point_of_a_stand_is_in_two_crowns_and_the_same_stand_gives_the_same_reach():
    # a stand's 25 stems on a jittered 6 m grid, crowns of 2.5-4 m: they overlap
    rng = np.random.default_rng(5)
    xy = np.stack(np.meshgrid(np.arange(5), np.arange(5)), -1).reshape(-1, 2) * 6.0
    xy = xy + rng.uniform(-1.0, 1.0, size=(25, 2))
    radii = rng.uniform(2.5, 4.0, 25)
    off = rng.normal(0, 0.5, size=(25, 2))
    r = crown_reach(xy, radii, offsets=off)
    np.testing.assert_array_equal(r, crown_reach(xy.copy(), radii.copy(), offsets=off.copy()))
    g = np.stack(np.meshgrid(np.arange(-5, 35, 0.2), np.arange(-5, 35, 0.2)), -1).reshape(-1, 2)
    held = _covered(xy, r, g)
    # (the star polygons are drawn linear between sectors: a sliver where two meet)
    assert np.mean(held.sum(0) > 1) < 0.01
    base = np.stack([offset_reach(radii[i], off[i]) for i in range(25)])
    before = _covered(xy, base, g)
    assert np.mean(before.sum(0) > 1) > 0.05                     # they did overlap
    assert held.any(0).mean() > before.any(0).mean()              # and now cover more


def test_bad_input_names_the_argument():
    with pytest.raises(ValueError, match="radii"):
        crown_reach(np.zeros((2, 2)) + [[0, 0], [1, 0]], np.array([1.0, 0.0]))
    with pytest.raises(ValueError, match="reach_max"):
        crown_reach(np.array([[0.0, 0.0]]), np.array([1.0]), reach_max=0.5)
    with pytest.raises(ValueError, match="xy"):
        crown_reach(np.zeros((2, 3)), np.ones(2))


def test_a_placed_crown_follows_its_reach_by_azimuth():
    m = grow_tree("PSME", rng=np.random.default_rng(4), years=crown_years(16.0, 0.6))
    kw = dict(position=(3.0, 4.0, 0.0), height=16.0, crown_radius=2.5, azimuth=0.7)
    V0, F0, P0 = place_tree(m, rng=np.random.default_rng(1), **kw)
    # a reach of the radius everywhere is the crown as it was (to rounding)
    V1, _, _ = place_tree(m, rng=np.random.default_rng(1), crown_reach=np.full(SECTORS, 2.5),
                          **kw)
    np.testing.assert_allclose(V0, V1, rtol=0, atol=1e-12)
    reach = np.where(np.cos(T) > 0.5, 1.5, 3.0)                   # short towards +x
    V2, F2, P2 = place_tree(m, rng=np.random.default_rng(1), crown_reach=reach, **kw)
    np.testing.assert_array_equal(F0, F2)
    stem = np.unique(F0[P0 == 0])
    np.testing.assert_array_equal(V0[stem], V2[stem])
    assert V2[:, 2].max() == V0[:, 2].max()
    leaf0, leaf2 = (V[F0[P0 == 2].ravel(), :2] - [3.0, 4.0] for V in (V0, V2))
    # each point moved along its own azimuth by reach / radius: x ahead 1.5 / 2.5, behind 3 / 2.5
    assert leaf2[:, 0].max() / leaf0[:, 0].max() == pytest.approx(0.6, rel=0.05)
    assert leaf2[:, 0].min() / leaf0[:, 0].min() == pytest.approx(1.2, rel=0.05)
    with pytest.raises(ValueError, match="crown_offset"):
        place_tree(m, crown_reach=reach, crown_offset=(0.5, 0.0), **kw)


def _leaf(b, k):
    objs = {o.name: o for o in b.render_scene.objects}
    return objs[f"tree{k:05d}.leaf"].world_arrays()[0] + b.origin


def test_a_stand_with_competition_pushes_close_crowns_apart_and_rebuilds_bit_for_bit(tmp_path):
    from data_synth.forest import ForestConfig, build_forest

    inv = tmp_path / "inv.csv"
    # two trees 4 m apart with 3 m crowns, a third alone 30 m away (no radius: drawn)
    inv.write_text("x,y,height,crown_radius,species\n10,10,14,3.0,PSME\n14,10,14,3.0,PSME\n"
                   "40,10,14,,PSME\n")
    kw = dict(relief=0.0, margin=2.0, understory=0.0, variants=1)
    plain = build_forest(ForestConfig(**kw), inventory=inv, seed=3)
    comp = build_forest(ForestConfig(crown_competition=True, **kw), inventory=inv, seed=3)
    a, b = _leaf(comp, 1), _leaf(comp, 2)
    towards, away = a[:, 0].max() - 10, 10 - a[:, 0].min()
    assert towards < 0.8 * away                                  # tree 1 shorter towards 2
    assert b[:, 0].max() - 14 > 1.2 * (14 - b[:, 0].min())        # and tree 2 towards 1
    # without competition both reach as far either way (within the spray's scatter)
    p = _leaf(plain, 1)
    assert p[:, 0].max() - 10 == pytest.approx(10 - p[:, 0].min(), rel=0.25)
    # the lone tree is round: its crown as far every way
    lone = _leaf(comp, 3) - [40.0, 10.0, 0.0]
    ext = [lone[:, 0].max(), -lone[:, 0].min(), lone[:, 1].max(), -lone[:, 1].min()]
    assert max(ext) < 1.3 * min(ext)
    again = build_forest(ForestConfig(crown_competition=True, **kw), inventory=inv, seed=3)
    for o1, o2 in zip(comp.render_scene.objects, again.render_scene.objects, strict=True):
        np.testing.assert_array_equal(np.asarray(o1.mesh.vertices), np.asarray(o2.mesh.vertices))
