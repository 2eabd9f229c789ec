"""The ground filter's compiled passes against plain reference implementations, and the
work they do counted (never timed): the TIN densification kept up to date by insertion
must classify as rebuilding the triangulation every pass does, and the lower-surface fit
as the batched least squares; a pass must not re-locate every candidate, and a point's
location must take a bounded number of steps whatever the cloud's size."""

import numpy as np
import pytest

from data_synth.fixtures import sloped_tile
from reconstruct.lidar.ground import (
    LOWER_CERTAIN,
    delaunay_2d,
    densify_tin,
    trim_above_lower_surface,
)


def _reference_densify(p, seeds, eligible, *, angle, distance, offset, passes, slope_gain,
                       slope_rise, local, angle_below=None):
    """Axelsson's densification the plain way: every pass triangulates all the ground
    again and tests every candidate in it."""
    g = seeds.copy()
    q = p[:, :2] - p[:, :2].mean(axis=0)
    seed_tri = delaunay_2d(q[g])
    c = p[g][seed_tri.simplices]
    n = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
    seed_sl = np.degrees(np.arccos(np.abs(n[:, 2]) / np.linalg.norm(n, axis=1)))
    s0 = seed_tri.find_simplex(q)
    seed_slope = np.where(s0 >= 0, seed_sl[s0], 90.0)
    for _ in range(passes):
        gi = np.flatnonzero(g)
        tri = delaunay_2d(q[gi])
        cand = np.flatnonzero(eligible & ~g)
        s = tri.find_simplex(q[cand])
        cand, s = cand[s >= 0], s[s >= 0]
        k = gi[tri.simplices[s]]
        corners = p[k]
        normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        normal /= np.linalg.norm(normal, axis=1)[:, None]
        normal *= np.sign(normal[:, 2])[:, None]  # upwards: + above the plane
        sd = np.einsum("ij,ij->i", p[cand] - corners[:, 0], normal)
        d = np.abs(sd)
        rc = np.linalg.norm(q[cand][:, None] - q[k], axis=2)
        r = rc.min(axis=1)
        d_angle = d
        if local:
            t = p[gi][tri.simplices]
            tn = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
            tn *= np.sign(tn[:, 2])[:, None]
            vn = np.zeros((len(gi), 3))
            for j in range(3):
                np.add.at(vn, tri.simplices[:, j], tn)
            with np.errstate(invalid="ignore"):  # a duplicate is no corner: 0 / 0
                vn /= np.linalg.norm(vn, axis=1)[:, None]
            near = tri.simplices[s, np.argmin(rc, axis=1)]
            dl = np.abs(np.einsum("ij,ij->i", p[cand] - p[gi[near]], vn[near]))
            d_angle = np.minimum(d, dl)
        slope = np.degrees(np.arccos(np.minimum(np.abs(normal[:, 2]), 1.0)))
        if slope_rise < 90:
            slope = np.minimum(slope, seed_slope[cand] + slope_rise)
        base = np.where(sd >= 0, angle, angle if angle_below is None else angle_below)
        tan_a = np.tan(np.radians(np.minimum(base + slope_gain * slope, 89.0)))
        join = (d < distance) & ((d_angle < tan_a * r) | (d < offset))
        if not np.any(join):
            break
        g[cand[join]] = True
    return g


def _reference_trim(p, ground, *, offset, neighbours, iterations=4):
    """The lower-surface trim as batched weighted least squares (numpy)."""
    from scipy.spatial import cKDTree

    gi = np.flatnonzero(ground)
    xy = p[gi, :2] - p[gi, :2].mean(axis=0)
    _, nb = cKDTree(xy).query(xy, neighbours + 1)
    nb = nb[:, 1:]
    dx = xy[nb] - xy[:, None]
    z = p[gi][nb, 2]
    a = np.stack([np.ones_like(dx[..., 0]), dx[..., 0], dx[..., 1], dx[..., 0] ** 2,
                  dx[..., 0] * dx[..., 1], dx[..., 1] ** 2], axis=-1)
    w = np.ones(z.shape)
    for _ in range(iterations):
        aw = a * w[..., None]
        coef = np.linalg.solve(np.einsum("nki,nkj->nij", aw, a) + 1e-6 * np.eye(6),
                               np.einsum("nki,nk->ni", aw, z)[..., None])[..., 0]
        w = np.clip((LOWER_CERTAIN - (z - np.einsum("nki,ni->nk", a, coef))) / 0.25, 0, 1)
    out = ground.copy()
    out[gi[p[gi, 2] - coef[:, 0] > offset]] = False
    return out


def _seeded(slope, size, seed, grid=None):
    """A sloped survey under shrubs and crowns, its last returns, and seeds: the lowest last
    return of every 5 m cell and the last returns' hull (what the cloth leaves, roughly)."""
    from scipy.spatial import ConvexHull

    t = sloped_tile(slope, rng=np.random.default_rng(seed), size=size, density=15.0)
    p = t.points.copy()
    if grid:
        p = np.round(p / grid) * grid  # a LAS file's scale: ties, collinear and cocircular
    last = t.last
    li = np.flatnonzero(last)
    cell = np.floor(p[li, :2] / 5.0).astype(int)
    key = cell[:, 0] * 1000 + cell[:, 1]
    order = np.lexsort((p[li, 2], key))
    first = np.r_[True, key[order][1:] != key[order][:-1]]
    seeds = np.zeros(len(p), bool)
    seeds[li[order[first]]] = True
    seeds[li[ConvexHull(p[li, :2]).vertices]] = True
    return p, seeds, last


@pytest.mark.parametrize("slope, local, gain, rise, grid, below", [
    (5.0, False, 0.0, 90.0, None, None),   # Axelsson's fixed angle
    (30.0, True, 0.5, 5.0, None, 20.0),    # the defaults: corner planes, the bounded slope
                                           # term, points below at their own angle
    (40.0, True, 0.5, 90.0, None, None),   # the slope term unbounded
    (30.0, True, 0.5, 5.0, 0.01, 20.0),    # on a centimetre grid, as a LAS file stores them
])
def test_densification_by_insertion_is_the_rebuilt_one(slope, local, gain, rise, grid, below):
    p, seeds, last = _seeded(slope, 30.0, int(slope), grid)
    kw = dict(angle=6.0, distance=1.4, offset=0.1, passes=50, slope_gain=gain,
              slope_rise=rise, local=local, angle_below=below)
    stats = {}
    ours = densify_tin(p, seeds, last, stats=stats, **kw)
    ref = _reference_densify(p, seeds, last, **kw)
    assert stats["passes"] >= 3  # points joined over several passes, each on the last
    assert seeds.sum() * 20 < ours.sum() < last.sum()
    if grid is None:
        assert np.array_equal(ours, ref)
    else:  # ties on the grid may triangulate either way: a handful of points, no more
        assert np.sum(ours != ref) <= 1e-3 * len(p)


def test_densification_work_is_linear():
    # a pass locates again only the candidates whose triangle a new point replaced, by a
    # walk from a nearby triangle: rebuilding every pass re-locates every candidate each
    # time (walks ~ candidates x passes), and walks from afar grow with the cloud's side
    per_walk = []
    for size in (25.0, 70.0):
        p, seeds, last = _seeded(30.0, size, 1)
        stats = {}
        densify_tin(p, seeds, last, angle=6.0, slope_gain=0.5, slope_rise=5.0, local=True,
                    stats=stats)
        assert stats["passes"] >= 4
        assert stats["walks"] <= 1.5 * stats["candidates"]
        assert stats["inserted"] <= stats["candidates"]
        per_walk.append(stats["steps"] / stats["walks"])
    assert max(per_walk) < 25
    assert per_walk[1] < 1.5 * per_walk[0]  # 2.8 x the side, not 2.8 x the steps


def test_lower_surface_fit_is_the_batched_least_squares():
    p, seeds, last = _seeded(30.0, 25.0, 3)
    ground = densify_tin(p, seeds, last, angle=6.0, slope_gain=0.5, slope_rise=5.0,
                         local=True)
    for k in (15, 40):
        ours = trim_above_lower_surface(p, ground, offset=0.1, neighbours=k)
        ref = _reference_trim(p, ground, offset=0.1, neighbours=k)
        assert np.array_equal(ours, ref)
        assert 0 < ground.sum() - ours.sum() < 0.5 * ground.sum()


def test_lower_surface_spread_is_the_weighted_rms_below_the_fit():
    from reconstruct.lidar._kernels import lower_surface

    rng = np.random.default_rng(4)
    n, k = 60, 12
    xy = rng.uniform(0, 5, (n, 2))
    z = 0.3 * xy[:, 0] + 0.05 * xy[:, 1] ** 2 + rng.normal(0, 0.05, n)
    z[::9] += 0.4  # some above the certain band: weight 0
    from scipy.spatial import cKDTree

    nb = cKDTree(xy).query(xy, k + 1)[1][:, 1:]
    rows = np.arange(n)
    fit, spread = np.empty(n), np.empty(n)
    lower_surface(xy, z, nb, rows, 4, LOWER_CERTAIN, 0.25, 1e-6, fit, spread)
    dx = xy[nb] - xy[:, None]
    a = np.stack([np.ones_like(dx[..., 0]), dx[..., 0], dx[..., 1], dx[..., 0] ** 2,
                  dx[..., 0] * dx[..., 1], dx[..., 1] ** 2], axis=-1)
    w = np.ones((n, k))
    for _ in range(4):
        aw = a * w[..., None]
        coef = np.linalg.solve(np.einsum("nki,nkj->nij", aw, a) + 1e-6 * np.eye(6),
                               np.einsum("nki,nk->ni", aw, z[nb])[..., None])[..., 0]
        e = z[nb] - np.einsum("nki,ni->nk", a, coef)
        w = np.clip((LOWER_CERTAIN - e) / 0.25, 0, 1)
    wb = np.where(e < 0, w, 0.0)  # the neighbours below the fit
    want = np.sqrt(np.sum(wb * e ** 2, axis=1) / np.sum(wb, axis=1))
    assert np.allclose(fit, coef[:, 0], atol=1e-9)
    assert np.allclose(spread, want, atol=1e-9)
    assert 0.02 < np.median(spread) < 0.1  # the noise (0.05 m), not the 0.4 m outliers


def test_disc_sums_are_the_direct_convolution():
    from scipy import ndimage

    from reconstruct.lidar.ground import _disc_sum

    rng = np.random.default_rng(0)
    for shape, pad in (((40, 70), 15), ((9, 5), 3), ((30, 30), 1)):
        a = rng.poisson(2.0, shape).astype(float)
        k = np.arange(-pad, pad + 1)
        disc = k[:, None] ** 2 + k[None, :] ** 2 <= pad ** 2
        direct = ndimage.convolve(a, disc.astype(float), mode="constant", cval=0.0)
        assert np.array_equal(_disc_sum(a, disc), direct)


def _cliff(rng, density=12.0):
    """A 30-degree slope falling in +x with a 4 m cliff at x = 20, under shrubs (discs of
    0.5-1 m radius, 0.5-2 m high, 40 % of the ground's pulses on them)."""
    n = int(40 * 30 * density)
    xy = rng.uniform(0, 40, (n, 2)) * [1, 0.75]
    ground = -np.tan(np.radians(30)) * xy[:, 0] - 4.0 * (xy[:, 0] > 20)
    sh = rng.uniform(0, 40, (120, 2)) * [1, 0.75]
    sh = sh[np.abs(sh[:, 0] - 20) > 1.5]  # none on the cliff's edge itself
    r = rng.uniform(0.5, 1.0, len(sh))
    hgt = rng.uniform(0.5, 2.0, len(sh))
    from scipy.spatial import cKDTree

    d, k = cKDTree(sh).query(xy)
    on = (d < r[k]) & (rng.random(n) < 0.4)
    z = ground + rng.normal(0, 0.03, n) + np.where(on, hgt[k] * rng.uniform(0.5, 1, n), 0)
    return np.column_stack([xy, z]), ~on


def test_a_cliffs_top_edge_stays_ground_and_shrubs_do_not():
    from reconstruct.lidar.ground import GroundOptions, classify_ground

    p, truth = _cliff(np.random.default_rng(4))
    edge = truth & (p[:, 0] > 18.5) & (p[:, 0] < 20) & (p[:, 1] > 2) & (p[:, 1] < 28)
    g = classify_ground(p)
    flat = classify_ground(p, options=GroundOptions(lower_edges=False))
    # the trim fits a surface pulled down by the cliff's foot: its top edge stood above it
    # (kept: up to about 1 m back, where half the other side is the foot)
    assert np.mean(g[edge]) > 0.55
    assert np.mean(flat[edge]) < np.mean(g[edge]) - 0.4
    # and the shrubs are no more ground than without the edge rule
    assert np.mean(g[~truth]) <= np.mean(flat[~truth]) + 0.002
    assert np.mean(g[~truth]) < 0.02
