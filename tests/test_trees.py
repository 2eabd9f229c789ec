"""L-system trees: conifers' needle clusters in metres, per-tree growth, crowns of the size
an inventory asks (procgen/trees.py)."""

from __future__ import annotations

import numpy as np
import pytest

from procgen.trees import (
    FAN,
    WHORL_AREA,
    crown_years,
    grow_tree,
    hull_radius,
    needle_clusters,
    place_tree,
    species_for,
    spray_scale,
)


def _straight_axis(n=3, step=1.0):
    """One horizontal axis of ``n`` shoots of ``step`` metres along +x, tip at x = n."""
    a = np.array([[i * step, 0.0, 10.0] for i in range(n)])
    b = a + [step, 0.0, 0.0]
    return np.stack([a, b], 1), np.arange(-1, n - 1)


def test_needle_clusters_lie_on_the_needled_spray_with_its_law():
    sp = species_for("PSME")                 # needle reach 1.5 m, spray 0.35 m
    shoots, parents = _straight_axis(3)
    size, density = 0.2, 400.0
    V, F = needle_clusters(shoots, parents, sp, np.random.default_rng(0), size=size,
                           density=density)
    tri = V[F]
    # every cluster is an equilateral triangle of the side asked
    sides = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2)
    np.testing.assert_allclose(sides, size, rtol=1e-9)
    c = tri.mean(1)
    x = 3.0 - c[:, 0]                         # metres back from the axis' tip
    reach, w0 = sp.needle_reach, sp.spray
    # needles only on the last `reach` metres (the first shoot has none), within the
    # spray's half-width (w0 + FAN x) across and a quarter of it above and below
    assert x.min() >= 0 and x.max() <= reach + 1e-9
    assert np.all(np.abs(c[:, 1]) <= w0 + FAN * x + 1e-9)
    assert np.all(np.abs(c[:, 2] - 10.0) <= (w0 + FAN * x) / 4 + 1e-9)
    # as many as the density times the spray's area (Poisson: 4 sigma)
    area = 2 * (w0 * reach + FAN * reach ** 2 / 2)
    assert abs(len(F) - density * area) < 4 * np.sqrt(density * area)
    # the distance from the tip follows the spray's width: E[x] in closed form
    ex = (w0 * reach ** 2 / 2 + FAN * reach ** 3 / 3) / (w0 * reach + FAN * reach ** 2 / 2)
    assert x.mean() == pytest.approx(ex, abs=4 * x.std() / np.sqrt(len(x)))


def test_a_placed_conifer_has_the_crown_and_top_asked_and_its_own_needles():
    m = grow_tree("ABCO", rng=np.random.default_rng(3), years=crown_years(18.0, 0.65))
    assert m.form == "conifer" and not np.any(m.parts == 2)   # needles come when placed
    out = []
    for seed in (1, 1, 2):
        V, F, P = place_tree(m, position=(5.0, -2.0, 1.0), height=18.0, crown_radius=2.5,
                             rng=np.random.default_rng(seed))
        assert V[:, 2].max() == pytest.approx(19.0, abs=1e-9)   # the top is exact
        leaf = V[F[P == 2].ravel()]
        # the crown's radius as a LiDAR inventory measures it: its hull seen from above
        assert hull_radius(leaf[:, :2] - [5.0, -2.0]) == pytest.approx(2.5, rel=0.06)
        # trunk, branches and needles
        assert set(np.unique(P).tolist()) == {0, 1, 2}
        out.append(leaf)
    np.testing.assert_array_equal(out[0], out[1])             # seeded
    assert out[0].shape != out[2].shape or not np.array_equal(out[0], out[2])


def test_crown_ratio_sets_the_crown_base():
    lows = []
    for ratio in (0.35, 0.7):
        m = grow_tree("PSME", rng=np.random.default_rng(0), years=12, crown_ratio=ratio)
        V, F, P = place_tree(m, position=(0.0, 0.0, 0.0), height=20.0, crown_radius=3.0,
                             rng=np.random.default_rng(0))
        lows.append(np.percentile(V[F[P == 2].ravel(), 2], 1) / 20.0)
    # the lowest needles sit near 1 - crown ratio of the height (drooping branches a bit
    # lower)
    assert lows[0] == pytest.approx(0.65, abs=0.08)
    assert lows[1] == pytest.approx(0.30, abs=0.08)


def test_crown_years_follow_the_leader_growth():
    assert crown_years(9.0, 0.5) == 10              # 4.5 m of crown at 0.45 m a year
    assert crown_years(2.0, 0.3) == 6 and crown_years(60.0, 0.8) == 24   # bounded


def test_a_crown_offset_moves_the_crown_not_the_stem_or_the_top():
    m = grow_tree("PSME", rng=np.random.default_rng(4), years=crown_years(16.0, 0.6))
    kw = dict(position=(3.0, 4.0, 0.0), height=16.0, crown_radius=2.5)
    V0, F0, P0 = place_tree(m, rng=np.random.default_rng(1), **kw)
    V1, F1, P1 = place_tree(m, rng=np.random.default_rng(1), crown_offset=(0.0, 0.75), **kw)
    np.testing.assert_array_equal(F0, F1)
    stem = np.unique(F0[P0 == 0])
    np.testing.assert_array_equal(V0[stem], V1[stem])           # the stem stays round
    top0, top1 = V0[np.argmax(V0[:, 2])], V1[np.argmax(V1[:, 2])]
    assert np.hypot(*(top1[:2] - top0[:2])) < 0.05               # and the top on it
    leaf0, leaf1 = V0[F0[P0 == 2].ravel()], V1[F1[P1 == 2].ravel()]
    # r(t) = r (1 + a cos t): each point moves a * rho * cos(t) along its own direction,
    # so its y by a * dy^2 / rho: the foliage's centre moves about a * (mean reach) / 2
    a = 0.75 / 2.5
    d = leaf0[:, :2] - [3.0, 4.0]
    rho = np.hypot(d[:, 0], d[:, 1])
    shift = leaf1[:, :2].mean(0) - leaf0[:, :2].mean(0)
    assert shift[1] == pytest.approx(a * np.mean(d[:, 1] ** 2 / rho), rel=1e-9)
    assert shift[1] == pytest.approx(a * rho.mean() / 2, rel=0.15)
    assert abs(shift[0]) < 0.1 * shift[1]
    # the crown reaches further on the offset's side, less on the other
    far = np.max(leaf1[:, 1] - 4.0) / np.max(leaf0[:, 1] - 4.0)
    near = np.max(4.0 - leaf1[:, 1]) / np.max(4.0 - leaf0[:, 1])
    assert far == pytest.approx(1 + a, rel=0.1) and near == pytest.approx(1 - a, rel=0.1)


def _nadir_opacity(V, F, radius, lo=0.0, hi=0.8, step=0.05):
    """Share of vertical rays ``step`` apart, between ``lo`` and ``hi`` of the crown's
    radius from the stem (at the origin), that hit a triangle."""
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(V.astype(np.float32)),
                        o3d.core.Tensor(F.astype(np.uint32)))
    g = np.arange(-radius, radius + 1e-9, step)
    x, y = (a.ravel() for a in np.meshgrid(g, g))
    rho = np.hypot(x, y) / radius
    keep = (rho >= lo) & (rho <= hi)
    rays = np.zeros((int(keep.sum()), 6), np.float32)
    rays[:, 0], rays[:, 1], rays[:, 2], rays[:, 5] = x[keep], y[keep], V[:, 2].max() + 5, -1
    return float(np.isfinite(scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()).mean())


@pytest.mark.parametrize("code, bound", [("PIPO", 0.85), ("ABCO", 0.95)])
def test_a_conifer_crown_stays_as_opaque_whatever_its_size(code, bound):
    sp = species_for(code)
    stopped, widened = {}, {}
    # the calibrated crown (21 m, 3 m), the species' proportion, and the stand's large ones
    for h, r in ((16.0, 2.24), (21.0, 3.0), (16.0, 3.3), (24.0, 4.2)):
        m = grow_tree(sp, rng=np.random.default_rng(0), years=crown_years(h, sp.crown_ratio),
                      crown_ratio=sp.crown_ratio)
        for area in (WHORL_AREA, 100.0):           # 100 m2 per whorl: sprays never widen
            V, F, P = place_tree(m, position=(0.0, 0.0, 0.0), height=h, crown_radius=r,
                                 rng=np.random.default_rng(1), whorl_area=area)
            (widened if area == WHORL_AREA else stopped)[h, r] = _nadir_opacity(V, F, r)
            if area == WHORL_AREA:
                # the widened sprays keep the crown's radius as asked
                leaf = V[F[P == 2].ravel()]
                assert hull_radius(leaf[:, :2]) == pytest.approx(r, rel=0.06)
    w = np.array(list(widened.values()))
    # within 0.8 of the radius the crown stops about the same share of nadir rays at every
    # size, and nearly all of them
    assert w.min() > bound and w.max() - w.min() < 0.10, widened
    # with sprays of a fixed width the large crowns opened (PIPO 24 m / 4.2 m: 75 % against
    # 93 % for 16 m / 2.24 m), and the small ones were already as they are
    s = np.array(list(stopped.values()))
    assert s[0] == w[0] and s[-1] < w[-1] - 0.02
    assert spray_scale(3.0, 23) == 1.0 and spray_scale(4.2, 24) > 1.5


def test_widened_sprays_are_seeded():
    m = grow_tree("PIPO", rng=np.random.default_rng(2), years=crown_years(24.0, 0.5))
    out = [place_tree(m, position=(0.0, 0.0, 0.0), height=24.0, crown_radius=4.2,
                      rng=np.random.default_rng(s))[0] for s in (5, 5, 6)]
    assert out[0].tobytes() == out[1].tobytes()
    assert out[0].shape != out[2].shape or not np.array_equal(out[0], out[2])
