"""Mountainsides: the relief of the forest test bed (slope, breaks, terraces, cliffs,
ravines, boulders) keeps its exact truth, and the ground filter holds on steep slopes under
shrubs, judged against that truth (Sithole and Vosselman's errors, the DTM's RMSE)."""

from __future__ import annotations

import numpy as np
import pytest

from data_synth.fixtures import sloped_tile
from data_synth.forest import ForestConfig, build_forest, terrain_height
from procgen.terrain import fractal_terrain, mean_slope, mountain_relief
from reconstruct.lidar.ground import classify_ground
from reconstruct.lidar.rasters import dtm_from_ground
from scanamp.cli import main
from scanamp.study.lidar_ground import ground_errors, stand_dtm_errors


def _base(seed=0, size=65, height=0.5):
    return fractal_terrain(size, rng=np.random.default_rng(seed), method="fbm", hurst=0.8,
                           height=height, frequency=1.0, octaves=5)


@pytest.mark.parametrize("slope", [10.0, 35.0, 45.0])
def test_relief_has_the_mean_slope_asked_and_is_seeded(slope):
    base = _base()
    kw = dict(spacing=1.0, slope=slope, slope_breaks=2, terraces=2, cliffs=1, ravines=1,
              boulders=50.0)
    z = mountain_relief(base, rng=np.random.default_rng(3), **kw)
    # the features alone (no tilt: the same draws) are steeper than 10 degrees: no tilt then
    alone = mean_slope(mountain_relief(base, rng=np.random.default_rng(3), **{**kw, "slope": 0}),
                       1.0)
    assert 10 < alone < 35
    assert abs(mean_slope(z, 1.0) - max(slope, alone)) < 1e-6
    again = mountain_relief(base, rng=np.random.default_rng(3), **kw)
    other = mountain_relief(base, rng=np.random.default_rng(4), **kw)
    assert np.array_equal(z, again) and not np.allclose(z, other)
    # tilted downhill towards the aspect (180: south, -y): the north edge is higher
    if slope > alone:
        assert z[-1].mean() > z[0].mean() + 20 * np.tan(np.radians(slope))


def test_relief_features_have_their_shapes():
    flat = np.zeros((129, 129))
    # a cliff on level ground drops cliff_height, over one cell, somewhere downhill
    c = mountain_relief(flat, spacing=0.5, rng=np.random.default_rng(1), cliffs=1,
                        cliff_height=5.0, aspect=90.0)  # facing east: drops along +x
    assert np.allclose(c[:, 0], 0.0) and np.allclose(c[:, -1], -5.0)
    steps = -np.diff(c, axis=1)
    assert np.all(steps >= -1e-12) and steps.max(axis=1).min() >= 2.5  # over 1 or 2 cells
    # a ravine: a V as deep as asked, 4 times as wide
    r = mountain_relief(flat, spacing=0.5, rng=np.random.default_rng(2), ravines=1,
                        ravine_depth=3.0)
    assert np.isclose(r.min(), -3.0, atol=0.15) and r.max() == 0.0  # sampled every 0.5 m
    wet = (r < 0).sum(axis=1) * 0.5  # the ravine's width across each row (fall line: y)
    assert np.all((wet > 10.0) & (wet <= 12.0))
    # boulders stand on the ground, at most 1.8 m high
    b = mountain_relief(flat, spacing=0.5, rng=np.random.default_rng(3), boulders=200.0)
    assert b.min() == 0.0 and 0.25 < b.max() <= 1.8
    # no feature asked: the base untouched
    assert np.array_equal(mountain_relief(_base(), spacing=1.0, rng=np.random.default_rng(0)),
                          _base())


def test_forest_on_a_mountainside_keeps_its_exact_terrain():
    cfg = ForestConfig(size=30.0, margin=5.0, density=0.0, understory=0.0, relief=0.5,
                       slope=30.0, slope_breaks=1, ravines=1, boulders=40.0, terrain_res=1.0)
    b = build_forest(cfg, seed=5)
    v = np.asarray(b.meshes["ground"].vertices)
    assert np.allclose(v[:, 2], terrain_height(b.dtm, v[:, 0], v[:, 1]), atol=1e-9)
    r, c = b.dtm.values.shape
    k = int(round(cfg.margin / b.dtm.res))
    stand = np.zeros((r - 1, c - 1), bool)
    stand[k:r - 1 - k, k:c - 1 - k] = True
    assert abs(mean_slope(b.dtm.values, b.dtm.res, where=stand) - 30.0) < 0.5
    # without relief options the terrain is the plain fractal one (the relief's own stream)
    plain = build_forest(ForestConfig(size=30.0, margin=5.0, density=0.0, understory=0.0,
                                      relief=0.5), seed=5)
    assert not np.allclose(plain.dtm.values, b.dtm.values)
    assert mean_slope(plain.dtm.values, plain.dtm.res) < 15.0


@pytest.mark.parametrize("flag,value,field", [
    ("--forest.slope", "45.5", "forest.slope"),
    ("--forest.slope", "-1", "forest.slope"),
    ("--forest.ravines", "11", "forest.ravines"),
    ("--forest.boulders", "-3", "forest.boulders"),
])
def test_bad_relief_exits_2_with_one_line(tmp_path, capsys, flag, value, field):
    out = tmp_path / "scene"
    assert main(["scene", "forest", flag, value, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and field in err[0], err
    assert not out.exists()


@pytest.mark.parametrize("slope,total_max,rmse_max", [(20.0, 0.03, 0.15), (35.0, 0.03, 0.15),
                                                      (45.0, None, 0.30)])
def test_ground_holds_on_steep_slopes_under_shrubs(slope, total_max, rmse_max):
    # shrubs cover half the floor; at 45 degrees only the DTM has a target (the filter
    # leaves much of the ground out there, but takes in no shrub that would lift it)
    t = sloped_tile(slope, rng=np.random.default_rng(int(slope)), size=50.0)
    pts, last, truth, terrain = t.points, t.last, t.ground, t.terrain
    g = classify_ground(pts, last=last)
    inner = np.all((pts[:, :2] > 5) & (pts[:, :2] < 45), axis=1)  # the cloth's edges: less sure
    e = ground_errors(g[inner], truth[inner])
    dtm = dtm_from_ground(pts[g], bounds=(0, 0, 50, 50), res=0.5)
    # scored 5 m inside the tile's edges (the terrain raster reaches 10 m beyond them)
    err = stand_dtm_errors(dtm, terrain, margin=15.0)
    if total_max is not None:
        assert e["total"] <= total_max, e
    # shrubs just over the ground, where it strays from its lower surface, are kept with
    # it (the trim's offset follows that spread): type II 1.1-2.0 %, the DTM still within
    # 0.04-0.06 m (measured)
    assert e["type_ii"] <= 0.025, e
    assert err["rmse"] <= rmse_max, err


def test_lidar_ground_study_kind_splits_forest_and_capture(tmp_path):
    from core.validate import InputError
    from scanamp.study.kinds import KINDS, build_configs

    kind = KINDS["lidar-ground"]
    cap, rec = build_configs(kind, {"forest.slope": 30.0, "forest.ravines": 1,
                                    "density": 10.0, "reconstruct.ground.lower_passes": 2},
                             tmp_path / "a.toml")
    assert cap.forest == {"slope": 30.0, "ravines": 1} and cap.capture.density == 10.0
    assert rec.ground.lower_passes == 2
    with pytest.raises(InputError) as e:
        build_configs(kind, {"forest.slope": 50.0}, tmp_path / "b.toml")
    assert e.value.field == "forest.slope"
    with pytest.raises(InputError):
        build_configs(kind, {"forest.no_such_option": 1.0}, tmp_path / "c.toml")
