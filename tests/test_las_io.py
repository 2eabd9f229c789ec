"""core.io.las: LAS 1.4 / LAZ round trips at survey coordinates, streaming, bad files."""

from __future__ import annotations

import numpy as np
import pytest

from core.io.las import SCAN_ANGLE_STEP_DEG, LasWriter, iter_las_chunks, read_las
from core.validate import InputError

ORIGIN = np.array([512_345.678, 6_789_012.345, 310.0])   # projected metres (UTM-like)
WKT = 'PROJCS["ETRS89 / UTM zone 32N",AUTHORITY["EPSG","25832"]]'


def _chunk(rng, n, k):
    pts = {
        "x": ORIGIN[0] + rng.uniform(-800, 800, n),
        "y": ORIGIN[1] + rng.uniform(-800, 800, n),
        "z": ORIGIN[2] + rng.uniform(-50, 60, n),
        "intensity": rng.integers(0, 65535, n),
        "return_number": rng.integers(1, 4, n),
        "gps_time": 3.2e8 + np.sort(rng.uniform(0, 10, n)) + 10 * k,
        "scan_angle": rng.uniform(-30, 30, n),
        "point_source_id": np.full(n, k + 1),
        "classification": rng.choice([2, 3, 4, 5, 6], n),
        "object_id": rng.integers(-1, 5000, n),
        "part": rng.integers(0, 10, n),
        "true_x": ORIGIN[0] + rng.uniform(-800, 800, n),
    }
    pts["number_of_returns"] = pts["return_number"] + rng.integers(0, 3, n)
    return pts


EXTRA = {"object_id": "int32", "part": "uint8", "true_x": "float64"}


@pytest.mark.parametrize("suffix", [".laz", ".las"])
def test_round_trip_large_coordinates_exact_to_the_scale(tmp_path, suffix):
    rng = np.random.default_rng(0)
    chunks = [_chunk(rng, 3000, k) for k in range(3)]
    path = tmp_path / f"s{suffix}"
    with LasWriter(path, origin=ORIGIN, scale=0.001, extra=EXTRA, crs_wkt=WKT) as w:
        for c in chunks:
            w.write(c)
    back, info = read_las(path)
    want = {k: np.concatenate([c[k] for c in chunks]) for k in chunks[0]}
    assert info.point_count == 9000 and info.version == "1.4" and info.point_format == 6
    assert info.crs_wkt == WKT
    np.testing.assert_array_equal(info.offsets, np.round(ORIGIN))
    for axis in "xyz":      # quantised to the 1 mm grid about the offset: error <= 0.5 mm
        assert np.abs(back[axis] - want[axis]).max() <= 0.0005 + 1e-9
    for name in ("intensity", "return_number", "number_of_returns", "point_source_id",
                 "classification", "object_id", "part"):
        np.testing.assert_array_equal(back[name], want[name].astype(back[name].dtype), name)
    np.testing.assert_array_equal(back["gps_time"], want["gps_time"])
    np.testing.assert_array_equal(back["true_x"], want["true_x"])
    assert np.abs(back["scan_angle"] - want["scan_angle"]).max() <= SCAN_ANGLE_STEP_DEG / 2 + 1e-6
    assert info.extra_dims == tuple(EXTRA)
    # bounds in the header are those of the points
    np.testing.assert_allclose(info.mins, [back[a].min() for a in "xyz"], atol=1e-9)


def test_chunks_stream_in_order_and_sum_to_the_file(tmp_path):
    rng = np.random.default_rng(1)
    c = _chunk(rng, 2500, 0)
    path = tmp_path / "a.laz"
    with LasWriter(path, origin=ORIGIN, extra=EXTRA) as w:
        w.write(c)
    xs = [ch["x"] for ch, _ in iter_las_chunks(path, 1000, fields=("x",))]
    assert [len(x) for x in xs] == [1000, 1000, 500]
    np.testing.assert_allclose(np.concatenate(xs), c["x"], atol=5e-4 + 1e-9)


def test_same_input_same_bytes(tmp_path):
    for name in ("a.laz", "b.laz"):
        with LasWriter(tmp_path / name, origin=ORIGIN, extra=EXTRA) as w:
            w.write(_chunk(np.random.default_rng(2), 500, 0))
    assert (tmp_path / "a.laz").read_bytes() == (tmp_path / "b.laz").read_bytes()


def test_failure_inside_the_block_leaves_no_file(tmp_path):
    path = tmp_path / "x.laz"
    with pytest.raises(RuntimeError), LasWriter(path, origin=ORIGIN) as w:
        w.write({"x": [ORIGIN[0]], "y": [ORIGIN[1]], "z": [ORIGIN[2]]})
        raise RuntimeError("stop")
    assert list(tmp_path.iterdir()) == []


def test_bad_files_and_fields_raise_input_error(tmp_path):
    empty = tmp_path / "e.las"
    with LasWriter(empty, origin=ORIGIN):
        pass
    with pytest.raises(InputError, match="no points") as e:
        read_las(empty)
    assert e.value.field == "points" and e.value.path == str(empty)
    junk = tmp_path / "j.laz"
    junk.write_bytes(b"not a las file at all" * 20)
    with pytest.raises(InputError) as e:
        read_las(junk)
    assert e.value.path == str(junk)
    with pytest.raises(InputError, match="file not found"):
        read_las(tmp_path / "missing.laz")
    with pytest.raises(InputError) as e:
        read_las(_one_point(tmp_path), fields=("nope",))
    assert e.value.field == "nope"
    with pytest.raises(InputError) as e, LasWriter(tmp_path / "f.laz", origin=ORIGIN) as w:
        w.write({"x": [ORIGIN[0] + 3e6], "y": [ORIGIN[1]], "z": [ORIGIN[2]]})
    assert e.value.field == "x" and not (tmp_path / "f.laz").exists()


def _one_point(tmp_path):
    path = tmp_path / "one.laz"
    with LasWriter(path, origin=ORIGIN) as w:
        w.write({"x": [ORIGIN[0]], "y": [ORIGIN[1]], "z": [ORIGIN[2]]})
    return path


def test_a_las_12_file_reads_its_scan_angle_rank_and_epsg_code(tmp_path):
    """Real surveys are often LAS 1.2 (point format 1): a scan angle rank in degrees and
    the CRS as a GeoTIFF key directory (EPSG 25832 here), read as WKT."""
    import laspy
    from laspy.vlrs.known import GeoKeyDirectoryVlr, GeoKeyEntryStruct

    key = GeoKeyEntryStruct()
    key.id, key.tiff_tag_location, key.count, key.value_offset = 3072, 0, 1, 25832
    vlr = GeoKeyDirectoryVlr()
    vlr.geo_keys, vlr.geo_keys_header.number_of_keys = [key], 1
    h = laspy.LasHeader(point_format=1, version="1.2")
    h.vlrs.append(vlr)
    las = laspy.LasData(h)
    las.x, las.y, las.z = np.array([5e5, 5e5 + 1]), np.array([6e6, 6e6]), np.array([1.0, 2.0])
    las.scan_angle_rank = np.array([-12, 30])
    las.write(tmp_path / "old.las")
    pts, info = read_las(tmp_path / "old.las")
    assert info.version == "1.2" and pts["scan_angle"].tolist() == [-12.0, 30.0]
    assert info.crs_wkt is not None and "UTM zone 32N" in info.crs_wkt
