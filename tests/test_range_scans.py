"""The range-scan model (reconstruct.scans): triangulating range images, normals, lines of
sight, confidences, and loading scans from files, folders, E57 and .conf files."""

import numpy as np
import pytest

from core.frames import axis_angle_matrix, rigid
from core.io.e57 import E57Scan, write_e57
from core.io.range import RangeGrid, write_conf, write_range_grid
from core.validate import InputError
from reconstruct.scans import (
    RangeScan,
    check_scans,
    load_scans,
    scan_from_grid,
    scan_from_points,
)
from reconstruct.surface import sample_spacing

STEP = 1e-3     # grid spacing of the synthetic range images (m)


def _image(depth):
    """A perspective range image of ``depth (rows, cols)`` (NaN empty) seen from the
    origin along +z, one sample per ``STEP`` at 0.5 m."""
    rows, cols = depth.shape
    r, c = np.mgrid[0:rows, 0:cols]
    ok = np.isfinite(depth)
    ray = np.stack([(c - cols / 2) * STEP / 0.5, (r - rows / 2) * STEP / 0.5,
                    np.ones_like(depth)], -1)
    pts = ray[ok] * depth[ok][:, None]
    index = np.full(depth.shape, -1)
    index[ok] = np.arange(ok.sum())
    return RangeGrid(pts, index)


def test_a_step_edge_is_not_bridged_and_a_smooth_surface_is():
    depth = np.full((12, 20), 0.5)
    depth[:, 10:] = 0.52                    # a 2 cm step: 20 sample spacings
    s = scan_from_grid(_image(depth))
    side = np.zeros(len(s.points), bool)
    side[s.grid[:, 10:].ravel()] = True
    mixed = side[s.triangles].any(axis=1) & ~side[s.triangles].all(axis=1)
    assert not mixed.any()
    # both flat parts are fully triangulated: 2 triangles per 2 x 2 block
    assert len(s.triangles) == 2 * (11 * 9 + 11 * 9)
    # a smooth but steep ramp (45 degrees) is one surface
    r, c = np.mgrid[0:12, 0:20]
    smooth = scan_from_grid(_image(0.5 + c * STEP * 1.0))
    assert len(smooth.triangles) == 2 * 11 * 19


def test_grazing_triangles_are_dropped():
    r, c = np.mgrid[0:10, 0:10]
    steep = scan_from_grid(_image(0.5 + c * STEP * np.tan(np.radians(85))), max_jump=100)
    assert len(steep.triangles) == 0        # 85 degrees from the line of sight
    kept = scan_from_grid(_image(0.5 + c * STEP * np.tan(np.radians(85))), max_jump=100,
                          max_sight_deg=89)
    assert len(kept.triangles) == 2 * 9 * 9


def test_normals_face_the_scanner_and_confidence_follows_the_angle_and_the_edges():
    r, c = np.mgrid[0:21, 0:21]
    tilt = np.radians(60)
    s = scan_from_grid(_image(0.5 + c * STEP * np.tan(tilt)), edge_steps=3)
    assert np.all(np.einsum("ij,ij->i", s.normals, s.sight) > 0)
    assert np.all((s.confidence >= 0) & (s.confidence <= 1))
    d = np.minimum.reduce([r, c, 20 - r, 20 - c]).ravel()     # steps to the grid's edge
    inner = d >= 4
    # a plane tilted 60 degrees from the line of sight: cos 60 = 0.5 (the rays spread a
    # little about the optical axis, hence the tolerance)
    np.testing.assert_allclose(s.confidence[s.grid.ravel()[inner]], 0.5, atol=0.03)
    assert np.all(s.confidence[s.grid.ravel()[d == 0]] == 0)    # the boundary
    ramp = [np.median(s.confidence[s.grid.ravel()[d == k]]) for k in range(5)]
    assert np.all(np.diff(ramp) >= 0) and ramp[0] == 0 and ramp[4] > 0.45


def test_sight_conventions_of_range_images():
    g = _image(np.full((4, 5), 0.5))
    s = scan_from_grid(g)
    np.testing.assert_allclose(s.sight, -g.points / np.linalg.norm(g.points, axis=1)[:, None])
    cyb = scan_from_grid(RangeGrid(g.points, g.index, obj_info={"is_cyberware_data": "1"}))
    assert np.all(cyb.sight == [0, 0, 1])


def test_scan_of_points_orients_normals_toward_the_scanner():
    rng = np.random.default_rng(0)
    d = rng.normal(size=(3000, 3))
    sphere = 0.05 * d / np.linalg.norm(d, axis=1)[:, None] + [0, 0, 0.5]
    seen = sphere[sphere[:, 2] < 0.5]                         # the half facing the origin
    s = scan_from_points(seen, name="ball")
    outward = (seen - [0, 0, 0.5]) / 0.05
    facing = np.einsum("ij,ij->i", outward, s.sight) > 0.2    # not on the silhouette, where
    assert np.all(np.einsum("ij,ij->i", s.normals[facing], outward[facing]) > 0.9)  # it's moot
    np.testing.assert_allclose(s.confidence, np.clip(np.einsum("ij,ij->i", s.normals, s.sight),
                                                     0, 1))
    assert s.grid is None and len(s.triangles) == 0


def test_transformed_moves_every_vector():
    s = scan_from_grid(_image(np.full((5, 6), 0.5)))
    T = rigid(axis_angle_matrix([1, 1, 0], 0.7), [0.1, 0.2, 0.3])
    m = s.transformed(T)
    np.testing.assert_allclose(m.points, s.points @ T[:3, :3].T + T[:3, 3])
    np.testing.assert_allclose(np.einsum("ij,ij->i", m.normals, m.sight),
                               np.einsum("ij,ij->i", s.normals, s.sight))
    np.testing.assert_allclose(m.origin, T[:3, 3])
    assert sample_spacing([s]) == pytest.approx(STEP, rel=0.01)


def test_load_scans_from_files_folders_e57_and_conf(tmp_path):
    depth = np.full((6, 8), 0.5)
    grid = _image(depth)
    folder = tmp_path / "set"
    write_range_grid(folder / "a.ply", grid)
    write_range_grid(folder / "b.ply", grid, ascii=True)
    (folder / "notes.txt").write_text("not a scan")
    from core.io.mesh import write_points

    write_points(folder / "c.pcd", grid.points)
    rows, cols = np.nonzero(grid.index >= 0)
    write_e57(tmp_path / "stations.e57", [
        E57Scan("one", grid.points, rigid(np.eye(3), [1, 0, 0]), row=rows, column=cols),
        E57Scan("two", grid.points)])
    scans = load_scans([folder, tmp_path / "stations.e57"])
    assert [s.name for s in scans] == ["a.ply", "b.ply", "c.pcd", "stations.e57[0]",
                                       "stations.e57[1]"]
    assert all(isinstance(s, RangeScan) for s in scans)
    assert scans[0].grid.shape == (6, 8) and len(scans[0].triangles) == 2 * 5 * 7
    assert scans[2].grid is None and scans[4].grid is None
    assert scans[3].grid.shape == (6, 8)
    np.testing.assert_allclose(scans[3].model_from_scan[:3, 3], [1, 0, 0])
    write_conf(folder / "p.conf", [("a.ply", np.eye(4)), ("b.ply", np.eye(4))])
    assert [s.name for s in load_scans(folder / "p.conf")] == ["a.ply", "b.ply"]


def test_load_scans_bad_inputs(tmp_path):
    write_range_grid(tmp_path / "a.ply", _image(np.full((3, 3), 0.5)))
    with pytest.raises(InputError) as exc:
        load_scans(tmp_path / "a.ply")
    assert exc.value.field == "scans" and "at least 2" in exc.value.message
    assert len(load_scans(tmp_path / "a.ply", min_scans=1)) == 1
    write_conf(tmp_path / "p.conf", [("a.ply", np.eye(4)), ("gone.ply", np.eye(4))])
    with pytest.raises(InputError) as exc:
        load_scans(tmp_path / "p.conf")
    assert exc.value.path == str(tmp_path / "p.conf") and "gone.ply" in exc.value.field
    with pytest.raises(InputError, match="file not found"):
        load_scans([tmp_path / "a.ply", tmp_path / "nothing.ply"])
    empty = RangeScan("void", np.empty((0, 3)), np.empty((0, 3)), np.empty((0, 3)),
                      np.empty(0))
    with pytest.raises(InputError, match="no points"):
        check_scans([empty, empty])


class _Bounded(np.ndarray):
    """An array whose bounds include 0, even when empty: pye57 takes the bounds of the
    valid points (a scan with none is what the test needs) and gives the invalid-state
    field the default value 0, which must lie within its bounds."""

    def min(self, *a, **k):
        return 0 if self.size == 0 else min(0, np.asarray(self).min())

    def max(self, *a, **k):
        return 0.0 if self.size == 0 else np.asarray(self).max()


def _void_e57(path):
    """An E57 file whose one scan has no valid point."""
    import pye57

    e = pye57.E57(str(path), mode="w")
    xyz = np.zeros(2).view(_Bounded)
    e.write_scan_raw({"cartesianX": xyz, "cartesianY": xyz, "cartesianZ": xyz,
                      "cartesianInvalidState": np.array([2, 2], np.int8).view(_Bounded)},
                     name="void")
    e.close()


def test_an_e57_scan_without_points(tmp_path):
    from core.io.e57 import read_e57

    _void_e57(tmp_path / "void.e57")
    with pytest.raises(InputError) as exc:
        read_e57(tmp_path / "void.e57")
    assert exc.value.field == "data3D[0] (void)" and "no points" in exc.value.message
    with pytest.raises(InputError) as exc:
        load_scans([tmp_path / "void.e57", tmp_path / "void.e57"])
    assert exc.value.path == str(tmp_path / "void.e57")


def _bad_inputs(root):
    """(case, argv inputs, the file and field the one-line error must name)."""
    good = _image(np.full((4, 5), 0.5))
    write_range_grid(root / "good.ply", good)
    write_range_grid(root / "good2.ply", good)
    text = (root / "good.ply").read_bytes()
    (root / "size.ply").write_bytes(text.replace(b"obj_info num_rows 4", b"obj_info num_rows 5"))
    bad = RangeGrid(good.points, good.index)
    write_range_grid(root / "index.ply", bad, ascii=True)
    lines = (root / "index.ply").read_text().splitlines()
    lines[-1] = "1 999"
    (root / "index.ply").write_text("\n".join(lines) + "\n")
    (root / "empty.ply").write_text(
        "ply\nformat ascii 1.0\nobj_info num_cols 1\nobj_info num_rows 1\nelement vertex 0\n"
        "property float x\nproperty float y\nproperty float z\nelement range_grid 1\n"
        "property list uchar int vertex_indices\nend_header\n0\n")
    write_conf(root / "p.conf", [("good.ply", np.eye(4)), ("gone.ply", np.eye(4))])
    _void_e57(root / "void.e57")
    return [("grid size", ["size.ply", "good2.ply"], ("size.ply", "range_grid")),
            ("cell index", ["index.ply", "good2.ply"], ("index.ply", "range_grid", "999")),
            ("no points", ["empty.ply", "good2.ply"], ("empty.ply", "vertex")),
            ("e57 without points", ["void.e57", "good2.ply"], ("void.e57", "data3D[0]")),
            ("conf missing file", ["p.conf"], ("p.conf", "gone.ply")),
            ("one scan", ["good.ply"], ("good.ply", "scans"))]


def test_bad_scans_through_the_cli(tmp_path, capsys):
    """``scanamp reconstruct scans`` on each bad input: exit 2, one line naming the file and
    the field, nothing written."""
    from scanamp.cli import main

    for case, inputs, words in _bad_inputs(tmp_path):
        before = sorted(p.name for p in tmp_path.iterdir())
        code = main(["-q", "reconstruct", "scans", *(str(tmp_path / f) for f in inputs),
                     "--out", str(tmp_path / "out")])
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2, (case, err)
        assert len(err) == 1 and err[0].startswith("error: "), (case, err)
        assert all(w in err[0] for w in words), (case, err[0])
        assert sorted(p.name for p in tmp_path.iterdir()) == before, case
