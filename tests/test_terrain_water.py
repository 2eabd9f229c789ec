"""Terrain shaped by water: D8 routing and priority-flood on hand-checkable grids, the
geomorphometry on closed forms (planes, a cone, a profile of known concavity, a known
Strahler tree), and the erosion models' defining properties on small grids."""

import numpy as np
import pytest

from procgen.terrain.erosion import (
    ErosionConfig,
    chi,
    erode,
    hydraulic_erosion,
    stream_power,
    thermal_erosion,
)
from procgen.terrain.flow import (
    accumulate,
    d8_receivers,
    fill_depressions,
    lake_depth,
    route_flow,
    stack_order,
)
from procgen.terrain.heightfield import fractal_terrain
from procgen.terrain.metrics import (
    bifurcation_ratio,
    concavity,
    hack_exponent,
    hypsometric_integral,
    pit_share,
    strahler_order,
    terrain_figures,
)


def _ds(size=65, seed=0, height=50.0):
    return fractal_terrain(size, rng=np.random.default_rng(seed), height=height)


# -- routing ----------------------------------------------------------------------------

def test_d8_on_a_plane_and_the_area_it_drains():
    rows, cols = 9, 12
    z = np.tile(np.arange(cols, dtype=float), (rows, 1)) * 0.5   # falls toward column 0
    rec, dist = d8_receivers(z, spacing=2.0)
    k = 4 * cols + 5
    assert rec[k] == k - 1 and dist[k] == 2.0
    fl = route_flow(z, spacing=2.0)
    # every interior cell of a row drains its row's upslope interior cells (the last
    # column is boundary, base level of its own): area = cells * 4 m2
    np.testing.assert_allclose(fl.area[4, 1:-1], 4.0 * np.arange(cols - 2, 0, -1))
    assert fl.area[4, 0] == 4.0 * (cols - 1)     # the outlet receives the row
    assert fl.area.sum() > 0 and pit_share(z) == 0.0


def test_stack_puts_every_cell_after_its_receiver():
    z = _ds(33)
    fl = route_flow(fill_depressions(z, epsilon=1e-9), spacing=1.0)
    pos = np.empty(z.size, int)
    pos[fl.stack] = np.arange(z.size)
    assert sorted(fl.stack.tolist()) == list(range(z.size))
    moving = fl.receivers != np.arange(z.size)
    assert np.all(pos[fl.receivers[moving]] < pos[np.nonzero(moving)[0]])
    # drainage area summed down the stack = total area once everything drains out
    a = accumulate(fl.receivers, fl.stack, np.ones(z.size))
    base = ~moving
    assert a[base].sum() == pytest.approx(z.size)
    with pytest.raises(ValueError, match="receivers"):
        stack_order(np.array([0, 5]))


def test_priority_flood_fills_a_bowl_to_its_spill_point():
    z = np.full((7, 7), 10.0)
    z[2:5, 2:5] = 2.0      # a bowl, rim at 10 ...
    z[3, 0] = 6.0          # ... with a notch at 6 on the edge
    z[3, 1] = 6.5          # and a sill between them at 6.5: the spill point
    filled = fill_depressions(z)
    assert filled[3, 3] == 6.5 and filled[2, 2] == 6.5 and filled[3, 1] == 6.5
    assert np.all(filled >= z) and filled[0, 0] == 10.0
    depth = lake_depth(z)
    assert depth[3, 3] == pytest.approx(4.5) and depth[0, 0] == 0.0
    # +epsilon: flats drain, every interior cell then has a strictly lower neighbour
    eps = fill_depressions(z, epsilon=1e-9)
    assert pit_share(eps) == 0.0 and pit_share(z) > 0.2
    assert np.all(eps >= filled) and np.max(eps - filled) < 1e-6


def test_filling_from_the_pits_equals_the_global_flood():
    """The fast path of stream power: a drained surface with a few new pits is filled from
    each pit; the result is the global priority-flood's, exactly (epsilon 0)."""
    from procgen.terrain.flow import _priority_flood, boundary_mask, drain

    z = _ds(129)
    b = boundary_mask(z)
    g = _priority_flood(z, b, 1e-9)
    rng = np.random.default_rng(1)
    ij = rng.integers(1, 128, size=(40, 2))
    g[ij[:, 0], ij[:, 1]] -= rng.uniform(0, 20, 40)
    g[60:64, 60:64] -= 30.0                             # and a wider pit
    np.testing.assert_array_equal(drain(g, b, 0.0), _priority_flood(g, b, 0.0))
    d = drain(g, b, 1e-9)
    assert pit_share(g) > 0 and pit_share(d) == 0.0 and np.all(d >= g)


def test_nodata_cells_are_outside_and_their_edge_drains():
    z = _ds(33)
    z[10:20, 10:20] = np.nan
    fl = route_flow(z, spacing=1.0)
    assert np.all(fl.area[10:20, 10:20] == 0)
    f = fill_depressions(z)
    assert np.all(np.isnan(f[10:20, 10:20])) and np.all(f[np.isfinite(z)] >= z[np.isfinite(z)])


# -- metrics on closed forms ------------------------------------------------------------

def _profile(theta, rows=21, cols=200, ks=0.5):
    """Rows that each drain along -x, one cell wide: column j drains A = cols - 1 - j cells
    (the last column is boundary). The heights integrate S = ks A^-theta, so every
    channel cell obeys Flint's law exactly."""
    a = np.maximum(cols - 1 - np.arange(cols), 1).astype(float)  # area (cells, dx = 1)
    s = ks * a ** -theta
    z = np.concatenate([[0.0], np.cumsum(s[1:])])  # z[j] - z[j-1] = S[j]
    return np.tile(z, (rows, 1))


@pytest.mark.parametrize("theta", [0.0, 0.3, 0.5, 0.7])
def test_concavity_of_a_profile_that_obeys_flints_law(theta):
    z = _profile(theta)
    assert concavity(z, min_area=10.0) == pytest.approx(theta, abs=1e-6)
    # parallel flow, one cell wide: the longest path above a cell of A cells is A - 1
    a = np.arange(10, 199, dtype=float)
    expected = np.polyfit(np.log10(a), np.log10(a - 1), 1)[0]   # 1.02: h -> 1
    assert hack_exponent(z, min_area=10.0) == pytest.approx(expected, abs=1e-9)


def test_hypsometric_integral_of_a_plane_and_a_cone():
    u = np.linspace(-1, 1, 401)
    xx, yy = np.meshgrid(u, u)
    assert hypsometric_integral(xx) == pytest.approx(0.5, abs=1e-9)
    r = np.hypot(xx, yy)
    cone = np.where(r <= 1, 1 - r, np.nan)
    assert hypsometric_integral(cone) == pytest.approx(1 / 3, abs=0.01)


def _tree(branches, depth):
    """Receivers of a complete tree: each junction has ``branches`` donors; the leaves."""
    rec, frontier = [0], [0]
    for _ in range(depth):
        nxt = []
        for p in frontier:
            for _ in range(branches):
                rec.append(p)
                nxt.append(len(rec) - 1)
        frontier = nxt
    return np.array(rec), frontier


def test_strahler_orders_and_horton_ratio_of_a_binary_tree():
    """A complete binary tree of depth 4 drawn as receivers: 8 first-order streams, 4
    second, 2 third, 1 fourth; R_b = 2 exactly (the top order is left out: 8, 4, 2)."""
    rec, leaves = _tree(2, 3)
    stack = stack_order(rec)
    channel = np.ones(len(rec), bool)
    order = strahler_order(rec, stack, channel)
    assert order[0] == 4 and sorted(order[leaves]) == [1] * 8
    assert bifurcation_ratio(rec, stack, channel) == pytest.approx(2.0)
    # a tree with three donors per junction: R_b = 3
    rec3, _ = _tree(3, 3)
    assert bifurcation_ratio(rec3, stack_order(rec3), np.ones(len(rec3), bool)) == \
        pytest.approx(3.0)


def test_fractal_noise_is_full_of_pits():
    assert pit_share(_ds(129)) > 0.02


# -- erosion ----------------------------------------------------------------------------

def test_stream_power_drains_the_land_and_reaches_flints_law():
    z = _ds(129, seed=3)
    cfg = ErosionConfig(years=2e4, dt_years=500.0)
    out = stream_power(z, spacing=30.0, config=cfg)
    assert pit_share(z) > 0.02 and pit_share(out) <= 0.002
    fig = terrain_figures(out, spacing=30.0)
    # steady state S ~ A^-(m/n): m/n = 0.5, diffusion bends the smallest channels
    assert 0.3 <= fig.concavity <= 0.7, fig
    assert 3.0 <= fig.bifurcation_ratio <= 6.0, fig
    assert 0.45 <= fig.hack_exponent <= 0.7, fig
    # the boundary is base level
    assert np.array_equal(out[0], z[0]) and np.array_equal(out[:, -1], z[:, -1])
    # same input, same bytes
    assert out.tobytes() == stream_power(z, spacing=30.0, config=cfg).tobytes()


def test_stream_power_steady_state_is_chi_times_u_over_k():
    """No diffusion, n = 1: at steady state z = (U / K) chi exactly (Perron & Royden)."""
    z = np.zeros((33, 33))
    cfg = ErosionConfig(years=3e6, dt_years=3e4, uplift=1e-3, erodibility=1e-4,
                        diffusivity=0.0)
    out = stream_power(z, spacing=10.0, config=cfg)
    c = chi(out, spacing=10.0)
    np.testing.assert_allclose(out, (1e-3 / 1e-4) * c, rtol=1e-3, atol=1e-6)


def test_thermal_erosion_conserves_mass_and_rests_at_the_talus_angle():
    z = np.zeros((33, 33))
    z[16, 16] = 50.0           # a spike: far steeper than 30 degrees
    cfg = ErosionConfig(talus_deg=30.0, iterations=3000, thermal_rate=0.5)
    out = thermal_erosion(z, spacing=1.0, config=cfg)
    assert out.sum() == pytest.approx(z.sum())
    steep = np.abs(np.diff(out, axis=0)).max()
    assert steep <= np.tan(np.radians(30.0)) * 1.05


def test_hydraulic_erosion_moves_earth_downhill_and_is_scale_free():
    z = _ds(65, seed=1, height=40.0)
    out = hydraulic_erosion(z, spacing=10.0, config=ErosionConfig(iterations=60))
    change = out - z
    assert np.abs(change).max() > 1e-3
    # mass leaves only at the edge: what is missing is small against what moved
    assert abs(change.sum()) <= np.abs(change).sum()
    # lowered where it was high, raised where it was low (material moves downhill)
    assert np.corrcoef(change.ravel(), z.ravel())[0, 1] < 0
    scaled = hydraulic_erosion(10 * z, spacing=100.0, config=ErosionConfig(iterations=60))
    np.testing.assert_allclose(scaled, 10 * out, rtol=1e-9, atol=1e-9)


def _drained_share(z, spacing):
    """Share of the cells whose water reaches the grid edge along D8 with no filling."""
    fl = route_flow(z, spacing=spacing)
    edge = np.zeros(z.shape, bool)
    edge[0, :] = edge[-1, :] = edge[:, 0] = edge[:, -1] = True
    return fl.area[edge].sum() / (z.size * spacing ** 2)  # the edge collects what drains


def test_hydraulic_erosion_makes_the_land_drain():
    """Water routed downhill through its lakes carves a connected network: the noise's
    closed pits are gone (filled by sediment, crept over or cut through), several times
    more of the land drains to the edge, and the discharge gathers into rivers (the
    largest drainage area is ten times the raw noise's)."""
    z = _ds(129, seed=2, height=40.0)
    out = hydraulic_erosion(z, spacing=10.0, config=ErosionConfig(iterations=60))
    assert pit_share(z) > 0.02 and pit_share(out) <= 0.002
    assert _drained_share(z, 10.0) < 0.1 and _drained_share(out, 10.0) > 0.5
    assert route_flow(out, spacing=10.0).area.max() > 10 * route_flow(z, spacing=10.0).area.max()


def test_hydraulic_erosion_cuts_channels_only_from_their_drainage_area_on():
    """Sheet flow (water draining fewer than ``channel_cells`` cells) leaves the bed alone:
    on a rough slope with no creep, a threshold above the grid's size cuts nothing; a
    threshold of 40 cells cuts the cells that drain 40 or more and leaves every cell
    that drains fewer untouched after the first step."""
    z = _ds(33, seed=4, height=5.0) + np.linspace(0, 60, 33)[None, :]
    cfg = dict(iterations=1, creep=0.0, deposition=0.0)
    none = hydraulic_erosion(z, spacing=10.0, config=ErosionConfig(channel_cells=1e9, **cfg))
    assert np.all(none >= z - 1e-12)
    out = hydraulic_erosion(z, spacing=10.0, config=ErosionConfig(channel_cells=40, **cfg))
    from procgen.terrain.flow import fill_depressions

    drains = route_flow(fill_depressions(z, epsilon=1e-9), spacing=10.0).area / 100.0
    cut = out < z - 1e-12
    assert cut.any() and np.all(drains[cut] >= 40 - 1e-9)


def test_erode_dispatches_and_refuses_bad_input():
    z = _ds(17)
    assert np.array_equal(erode(z, kind="none"), z)
    with pytest.raises(ValueError, match="erosion"):
        erode(z, kind="glacial")
    with pytest.raises(ValueError, match="erodibility"):
        ErosionConfig(erodibility=-1.0)
    with pytest.raises(ValueError, match="spacing"):
        erode(z, kind="thermal", spacing=0.0)


# -- water and materials ----------------------------------------------------------------

def test_water_follows_the_flow_and_lakes_are_level_at_their_spill_point():
    from procgen.terrain.heightfield import heightfield_to_mesh, water_mesh
    from procgen.terrain.materials import water_surface

    # a valley falling along -x with a dammed basin halfway down
    cols, rows = 60, 31
    jj, ii = np.meshgrid(np.arange(cols), np.arange(rows))
    z = 0.5 * jj + 0.3 * np.abs(ii - 15)
    z[13:18, 28:33] -= 3.0                  # the basin
    w = water_surface(z, spacing=1.0, river_area=40.0)
    assert w.lake[15, 30] and not w.lake[15, 50]
    lake_levels = w.level[w.lake]
    assert np.ptp(lake_levels) == 0.0       # level
    assert lake_levels[0] == pytest.approx(fill_depressions(z)[15, 30])
    river = w.level[15, 5:25]
    assert w.river[15, 5:25].all() and np.all(np.diff(river) > 0)   # falls downstream
    assert np.all(w.level[w.river] > z[w.river])
    mesh = water_mesh(z, w.level)
    v = np.asarray(mesh.vertices)
    assert len(mesh.triangles) and np.ptp(v[:, 2]) > 5          # not a plane
    assert len(heightfield_to_mesh(z).vertices) == z.size


def test_materials_by_slope_altitude_and_exposure():
    from procgen.terrain.materials import MATERIALS, classify_materials, material_colors

    u = np.linspace(-1, 1, 129)
    xx, yy = np.meshgrid(u, u)
    r = np.hypot(xx, yy)

    def names_slope(z):
        mat = classify_materials(z, spacing=20.0, seed=1)
        return mat, np.array(MATERIALS)[mat], np.degrees(np.arctan(np.hypot(
            *np.gradient(z, 20.0))))

    # a steep cone: its flanks are rock
    _, names, slope = names_slope(2000 * np.clip(1 - r, 0, 0.8))
    assert np.mean(names[slope > 50] == "rock") > 0.9
    # a gentle cone (25 degrees) with a summit plateau
    z = 600 * np.clip(1 - r, 0, 0.8)
    mat, names, slope = names_slope(z)
    top = (z > 0.95 * z.max()) & (slope < 20)     # the plateau
    assert np.mean(names[top] == "snow") > 0.9
    low_flat = (slope < 10) & (z < 0.3 * z.max())
    assert np.mean(np.isin(names[low_flat], ["grass", "forest floor", "water"])) > 0.9
    # exposure: the snow line sits lower on the side away from the sun (south: -y)
    band = (slope > 10) & (z > 0.6 * z.max()) & (z < 0.95 * z.max())
    north = names[band & (yy > 0.2) & (np.abs(xx) < 0.2)]
    south = names[band & (yy < -0.2) & (np.abs(xx) < 0.2)]
    assert np.mean(north == "snow") > np.mean(south == "snow") + 0.2
    pts = np.stack([xx.ravel(), yy.ravel(), z.ravel()], 1)
    c = material_colors(pts, mat.ravel(), scale=100.0, seed=0)
    assert c.shape == (z.size, 3) and c.min() >= 0 and c.max() <= 1
    snow = mat.ravel() == MATERIALS.index("snow")
    assert c[snow].mean() > 0.8 and c[~snow].mean() < 0.6
    with pytest.raises(ValueError, match="labels"):
        material_colors(pts, mat.ravel()[:-1])
