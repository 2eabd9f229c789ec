"""Range images, scan poses and E57 files (core.io.range, core.io.e57)."""

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

from core.frames import axis_angle_matrix, rigid
from core.io.e57 import E57Scan, read_e57, write_e57
from core.io.range import (
    RangeGrid,
    ScanPose,
    conf_files,
    conf_from_model,
    is_range_grid,
    model_from_conf,
    read_aln,
    read_conf,
    read_poses_json,
    read_range_grid,
    write_aln,
    write_conf,
    write_poses_json,
    write_range_grid,
)
from core.validate import InputError

EXCERPT = Path(__file__).parent / "data" / "dragon_excerpt"


def _grid(rng, rows=6, cols=7, holes=5):
    index = np.arange(rows * cols).reshape(rows, cols)
    flat = index.reshape(-1).copy()
    flat[rng.choice(rows * cols, holes, replace=False)] = -1
    keep = flat >= 0
    flat[keep] = np.arange(keep.sum())
    pts = rng.normal(size=(int(keep.sum()), 3))
    return RangeGrid(pts, flat.reshape(rows, cols), intensity=rng.uniform(size=len(pts)),
                     obj_info={"scanner": "test"})


@pytest.mark.parametrize("ascii", [False, True])
def test_range_grid_round_trip(tmp_path, ascii):
    g = _grid(np.random.default_rng(0))
    back = read_range_grid(write_range_grid(tmp_path / "g.ply", g, ascii=ascii))
    assert np.array_equal(back.index, g.index)
    assert np.array_equal(back.points, g.points)          # doubles, exactly
    np.testing.assert_allclose(back.intensity, g.intensity, rtol=1e-6)   # stored as float
    assert back.confidence is None and back.obj_info == {"scanner": "test"}
    assert is_range_grid(tmp_path / "g.ply")


def test_excerpt_of_the_real_files_reads_as_a_grid():
    g = read_range_grid(EXCERPT / "dragonStandRight_96.ply")
    assert g.index.shape == (40, 41) and len(g.points) == 1353
    used = g.index[g.index >= 0]
    assert np.array_equal(np.sort(used), np.arange(len(g.points)))   # each vertex once
    assert g.obj_info["is_cyberware_data"] == "1"
    # neighbouring cells are neighbouring samples: about half a millimetre apart
    a, b = g.index[:, :-1], g.index[:, 1:]
    ok = (a >= 0) & (b >= 0)
    step = np.linalg.norm(g.points[a[ok]] - g.points[b[ok]], axis=1)
    assert 0.2e-3 < np.median(step) < 1.0e-3


def _normals(p):
    _, nb = cKDTree(p).query(p, k=10)
    q = p[nb] - p[nb].mean(1, keepdims=True)
    return np.linalg.eigh(np.einsum("nki,nkj->nij", q, q))[1][:, :, 0]


def _gaps(poses):
    """Median point-to-plane gap (m) and overlap of each pair of excerpt scans posed by
    ``poses`` (file -> model_from_scan)."""
    names = sorted(poses)
    pts = {n: read_range_grid(EXCERPT / n).points for n in names}
    out = []
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            Ta, Tb = poses[a], poses[b]
            pa = pts[a] @ Ta[:3, :3].T + Ta[:3, 3]
            pb = pts[b] @ Tb[:3, :3].T + Tb[:3, 3]
            nb = _normals(pb)
            d, j = cKDTree(pb).query(pa)
            near = d < 1e-3
            gap = np.abs(np.einsum("ij,ij->i", pa[near] - pb[j[near]], nb[j[near]]))
            out.append((np.median(gap) if near.any() else np.inf, near.mean()))
    return np.array(out)


def _raw_conf():
    raw = {}
    for line in (EXCERPT / "dragon_excerpt.conf").read_text().splitlines():
        w = line.split()
        raw[w[1]] = np.array(w[2:5], float), np.array(w[5:9], float)
    return raw


def _quat(q):
    x, y, z, w = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def test_conf_convention_aligns_the_real_dragon_and_no_other_does():
    poses = dict(read_conf(EXCERPT / "dragon_excerpt.conf"))
    gaps = _gaps(poses)
    # Cyberware samples ~0.5 mm apart with ~0.1 mm noise: aligned scans agree to ~0.1 mm
    assert np.all(gaps[:, 0] < 0.2e-3), gaps
    assert np.all(gaps[:, 1] > 0.7), gaps
    raw = _raw_conf()
    others = {  # every other reading of "t q": the rotation as is, the inverse, ...
        "q as is": lambda t, q: rigid(_quat(q), t),
        "scan_from_model": lambda t, q: np.linalg.inv(rigid(_quat(q), t)),
        "inverse of the documented": lambda t, q: np.linalg.inv(rigid(_quat(q).T, t)),
        "rotate after translating": lambda t, q: rigid(_quat(q).T, _quat(q).T @ t),
        "translation negated": lambda t, q: rigid(_quat(q).T, -t),
        "translation ignored": lambda t, q: rigid(_quat(q).T),
    }
    for what, make in others.items():
        g = _gaps({n: make(*raw[n]) for n in raw})
        # each is clearly worse on at least one pair: twice the gap (the closest, the
        # translation ignored, leaves 0.35 mm where the documented one leaves 0.18 mm), or
        # half the overlap
        assert np.max(g[:, 0]) > 1.5 * np.max(gaps[:, 0]) or np.min(g[:, 1]) < 0.5, (what, g)


def test_conf_round_trip_and_quaternion_sign(tmp_path):
    rng = np.random.default_rng(1)
    entries = [(f"s{i}.ply", rigid(axis_angle_matrix(rng.normal(size=3), rng.uniform(0, 3.1)),
                                   rng.normal(size=3) * 0.01)) for i in range(4)]
    back = read_conf(write_conf(tmp_path / "p.conf", entries))
    assert [n for n, _ in back] == [n for n, _ in entries]
    for (_, a), (_, b) in zip(entries, back, strict=True):
        np.testing.assert_allclose(a, b, atol=1e-12)
    t, q = conf_from_model(entries[0][1])
    np.testing.assert_allclose(model_from_conf(t, -q), entries[0][1], atol=1e-12)


def test_conf_naming_a_missing_file(tmp_path):
    (tmp_path / "a.ply").write_bytes(b"")
    (tmp_path / "p.conf").write_text("camera 0 0 0 0 0 0 1\nbmesh a.ply 0 0 0 0 0 0 1\n"
                                     "bmesh gone.ply 0 0 0 0 0 0 1\n")
    assert len(read_conf(tmp_path / "p.conf")) == 2      # reading alone does not look
    with pytest.raises(InputError) as exc:
        conf_files(tmp_path / "p.conf")
    assert exc.value.path == str(tmp_path / "p.conf") and "gone.ply" in exc.value.field


@pytest.mark.parametrize("text,field", [("bmesh a.ply 0 0 0 0 0 1\n", "line 1 (a.ply)"),
                                        ("bmesh a.ply 0 0 0 x 0 0 1\n", "line 1 (a.ply)"),
                                        ("bmesh a.ply 0 0 0 0 0 0 0\n", "line 1 (a.ply)"),
                                        ("scan a.ply\n", "line 1")])
def test_bad_conf_lines(tmp_path, text, field):
    (tmp_path / "p.conf").write_text(text)
    with pytest.raises(InputError) as exc:
        read_conf(tmp_path / "p.conf")
    assert exc.value.field == field


def test_aln_round_trip(tmp_path):
    entries = [("a.ply", np.eye(4)), ("b.ply", rigid(axis_angle_matrix([0, 1, 0], 0.4),
                                                     [0.1, 0.2, 0.3]))]
    back = read_aln(write_aln(tmp_path / "p.aln", entries))
    assert [n for n, _ in back] == ["a.ply", "b.ply"]
    np.testing.assert_allclose(back[1][1], entries[1][1], atol=1e-15)


def test_poses_json_round_trip_and_errors(tmp_path):
    poses = [ScanPose("scans/scan_00.ply", rigid(np.eye(3), [1, 2, 3]), rms=1e-4, overlap=0.8),
             ScanPose("scans/scan_01.ply", None, registered=False, reason="no overlap")]
    back = read_poses_json(write_poses_json(tmp_path / "poses.json", poses))
    assert back[1] == poses[1]
    assert back[0].file == poses[0].file and back[0].rms == 1e-4 and back[0].overlap == 0.8
    np.testing.assert_array_equal(back[0].model_from_scan, poses[0].model_from_scan)
    (tmp_path / "bad.json").write_text('{"scans": [{"file": "a.ply", "model_from_scan": '
                                       '[[1, 0, 0], [0, 1, 0]]}]}')
    with pytest.raises(InputError) as exc:
        read_poses_json(tmp_path / "bad.json")
    assert exc.value.field == "scans[0].model_from_scan"


def _ply(tmp_path, *, rows=2, cols=2, cells=("1 0", "1 1", "0", "1 2"), n=3, extra=""):
    text = ("ply\nformat ascii 1.0\n" + extra + f"obj_info num_cols {cols}\n"
            f"obj_info num_rows {rows}\nelement vertex {n}\nproperty float x\nproperty float y\n"
            f"property float z\nelement range_grid {len(cells)}\n"
            "property list uchar int vertex_indices\nend_header\n"
            + "".join(f"{k} 0 1\n" for k in range(n)) + "\n".join(cells) + "\n")
    p = tmp_path / "bad.ply"
    p.write_text(text)
    return p


@pytest.mark.parametrize("kwargs,field,words", [
    ({"rows": 3}, "range_grid", "num_rows 3"),                       # size disagrees
    ({"cells": ("1 0", "1 7", "0", "1 2")}, "range_grid", "vertex index 7"),
    ({"cells": ("1 0", "2 1 2", "0", "1 2")}, "range_grid", "2 vertex indices"),
    ({"n": 0, "cells": ("0", "0", "0", "0")}, "vertex", "no points"),
])
def test_bad_range_grids_name_the_field(tmp_path, kwargs, field, words):
    with pytest.raises(InputError) as exc:
        read_range_grid(_ply(tmp_path, **kwargs))
    assert exc.value.field == field and words in exc.value.message
    assert exc.value.path.endswith("bad.ply")


def test_truncated_binary_grid(tmp_path):
    p = write_range_grid(tmp_path / "g.ply", _grid(np.random.default_rng(2)))
    p.write_bytes(p.read_bytes()[:-7])
    with pytest.raises(InputError, match="truncated"):
        read_range_grid(p)
    (tmp_path / "plain.ply").write_text("ply\nformat ascii 1.0\nelement vertex 1\n"
                                        "property float x\nproperty float y\nproperty float z\n"
                                        "end_header\n0 0 0\n")
    assert not is_range_grid(tmp_path / "plain.ply")
    with pytest.raises(InputError) as exc:
        read_range_grid(tmp_path / "plain.ply")
    assert exc.value.field == "range_grid"


def test_e57_round_trip_with_poses_and_grids(tmp_path):
    rng = np.random.default_rng(3)
    rows, cols = np.divmod(np.arange(12), 4)
    keep = np.ones(12, bool)
    keep[5] = False                                   # an unmeasured cell
    structured = E57Scan("station A", rng.normal(size=(11, 3)) * 10,
                         rigid(axis_angle_matrix([1, 2, 3], 1.0), [100.0, -5, 2]),
                         row=rows[keep] + 2, column=cols[keep], intensity=rng.uniform(size=11))
    loose = E57Scan("station B", rng.normal(size=(5, 3)),
                    rigid(axis_angle_matrix([0, 0, 1], -2.5), [1.0, 2, 3]))
    back = read_e57(write_e57(tmp_path / "two.e57", [structured, loose]))
    assert [s.name for s in back] == ["station A", "station B"]
    for a, b in zip([structured, loose], back, strict=True):
        np.testing.assert_allclose(b.points, a.points, rtol=0, atol=1e-5)   # float32 storage
        np.testing.assert_allclose(b.model_from_scan, a.model_from_scan, atol=1e-12)
    grid = back[0].grid()
    assert grid.shape == (3, 4) and grid[1, 1] == -1
    assert np.array_equal(grid[grid >= 0], np.arange(11))
    np.testing.assert_allclose(back[0].intensity, structured.intensity, rtol=1e-6)
    assert back[1].grid() is None and back[1].intensity is None


def test_e57_errors(tmp_path):
    # an E57 scan with no valid points: tests/test_range_scans.py (with the CLI's)
    (tmp_path / "x.e57").write_text("not an e57")
    with pytest.raises(InputError, match="not a readable E57"):
        read_e57(tmp_path / "x.e57")


def test_big_endian_range_grid_as_scanalyze_writes_it(tmp_path):
    g = _grid(np.random.default_rng(4), rows=3, cols=4, holes=3)
    flat = g.index.reshape(-1)
    head = ("ply\nformat binary_big_endian 1.0\nobj_info num_cols 4\nobj_info num_rows 3\n"
            f"element vertex {len(g.points)}\nproperty float x\nproperty float y\n"
            "property float z\nproperty uchar intensity\n"
            f"element range_grid {flat.size}\nproperty list uchar int vertex_indices\n"
            "end_header\n")
    rec = np.empty(len(g.points), [("x", ">f4"), ("y", ">f4"), ("z", ">f4"), ("i", "u1")])
    rec["x"], rec["y"], rec["z"] = g.points.T
    rec["i"] = np.arange(len(g.points))
    cells = b"".join(b"\x00" if i < 0 else b"\x01" + np.array([i], ">i4").tobytes()
                     for i in flat)
    (tmp_path / "be.ply").write_bytes(head.encode() + rec.tobytes() + cells)
    back = read_range_grid(tmp_path / "be.ply")
    assert np.array_equal(back.index, g.index)
    np.testing.assert_array_equal(back.points, g.points.astype(np.float32))
    np.testing.assert_array_equal(back.intensity, np.arange(len(g.points)))
