"""Volumetric merging of range scans (reconstruct.surface.volumetric, issue 30).

The scans are rendered here by ray casting meshes with known answers (a sphere, a plane,
a cup with a pit) from a pinhole range scanner, triangulated on their pixel grid."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from core.meshes import is_closed
from core.validate import InputError
from reconstruct.surface.volumetric import (
    EMPTY,
    OBSERVED,
    UNSEEN,
    MergeOptions,
    merge_scans,
    sample_spacing,
    scan_signed_distance,
)

R = 0.05   # sphere radius, m


@dataclass
class Scan:
    """The fields of reconstruct.scans.RangeScan that merging reads."""

    name: str
    points: np.ndarray
    normals: np.ndarray
    sight: np.ndarray
    confidence: np.ndarray
    triangles: np.ndarray
    grid: np.ndarray | None
    origin: np.ndarray


def _look_at(eye, target=(0.0, 0.0, 0.0)) -> np.ndarray:
    """model_from_scan of a scanner at ``eye`` looking at ``target`` (OpenCV frame)."""
    z = np.asarray(target, float) - np.asarray(eye, float)
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0] if abs(z[2]) < 0.9 else [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.stack([x, np.cross(z, x), z], axis=1)
    T[:3, 3] = eye
    return T


def _grid_triangles(grid: np.ndarray) -> np.ndarray:
    a, b, c, d = grid[:-1, :-1], grid[:-1, 1:], grid[1:, :-1], grid[1:, 1:]
    out = []
    for t in ((a, c, b), (b, c, d)):
        ok = (t[0] >= 0) & (t[1] >= 0) & (t[2] >= 0)
        out.append(np.stack([x[ok] for x in t], axis=1))
    return np.concatenate(out)


def render_scan(meshes, model_from_scan, *, size=(120, 160), fov_deg=40.0, name="scan"):
    """A pinhole range scan of open3d meshes: samples, grid triangles (not across depth
    jumps), sight toward the scanner, confidence = cosine to the line of sight."""
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    for m in meshes:
        scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(m))
    H, W = size
    f = 0.5 * W / np.tan(np.radians(fov_deg) / 2)
    jj, ii = np.meshgrid(np.arange(W), np.arange(H))
    d = np.stack([(jj - (W - 1) / 2) / f, (ii - (H - 1) / 2) / f, np.ones((H, W))], -1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    Rm, o = model_from_scan[:3, :3], model_from_scan[:3, 3]
    rays = np.concatenate([np.broadcast_to(o, d.shape), d @ Rm.T], -1)
    hit = scene.cast_rays(o3d.core.Tensor(rays.reshape(-1, 6).astype(np.float32)))
    t = hit["t_hit"].numpy().reshape(H, W).astype(float)
    ok = np.isfinite(t)
    pts = (d * t[..., None])[ok]
    grid = np.full((H, W), -1, np.int64)
    grid[ok] = np.arange(ok.sum())
    n = hit["primitive_normals"].numpy().reshape(H, W, 3)[ok].astype(float) @ Rm
    sight = -pts / np.linalg.norm(pts, axis=1, keepdims=True)
    n[np.einsum("ij,ij->i", n, sight) < 0] *= -1
    tris = _grid_triangles(grid)
    e = np.linalg.norm(pts[tris] - pts[np.roll(tris, 1, axis=1)], axis=2).max(axis=1)
    tris = tris[e < 4.0 * np.linalg.norm(pts[tris[:, 0]], axis=1) / f]
    return Scan(name, pts, n, sight, np.clip(np.einsum("ij,ij->i", n, sight), 0, 1),
                tris.astype(np.int32), grid, np.zeros(3))


def _sphere():
    import open3d as o3d

    return o3d.geometry.TriangleMesh.create_sphere(R, resolution=120)


def _views(directions, distance=0.3):
    out = []
    for v in directions:
        v = np.asarray(v, float)
        out.append(_look_at(distance * v / np.linalg.norm(v)))
    return out


@pytest.fixture(scope="module")
def sphere_scans():
    Ts = _views([(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1),
                 (1, 1, 1), (-1, -1, 1)])
    return [render_scan([_sphere()], T, name=f"s{k}") for k, T in enumerate(Ts)], Ts


@pytest.fixture(scope="module")
def sphere_merged(sphere_scans):
    return {fill: merge_scans(*sphere_scans, MergeOptions(fill_holes=fill))
            for fill in (False, True)}


def test_merged_sphere_lies_on_the_true_radius(sphere_merged):
    mesh, rep = sphere_merged[False]
    r = np.linalg.norm(np.asarray(mesh.vertices), axis=1)
    h = rep["voxel_size"]
    # the scans sample a 120-gon sphere (chord error 4e-6 m << h): the merge itself is
    # what is measured. Marching cubes of a linear-in-voxel field: well within a voxel.
    assert abs(np.mean(r - R)) < 0.02 * h
    assert np.max(np.abs(r - R)) < 0.25 * h
    assert rep["triangles"] > 1000


def test_filled_sphere_is_watertight_and_holds_the_true_volume(sphere_merged):
    mesh, rep = sphere_merged[True]
    assert rep["watertight"] and is_closed(mesh)
    assert mesh.is_edge_manifold() and mesh.is_vertex_manifold()
    v, t = np.asarray(mesh.vertices), np.asarray(mesh.triangles)
    signed = np.einsum("ij,ij->i", v[t[:, 0]], np.cross(v[t[:, 1]], v[t[:, 2]])).sum() / 6
    true = 4 / 3 * np.pi * R ** 3
    # positive: the normals point out; the inscribed 120-gon loses 0.1 % of the volume
    assert signed == pytest.approx(true, rel=0.01)


def test_the_merge_is_deterministic_and_blocks_weld_exactly(sphere_scans):
    a, _ = merge_scans(*sphere_scans, MergeOptions(fill_holes=True))
    b, _ = merge_scans(*sphere_scans, MergeOptions(fill_holes=True))
    assert np.asarray(a.vertices).tobytes() == np.asarray(b.vertices).tobytes()
    assert np.asarray(a.triangles).tobytes() == np.asarray(b.triangles).tobytes()
    # small blocks (many seams) give the very same surface as one block: same vertices
    c, rep = merge_scans(*sphere_scans, MergeOptions(fill_holes=True, block_voxels=16))
    assert rep["blocks"] > 8 and is_closed(c)
    va = np.unique(np.round(np.asarray(a.vertices) / 1e-9).astype(np.int64), axis=0)
    vc = np.unique(np.round(np.asarray(c.vertices) / 1e-9).astype(np.int64), axis=0)
    assert len(a.triangles) == len(c.triangles) and np.array_equal(va, vc)


def test_voxel_size_defaults_to_the_sample_spacing(sphere_scans, sphere_merged):
    scans, _ = sphere_scans
    h = sphere_merged[False][1]["voxel_size"]
    assert h == 0.5 * sample_spacing(scans)   # MergeOptions.voxel_scale
    # a pixel of the 160-px, 40-degree scanner at the sphere's front (0.25 m) is
    # 0.25 * 2 tan(20 deg) / 160 = 1.14 mm; the sphere's slopes stretch it
    assert 1.1e-3 < sample_spacing(scans) < 1.8e-3
    _, rep = merge_scans(scans[:2], sphere_scans[1][:2], MergeOptions(voxel_scale=1.0))
    assert rep["voxel_size"] == sample_spacing(scans[:2])


def _cup():
    """A cup: a 60 x 60 x 10 mm base and four 10 mm walls 40 mm high around a 40 x 40 pit."""
    import open3d as o3d

    def box(lo, hi):
        b = o3d.geometry.TriangleMesh.create_box(*(np.subtract(hi, lo)))
        return b.translate(lo)

    return [box((-0.03, -0.03, -0.03), (0.03, 0.03, -0.02)),
            box((-0.03, -0.03, -0.02), (-0.02, 0.03, 0.02)),
            box((0.02, -0.03, -0.02), (0.03, 0.03, 0.02)),
            box((-0.02, -0.03, -0.02), (0.02, -0.02, 0.02)),
            box((-0.02, 0.02, -0.02), (0.02, 0.03, 0.02))]


@pytest.fixture(scope="module")
def cup_merged():
    # the top view looks into the pit; four side views from 20 degrees up; none below
    Ts = _views([(0.01, 0.0, 1), (1, 0, 0.36), (-1, 0, 0.36), (0, 1, 0.36), (0, -1, 0.36)],
                distance=0.25)
    scans = [render_scan(_cup(), T, size=(160, 160), name=f"c{k}") for k, T in enumerate(Ts)]
    return {fill: merge_scans(scans, Ts, MergeOptions(fill_holes=fill, voxel_size=1e-3))
            for fill in (False, True)}


def test_an_unseen_bottom_closes_only_with_fill_holes(cup_merged):
    open_mesh, rep = cup_merged[False]
    assert not rep["watertight"] and not is_closed(open_mesh)
    closed, rep = cup_merged[True]
    assert rep["watertight"] and is_closed(closed)
    filled = np.asarray(closed.triangle_material_ids) == 1
    assert filled.any() and not filled.all()
    v = np.asarray(closed.vertices)
    # the underside no scan saw is closed where the carving stops: at or below the true
    # bottom (-30 mm), within the volume (its margin is the 4 mm band + 2 voxels)
    assert -0.0365 < v[:, 2].min() < -0.029
    assert rep["fill_fraction"] > 0.05


def test_carved_space_stays_empty_so_the_pit_stays_open(cup_merged):
    for fill in (False, True):
        v = np.asarray(cup_merged[fill][0].vertices)
        h = 1e-3
        inside_pit = ((np.abs(v[:, 0]) < 0.02 - 2 * h) & (np.abs(v[:, 1]) < 0.02 - 2 * h)
                      & (v[:, 2] > -0.02 + 2 * h))
        assert not inside_pit.any(), fill
        floor = (np.abs(v[:, 0]) < 0.01) & (np.abs(v[:, 1]) < 0.01) & (v[:, 2] > -0.025)
        assert floor.any() and np.abs(v[floor, 2] + 0.02).max() < 0.3 * h


def _plane_scan(normal, c, *, size=(60, 80)):
    """A pinhole scan (origin 0) of the plane n.X = c, in the scanner's own frame."""
    import open3d as o3d

    n = np.asarray(normal, float) / np.linalg.norm(normal)
    plane = o3d.geometry.TriangleMesh.create_box(0.4, 0.4, 1e-4).translate((-0.2, -0.2, 0))
    plane.rotate(_look_at(-n)[:3, :3] @ np.diag([1.0, 1.0, 1.0]), center=(0, 0, 0))
    plane.translate(c * n)
    return render_scan([plane], np.eye(4), size=size, fov_deg=30.0), n


def test_signed_distance_against_a_plane_in_closed_form():
    scan, n = _plane_scan((0.3, -0.2, -1.0), -0.2)   # the face toward the scanner
    c = float(n @ scan.points[0])
    rng = np.random.default_rng(4)
    # points along random lines of sight inside the scan (off its border, where the
    # triangles end), from the scanner to past the plane
    inner = scan.grid[2:-2, 2:-2].ravel()
    dirs = scan.points[inner[rng.integers(0, len(inner), 400)]]
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    rng_m = c / (dirs @ n)                         # range to the plane along each line
    offset = rng.uniform(-0.02, 0.02, len(dirs))
    pts = dirs * (rng_m + offset)[:, None]
    h = 1e-3
    d, state, w = scan_signed_distance(scan, np.eye(4), pts, voxel_size=h)
    band = 4 * h
    near = np.abs(offset) <= band * 0.999
    assert np.all(state[near] == OBSERVED)
    # positive in front (toward the scanner), metres along the line of sight
    np.testing.assert_allclose(d[near], -offset[near], atol=1e-6)
    assert np.all(state[offset < -band * 1.001] == EMPTY)
    assert np.all(state[offset > band * 1.001] == UNSEEN)
    # the ramp: full weight up to half the band behind, falling to zero at the band
    behind = near & (offset > 0.75 * band)
    assert np.all(w[behind] < w[near & (offset < 0)].min())


def test_parallel_lines_of_sight_are_recognised_and_exact():
    scan, n = _plane_scan((0.0, 0.4, -1.0), -0.3)
    scan.sight = np.broadcast_to([0.0, 0.0, -1.0], scan.points.shape).copy()
    scan.origin = np.array([0.0, 0.0, -1e3])
    c = float(n @ scan.points[0])
    xy = scan.points[:50, :2]
    z = (c - xy @ n[:2]) / n[2]                     # the plane along +z
    pts = np.column_stack([xy, z - 0.002])          # 2 mm in front, along the sight
    d, state, _ = scan_signed_distance(scan, np.eye(4), pts, voxel_size=1e-3)
    assert np.all(state == OBSERVED)
    np.testing.assert_allclose(d, 0.002, atol=1e-6)


def test_bad_input_names_the_scan_and_field(sphere_scans):
    scans, Ts = sphere_scans
    with pytest.raises(InputError, match="model_from_scans"):
        merge_scans(scans, Ts[:-1])
    bare = Scan("bare.ply", scans[0].points, scans[0].normals, scans[0].sight,
                scans[0].confidence, np.zeros((0, 3), np.int32), None, np.zeros(3))
    with pytest.raises(InputError, match="bare.ply: triangles"):
        merge_scans([bare], Ts[:1])
    with pytest.raises(ValueError, match="voxel_size"):
        MergeOptions(voxel_size=-1.0)


def test_edge_fill_keeps_only_closing_surface_next_to_the_data(sphere_scans, sphere_merged):
    scans, Ts = sphere_scans
    bare, _ = merge_scans(scans, Ts, MergeOptions(edge_fill_voxels=0.0))
    assert not np.any(np.asarray(bare.triangle_material_ids))
    mesh, rep = sphere_merged[False]
    filled = np.asarray(mesh.triangle_material_ids) == 1
    assert len(mesh.triangles) >= len(bare.triangles)
    # what the default adds lies on the data: within a voxel of the true sphere
    v, t = np.asarray(mesh.vertices), np.asarray(mesh.triangles)
    r = np.linalg.norm(v[t[filled]].reshape(-1, 3), axis=1)
    assert np.all(np.abs(r - R) < rep["voxel_size"])


def test_fusing_only_voxels_within_reach_leaves_the_mesh_as_it_was(sphere_scans, sphere_merged,
                                                                    monkeypatch):
    import reconstruct.surface.volumetric as vol

    fused = []
    fuse = vol._fuse

    def counting(points, *args):
        fused.append(len(points))
        return fuse(points, *args)

    monkeypatch.setattr(vol, "_fuse", counting)
    masked, _ = merge_scans(*sphere_scans)
    n_masked = sum(fused)
    monkeypatch.setattr(vol, "_reach_mask", lambda *args: None)
    fused.clear()
    full, _ = merge_scans(*sphere_scans)   # every voxel of the near chunks
    assert sum(fused) > 1.2 * n_masked      # the mask spared work ...
    for a, b in ((masked, full), (masked, sphere_merged[False][0])):   # ... and nothing else
        assert np.asarray(a.vertices).tobytes() == np.asarray(b.vertices).tobytes()
        assert np.asarray(a.triangles).tobytes() == np.asarray(b.triangles).tobytes()
        assert np.array_equal(np.asarray(a.triangle_material_ids),
                              np.asarray(b.triangle_material_ids))
