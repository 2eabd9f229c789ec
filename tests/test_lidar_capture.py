"""scanamp capture lidar: LAZ at survey coordinates with its truth, report.json, E57 per
station, same seed same bytes, strips equal to one pass, bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

from core.io.las import read_las
from scanamp.cli import main

ORIGIN = [512345.6, 6789012.3, 100.0]
SPEC = f"""
[scene]
name = "block"
seed = 0
origin = {ORIGIN}

[[objects]]
name = "ground"
shape = "plane"
size = [60.0, 60.0]

[[objects]]
name = "house"
shape = "box"
size = [10.0, 10.0, 8.0]
position = [0.0, 0.0, 4.0]
"""
FAST = ["--preset", "livox-avia", "--footprint-samples", "3", "--pulse-rate", "20000",
        "--speed", "15"]


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    p = tmp_path_factory.mktemp("scene") / "block.toml"
    p.write_text(SPEC)
    return p


@pytest.fixture(scope="module")
def survey(scene, tmp_path_factory):
    out = tmp_path_factory.mktemp("runs") / "a"
    assert main(["capture", "lidar", str(scene), *FAST, "--out", str(out)]) == 0
    return out


def test_laz_keeps_survey_coordinates_and_the_truth(survey):
    pts, info = read_las(survey / "points.laz")
    assert info.version == "1.4" and info.point_count > 1000
    np.testing.assert_array_equal(info.offsets, np.round(ORIGIN))
    for name in ("object_id", "part", "true_x", "true_y", "true_z", "snr"):
        assert name in info.extra_dims
    # measured points lie within the range noise (cm) of where their sub-ray hit
    err = np.hypot(pts["x"] - pts["true_x"], pts["y"] - pts["true_y"])
    assert np.median(err) < 0.05
    assert abs(np.median(pts["true_x"]) - ORIGIN[0]) < 30
    roof = pts["true_z"] > ORIGIN[2] + 7.9
    assert roof.any() and set(np.unique(pts["object_id"][roof])) == {1}
    assert set(np.unique(pts["point_source_id"])) == {1}
    assert np.all(np.diff(pts["gps_time"]) >= 0)


def test_report_has_the_plan_and_the_achieved_density(survey):
    r = json.loads((survey / "report.json").read_text())
    assert r["preset"] == "livox-avia" and r["plan"]["platform"] == "multicopter"
    assert r["points"] == read_las(survey / "points.laz")[1].point_count
    assert r["density_first_per_m2"] > 0 and r["plan"]["pulse_rate_hz"] == 20000


def test_same_seed_same_bytes_and_strips_equal_one_pass(scene, survey, tmp_path):
    b = tmp_path / "b"
    assert main(["capture", "lidar", str(scene), *FAST, "--out", str(b)]) == 0
    assert (b / "points.laz").read_bytes() == (survey / "points.laz").read_bytes()
    c = tmp_path / "c"
    assert main(["capture", "lidar", str(scene), *FAST, "--per-strip", "--out", str(c)]) == 0
    assert len(list((c / "strips").glob("*.laz"))) == 1
    pa, _ = read_las(survey / "points.laz")
    pc, _ = read_las(c / "points.laz")
    for k in ("x", "y", "z", "gps_time", "object_id", "intensity"):
        np.testing.assert_array_equal(pa[k], pc[k])


def test_density_plans_the_strips(scene, tmp_path):
    out = tmp_path / "d"
    assert main(["capture", "lidar", str(scene), "--preset", "riegl-lms-q560", "--platform",
                 "multicopter", "--footprint-samples", "1", "--altitude", "50", "--density",
                 "100", "--out", str(out)]) == 0
    r = json.loads((out / "report.json").read_text())
    assert r["plan"]["density_planned_per_m2"] == pytest.approx(100, rel=1e-6)
    assert r["plan"]["legs"] == 2 and r["plan"]["pulse_rate_hz"] == 50000
    # the achieved first-return density is the plan's (the ground covers the area)
    assert r["density_first_per_m2"] == pytest.approx(100, rel=0.05)


def test_density_under_the_middle_of_one_strip(scene, tmp_path):
    """A 60 m block under one 250 m swath of a polygon scanner: its pulses fall
    uniformly in angle, so the middle of the swath is 5 % denser than its mean
    (tan 22.5 deg / 22.5 deg in radians); the plan allows for it."""
    out = tmp_path / "n"
    assert main(["capture", "lidar", str(scene), "--preset", "riegl-lms-q560",
                 "--footprint-samples", "1", "--altitude", "300", "--density", "4",
                 "--out", str(out)]) == 0
    r = json.loads((out / "report.json").read_text())
    assert r["plan"]["legs"] == 1
    assert r["density_first_per_m2"] == pytest.approx(4.0, rel=0.02)


def test_terrestrial_stations_go_to_e57_with_pose_and_grid(scene, tmp_path):
    from core.io.e57 import read_e57

    out = tmp_path / "t"
    assert main(["capture", "lidar", str(scene), "--preset", "riegl-vz-400", "--stations",
                 "2", "--angular-step", "1.5", "--footprint-samples", "1",
                 "--out", str(out)]) == 0
    scans = read_e57(out / "scans.e57")
    assert len(scans) == 2
    pts, _ = read_las(out / "points.laz")
    for s, sid in zip(scans, (1, 2), strict=True):
        assert s.grid() is not None
        sel = pts["point_source_id"] == sid
        world = s.points @ s.model_from_scan[:3, :3].T + s.model_from_scan[:3, 3]
        np.testing.assert_allclose(np.sort(world[:, 2]), np.sort(pts["z"][sel]), atol=1e-3)


@pytest.mark.parametrize("flags,field", [
    (["--preset", "riegl-nope"], "preset"),
    (["--preset", "riegl-lms-q560", "--density", "100000"], "density"),
])
def test_bad_input_exits_2_with_one_line_and_writes_nothing(scene, tmp_path, capsys,
                                                           flags, field):
    out = tmp_path / "bad"
    assert main(["capture", "lidar", str(scene), *flags, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:") and field in err[0]
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_reconstruction_same_seed_same_bytes(survey, tmp_path, output_differences):
    a, b = tmp_path / "a", tmp_path / "b"
    for out in (a, b):
        assert main(["-q", "reconstruct", "lidar", str(survey / "points.laz"), "--out",
                     str(out)]) == 0
    assert output_differences(a, b) == []
