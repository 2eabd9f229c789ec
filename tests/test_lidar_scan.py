"""Scan patterns, platforms, presets, part labels and flight planning."""

from __future__ import annotations

import numpy as np
import pytest

from acquire.lidar.labels import PARTS, asprs_class, part_code
from acquire.lidar.patterns import ScanPattern
from acquire.lidar.planning import plan_stations, plan_strips, swath_width
from acquire.lidar.platforms import Leg, mount_for
from acquire.lidar.presets import PRESETS, get_preset
from core.validate import InputError

T = np.arange(20000) / 20000.0          # one second at 20 kHz


@pytest.mark.parametrize("kind", ["oscillating", "polygon"])
def test_line_scanners_sweep_their_field_in_lines(kind):
    p = ScanPattern(kind, fov_deg=(-20, 30), rate_hz=50)
    d, ang = p.directions(T, np.arange(len(T)))
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1, atol=1e-12)
    assert np.all(d[:, 1] == 0)
    assert ang.min() == pytest.approx(-20, abs=0.1) and ang.max() == pytest.approx(30, abs=0.1)
    steps = np.diff(ang)
    if kind == "polygon":      # all lines swept the same way: one fly-back per line
        assert (steps < 0).sum() == 49
    else:                      # zig-zag: turning at each end, two lines per period
        turns = np.sum(np.diff(np.sign(steps)) != 0)
        assert 98 <= turns <= 101
    assert p.line_index(T).max() == (49 if kind == "polygon" else 99)


def test_conic_keeps_its_off_nadir_angle_and_spinning_its_channels():
    c = ScanPattern("conic", fov_deg=(-20, 20), rate_hz=40)
    d, _ = c.directions(T, np.arange(len(T)))
    np.testing.assert_allclose(np.degrees(np.arccos(d[:, 2])), 20, atol=1e-9)
    s = ScanPattern("spinning", rate_hz=10, channels_deg=tuple(range(-15, 16, 2)))
    d, _ = s.directions(T, np.arange(len(T)))
    el = np.degrees(np.arcsin(d[:, 2]))
    np.testing.assert_allclose(el[:16], np.arange(-15, 16, 2), atol=1e-9)
    az = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    assert (az[-1] - az[0]) / (2 * np.pi) == pytest.approx(10, rel=1e-3)


def test_rosette_fills_its_circle_without_repeating():
    p = ScanPattern("rosette", fov_deg=(-35.2, 35.2), rate_hz=10)
    d, _ = p.directions(T, np.arange(len(T)))
    off = np.degrees(np.arccos(d[:, 2]))
    assert off.max() <= 35.2 + 1e-6 and off.max() > 34
    # coverage: most cells of a 20 x 20 grid over the disc are visited within a second
    u = np.tan(np.radians(35.2))
    x, y = d[:, 0] / d[:, 2] / u, d[:, 1] / d[:, 2] / u
    cells = {(int(a), int(b)) for a, b in zip((x + 1) * 10, (y + 1) * 10, strict=True)}
    inside = sum(1 for i in range(20) for j in range(20)
                 if ((i + 0.5) / 10 - 1) ** 2 + ((j + 0.5) / 10 - 1) ** 2 < 0.8)
    assert len(cells) > 0.9 * inside


def test_mounts_are_rotations_and_look_where_they_should():
    for plat in ("airplane", "multicopter", "vehicle", "tripod"):
        for pat in ("polygon", "spinning"):
            M = mount_for(plat, pat)
            np.testing.assert_allclose(M @ M.T, np.eye(3), atol=1e-12)
            assert np.linalg.det(M) == pytest.approx(1)
    assert (mount_for("airplane", "polygon") @ [0, 0, 1]).tolist() == [0, 0, -1]
    assert (mount_for("tripod", "polygon") @ [1, 0, 0]).tolist() == [0, 0, 1]   # sweeps up


def test_a_station_pans_about_its_vertical():
    leg = Leg(source_id=3, start=np.array([1.0, 2, 3]), end=np.array([1.0, 2, 3]), speed=0,
              gps_start=0.0, mount=mount_for("tripod", "polygon"), pan_rate_deg_s=90.0)
    assert leg.duration == pytest.approx(4.0)
    pos, R = leg.poses(np.array([0.0, 1.0]))
    np.testing.assert_allclose(pos, [[1, 2, 3]] * 2)
    np.testing.assert_allclose(R[1] @ [0, 0, 1], [0, 1, 0], atol=1e-12)   # boresight +y


def test_presets_are_complete_and_unknown_ones_listed():
    for p in PRESETS.values():
        assert p.sources and p.pulse_rate_hz > 0 and p.max_returns >= 1
        assert 500 <= p.wavelength_nm <= 1600
    with pytest.raises(InputError) as e:
        get_preset("riegl-vq-1560i")
    assert e.value.field == "preset" and all(n in str(e.value) for n in PRESETS)


def test_labels_map_parts_to_asprs_classes():
    parts = np.array([part_code(n) for n in PARTS], np.uint8)
    h = np.full(len(parts), 10.0)
    assert asprs_class(parts, h).tolist() == [1, 2, 5, 5, 5, 5, 6, 11, 9, 6]
    leaf = np.full(3, part_code("leaf"), np.uint8)
    assert asprs_class(leaf, np.array([0.2, 1.0, 3.0])).tolist() == [3, 4, 5]
    with pytest.raises(InputError):
        part_code("twig")


def test_planned_strips_cover_the_area_at_the_target_density():
    pre = get_preset("riegl-lms-q560")
    area = np.array([[0.0, 0.0], [2000.0, 1500.0]])
    plan = plan_strips(area, 100.0, pre, altitude=300.0, overlap=0.3, density=8.0)
    W = swath_width(pre, 300.0)
    assert W == pytest.approx(2 * 300 * np.tan(np.radians(22.5)))
    ys = sorted(leg.start[1] for leg in plan.legs)
    assert ys[0] - W / 2 <= 0 and ys[-1] + W / 2 >= 1500               # covered
    np.testing.assert_allclose(np.diff(ys), W * 0.7)
    assert all(leg.start[2] == 400.0 for leg in plan.legs)
    assert plan.density_planned == pytest.approx(8.0)
    assert 30 <= plan.speed <= 90 and plan.pulse_rate in pre.pulse_rates_hz
    dirs = [np.sign(leg.end[0] - leg.start[0]) for leg in plan.legs]
    assert all(a == -b for a, b in zip(dirs, dirs[1:], strict=False))   # alternating
    t = [leg.gps_start for leg in plan.legs]
    assert all(b > a for a, b in zip(t, t[1:], strict=False))
    with pytest.raises(InputError) as e:
        plan_strips(area, 0.0, pre, altitude=300.0, density=1000.0)
    assert e.value.field == "density" and "reachable" in str(e.value)


def test_stations_scan_at_the_angular_step():
    pre = get_preset("riegl-vz-400")
    for step, prr in ((0.05, 122e3), (0.2, 42e3)):     # 120 lines/s at most
        plan = plan_stations(np.array([[0.0, 0, 1.5], [10, 0, 1.5]]), pre,
                             angular_step_deg=step)
        assert len(plan.legs) == 2 and plan.pulse_rate == prr
        pulses_per_line = plan.pulse_rate / plan.scan_rate
        assert 100.0 / pulses_per_line == pytest.approx(step, rel=1e-6)
        assert plan.legs[0].pan_rate_deg_s == pytest.approx(plan.scan_rate * step)
