"""procgen.amplify operators: properties that catch wrong answers."""

import numpy as np
import open3d as o3d
import pytest

from core.meshes import edge_lengths, is_closed, make_mesh, mesh_arrays, surface_area
from procgen.amplify import (
    displace,
    grow_vines,
    hypertexture_mesh,
    refine_terrain,
    scatter_plants,
    subdivide_to_edge,
)
from procgen.amplify.surface import local_edge_length
from procgen.terrain import heightfield_to_mesh


def _ball(res=8):
    return o3d.geometry.TriangleMesh.create_sphere(1.0, res)


def _rng(s=0):
    return np.random.default_rng(s)


def _area(v, f):
    return 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]),
                                axis=1).sum()


def test_subdivision_reaches_the_target_edge_and_keeps_the_surface():
    v, f = mesh_arrays(_ball())
    longest = edge_lengths(v, f).max()
    for target in (longest * 0.9, longest / 3.0, 0.05):
        nv, nf, _, rounds, used = subdivide_to_edge(v, f, target)
        assert used == target and rounds >= 1
        assert edge_lengths(nv, nf).max() <= target
        assert np.array_equal(nv[:len(v)], v)   # old vertices kept, in order
        assert is_closed(nf)
        assert _area(nv, nf) == pytest.approx(_area(v, f), rel=1e-12)  # nothing moved
        # orientation kept: every new triangle faces out of the ball as its parent did
        c = nv[nf].mean(axis=1)
        n = np.cross(nv[nf[:, 1]] - nv[nf[:, 0]], nv[nf[:, 2]] - nv[nf[:, 0]])
        assert np.all(np.einsum("ij,ij->i", c, n) > 0)


def test_subdivision_splits_only_the_long_edges():
    """A fine part and a coarse part: the fine part's triangles stay as they are, and the
    whole needs far fewer triangles than uniform midpoint levels would make."""
    from core.meshes import merge_meshes

    fine = _ball(8).subdivide_midpoint(3).translate((3.0, 0.0, 0.0))
    coarse = _ball(8)
    v, f = mesh_arrays(merge_meshes([fine, coarse]))
    n_fine = len(fine.triangles)
    target = edge_lengths(*mesh_arrays(fine)).max() * 1.01
    nv, nf, _, rounds, _ = subdivide_to_edge(v, f, target)
    assert edge_lengths(nv, nf).max() <= target
    kept = nf[np.all(nf < len(v), axis=1)]
    assert len(kept) >= n_fine     # no fine triangle was touched
    uniform = len(f) * 4 ** int(np.ceil(np.log2(edge_lengths(v, f).max() / target)))
    assert len(nf) < 0.5 * uniform


def test_subdivision_meets_the_triangle_budget_by_lengthening_the_target():
    v, f = mesh_arrays(_ball())
    nv, nf, _, _, used = subdivide_to_edge(v, f, 0.001, max_triangles=5000)
    assert len(nf) <= 5000 and used > 0.001
    assert edge_lengths(nv, nf).max() <= used
    # and the budget was used, not wasted: a quarter of it at least
    assert len(nf) > 5000 / 4


@pytest.mark.parametrize("noise", ["fbm", "turbulence", "ridged"])
def test_displacement_is_along_normals_with_the_stated_rms(noise):
    res = displace(_ball(), rng=_rng(1), target_edge=0.2, noise=noise, amplitude=0.3)
    out, _ = mesh_arrays(res.mesh)
    moved = out - res.base_vertices
    # along the normal only: the move is offset * normal, nothing tangential
    np.testing.assert_allclose(moved, res.offset[:, None] * res.normals, atol=1e-13)
    np.testing.assert_allclose(np.linalg.norm(res.normals, axis=1), 1.0, atol=1e-12)
    # the stated amplitude: RMS of offset / local scale
    assert res.rms_relative == pytest.approx(0.3, rel=1e-12)
    assert np.std(res.offset) > 0
    assert res.max_edge <= 0.2


def test_local_scale_is_the_input_edge_length_interpolated():
    mesh = _ball()
    v, f = mesh_arrays(mesh)
    h0 = local_edge_length(v, f)
    res = displace(mesh, rng=_rng(), target_edge=0.3, amplitude=0.1)
    np.testing.assert_array_equal(res.scale[:len(v)], h0)
    assert res.scale.min() >= h0.min() - 1e-12 and res.scale.max() <= h0.max() + 1e-12
    glob = displace(mesh, rng=_rng(), amplitude=0.1, scale="global")
    np.testing.assert_allclose(glob.scale, np.linalg.norm(v.max(0) - v.min(0)))


def test_zero_mask_leaves_the_mesh_unchanged():
    plane = heightfield_to_mesh(np.zeros((6, 6)), spacing=0.2)
    v, f = mesh_arrays(plane)
    # slope 0 everywhere, the mask ramps from 60 to 80 degrees: zero
    res = displace(plane, rng=_rng(), mask="slope", mask_range=(60.0, 80.0), amplitude=2.0)
    out, of = mesh_arrays(res.mesh)
    assert np.array_equal(out, v) and np.array_equal(of, f)
    res = displace(plane, rng=_rng(), target_edge=0.1, mask="curvature",
                   mask_range=(0.5, 1.0), amplitude=2.0)
    out, _ = mesh_arrays(res.mesh)
    assert np.array_equal(out, res.base_vertices) and len(out) > len(v)
    # inverted, the same mask is one: everything moves
    res = displace(plane, rng=_rng(), mask="slope", mask_range=(60.0, 80.0), invert_mask=True)
    assert np.all(res.mask == 1.0) and res.rms_relative == pytest.approx(0.25)


def test_slope_mask_moves_only_steep_faces():
    x = np.linspace(0, 4, 21)
    z = np.tile(np.maximum(0.0, x - 2.0) * 2.0, (5, 1))      # flat, then a 63 degree ramp
    mesh = heightfield_to_mesh(z, spacing=(0.2, 0.25))
    res = displace(mesh, rng=_rng(), mask="slope", mask_range=(30.0, 45.0))
    v, _ = mesh_arrays(mesh)
    flat = v[:, 0] < 1.9
    steep = v[:, 0] > 2.1
    assert np.all(res.offset[flat] == 0.0)
    assert np.all(res.mask[steep] == 1.0) and np.any(res.offset[steep] != 0.0)


def test_constrained_diamond_square_keeps_every_control_sample():
    rng = _rng(3)
    coarse = rng.normal(size=(17, 17)) * 0.2
    mesh = heightfield_to_mesh(coarse, spacing=0.25)
    res = refine_terrain(mesh, rng=_rng(4), control_size=17, levels=3, hurst=0.7)
    D = 2 ** 3
    assert res.heights.shape == (16 * D + 1, 16 * D + 1)
    assert np.array_equal(res.heights[::D, ::D], res.control)
    # the control grid is aligned with the input vertices: it is their heights
    np.testing.assert_allclose(res.control, coarse, atol=1e-5)
    assert res.valid.all()
    v, _ = mesh_arrays(res.mesh)
    grid_z = v[:, 2].reshape(res.heights.shape)
    assert np.array_equal(grid_z, res.heights)
    assert np.std(res.heights - np.kron(res.control, np.ones((D, D)))[:129, :129]) > 0


def test_refine_terrain_erodes_a_reconstructed_ground():
    """Erosion after refinement: the pits of the fractal detail drain away."""
    from procgen.terrain.metrics import pit_share

    coarse = _rng(3).normal(size=(17, 17)) * 0.2
    mesh = heightfield_to_mesh(coarse, spacing=0.25)
    plain = refine_terrain(mesh, rng=_rng(4), control_size=17, levels=2)
    eroded = refine_terrain(mesh, rng=_rng(4), control_size=17, levels=2,
                            erosion="stream-power")
    assert pit_share(plain.heights) > 0.01 and pit_share(eroded.heights) <= 0.002
    v, _ = mesh_arrays(eroded.mesh)
    assert np.array_equal(v[:, 2].reshape(eroded.heights.shape), eroded.heights)
    with pytest.raises(ValueError, match="erosion"):
        refine_terrain(mesh, rng=_rng(4), control_size=17, levels=1, erosion="wind")


def test_refine_terrain_trims_to_the_footprint():
    ball = _ball(12)
    res = refine_terrain(ball, rng=_rng(), control_size=9, levels=1)
    assert not res.valid.all() and res.valid.any()
    v, _ = mesh_arrays(res.mesh)
    assert np.all(np.linalg.norm(v[:, :2], axis=1) < 1.0 + 1e-9)


def _ramp_mesh():
    """4 m x 2 m: flat for x < 2, a 45 degree ramp beyond (area 4 + 4 sqrt 2)."""
    x = np.linspace(0, 4, 41)
    z = np.tile(np.maximum(0.0, x - 2.0), (21, 1))
    return heightfield_to_mesh(z, spacing=(0.1, 0.1))


def test_scatter_count_follows_density_times_area():
    plane = heightfield_to_mesh(np.zeros((5, 5)), spacing=1.0)     # 16 m^2
    counts = [len(scatter_plants(plane, rng=_rng(s), density=3.0, height=0.3,
                                 variants=2).positions) for s in range(4)]
    mean = 16 * 3.0
    assert all(abs(c - mean) < 4 * np.sqrt(mean) for c in counts)
    assert abs(np.mean(counts) - mean) < 4 * np.sqrt(mean / 4)


def test_scatter_respects_slope_and_altitude_rules():
    mesh = _ramp_mesh()
    res = scatter_plants(mesh, rng=_rng(1), density=20.0, slope_max_deg=30.0, height=0.2)
    assert len(res.positions) > 40
    assert np.all(res.positions[:, 0] <= 2.0 + 1e-9)         # nothing on the 45 degree ramp
    assert res.eligible_area == pytest.approx(4.0)
    mean = 20.0 * 4.0
    assert abs(len(res.positions) - mean) < 4 * np.sqrt(mean)
    res = scatter_plants(mesh, rng=_rng(2), density=20.0, slope_max_deg=90.0,
                         altitude_range=(0.5, 1.0), height=0.2)
    z = res.positions[:, 2]
    assert np.all(z >= 1.0 - 1e-9)                           # half of the 2 m altitude range
    mean = 20.0 * 2.0 * np.sqrt(2.0)                         # the upper half of the ramp
    assert abs(len(z) - mean) < 4 * np.sqrt(mean)
    # plants stand on their points and reach about their height
    pv, _ = mesh_arrays(res.mesh)
    assert pv[:, 2].max() <= z.max() + 0.2 * 1.3 + 1e-9


def test_scatter_altitude_ignores_stray_fragments_and_floor_plants():
    from core.meshes import merge_meshes

    ground = heightfield_to_mesh(np.zeros((11, 11)), spacing=0.1)          # 1 m^2 at z = 0
    # a stray 1 cm^2 fragment 10 m below (a reconstruction artefact): it must not make
    # the whole ground "high" for the altitude rule
    stray = heightfield_to_mesh(np.zeros((2, 2)), spacing=0.1).translate((0, 0, -10.0))
    mesh = merge_meshes([ground, stray])
    res = scatter_plants(mesh, rng=_rng(3), density=50.0, altitude_range=(0.0, 0.25),
                         height=0.05, variants=1)
    assert len(res.positions) > 20 and np.all(res.positions[:, 2] == 0.0)
    # the floor: a density expecting ~0.05 plants still plants min_plants on eligible ground
    res = scatter_plants(ground, rng=_rng(4), density=0.05, min_plants=3, height=0.05,
                         variants=1)
    assert len(res.positions) == 3 and res.candidates > 0
    # ... but never on ground the rules exclude
    res = scatter_plants(_ramp_mesh(), rng=_rng(5), density=0.01, min_plants=3,
                         slope_max_deg=10.0, altitude_range=(0.6, 1.0), height=0.05)
    assert len(res.positions) == 0


def test_scatter_grows_varied_plants_from_one_grammar():
    plane = heightfield_to_mesh(np.zeros((3, 3)), spacing=1.0)
    res = scatter_plants(plane, rng=_rng(5), density=10.0, variants=4, height=0.5)
    assert len(np.unique(res.variant)) > 1
    from procgen.amplify import grow_variants

    shapes = grow_variants(rng=_rng(6), variants=4)
    sizes = {len(v) for v, _, _ in shapes}
    assert len(sizes) > 1                                    # the seeds give different plants
    for v, f, leaf in shapes:
        assert v[:, 2].min() == pytest.approx(0.0) and v[:, 2].max() == pytest.approx(1.0)
        assert 0 < leaf.sum() < len(v)                       # bark and leaves
        assert np.all(leaf[f].all(axis=1) | ~leaf[f].any(axis=1))   # no mixed triangle
    assert len(res.leaf) == len(res.mesh.vertices) and res.leaf.any()


def test_tip_leaves_sit_on_the_tips_at_45_degrees():
    from procgen.amplify.plants import tip_leaves

    # a trunk (0) with two children (1, 2): only 1 and 2 are tips
    starts = np.array([[0, 0, 0], [0, 0, 1], [0, 0, 1]], float)
    ends = np.array([[0, 0, 1], [0, 1, 2], [1, 0, 1]], float)
    v, f = tip_leaves(starts, ends, np.array([-1, 0, 0]), count=3, size=0.2)
    assert v.shape == (2 * 3 * 4, 3) and f.shape == (2 * 3 * 4, 3)
    blades = v.reshape(2, 3, 4, 3)
    assert np.allclose(blades[0, :, 0], ends[1]) and np.allclose(blades[1, :, 0], ends[2])
    axis = blades[:, :, 2] - blades[:, :, 0]                 # base to tip of each blade
    assert np.allclose(np.linalg.norm(axis, axis=-1), 0.2)
    h = (ends[1:] - starts[1:]) / np.linalg.norm(ends[1:] - starts[1:], axis=1)[:, None]
    cos = np.einsum("tkc,tc->tk", axis / 0.2, h)
    assert np.allclose(cos, np.cos(np.radians(45.0)))


def test_vines_walk_on_the_surface():
    ball = _ball(30)
    res = grow_vines(ball, rng=_rng(2), count=4, length=1.5, step=0.05, radius=0.01)
    for P in res.paths:
        r = np.linalg.norm(P, axis=1)
        assert np.all(np.abs(r - 1.0) < 0.01)               # on the faceted unit sphere
        seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
        assert seg.max() <= 0.05 + 1e-6 and seg.sum() > 0.5 * 1.5
    v, f = mesh_arrays(res.mesh)
    assert len(f) and np.all(np.abs(np.linalg.norm(v, axis=1) - 1.0) < 0.03)


def test_hypertexture_with_zero_amplitude_reproduces_the_surface():
    from reconstruct.evaluation.evaluate import evaluate

    ball = _ball(20)
    res = hypertexture_mesh(ball, rng=_rng(), amplitude=0.0, resolution=32)
    ev = evaluate(res.mesh, ball, tau=res.voxel)
    assert ev.accuracy_mean < 0.25 * res.voxel and ev.completeness_mean < 0.25 * res.voxel
    v, _ = mesh_arrays(res.mesh)
    r = np.linalg.norm(v, axis=1)
    assert np.all(np.abs(r - 1.0) < res.voxel)
    assert ev.fscore > 0.99
    rough = hypertexture_mesh(ball, rng=_rng(), amplitude=0.1, resolution=32)
    r2 = np.linalg.norm(mesh_arrays(rough.mesh)[0], axis=1)
    assert r2.max() > 1.0 + 0.05                             # turbulence pushes outward


def test_hypertexture_gives_an_open_mesh_a_shell_instead_of_refusing():
    """An open hemisphere: the result is closed, hugs the input within the shell's
    half-width (plus a voxel of marching cubes), and covers all of it."""
    from procgen.amplify.hyper import SHELL_VOXELS
    from reconstruct.evaluation.evaluate import evaluate

    ball = _ball(24)
    v, f = mesh_arrays(ball)
    keep = np.all(v[f][:, :, 2] > -1e-9, axis=1)
    dome = make_mesh(v, f[keep])
    res = hypertexture_mesh(dome, rng=_rng(), amplitude=0.0, resolution=40)
    assert res.inside == "shell"
    out, of = mesh_arrays(res.mesh)
    assert is_closed(of)
    ev = evaluate(res.mesh, dome, tau=(SHELL_VOXELS + 1.0) * res.voxel, distance="surface")
    assert ev.precision > 0.99 and ev.recall > 0.99
    closed = hypertexture_mesh(ball, rng=_rng(), amplitude=0.0, resolution=24)
    assert closed.inside == "mesh"


def test_bad_arguments_name_themselves():
    ball = _ball()
    with pytest.raises(ValueError, match="noise"):
        displace(ball, rng=_rng(), noise="worley")
    with pytest.raises(ValueError, match="rng"):
        displace(ball, rng=0)
    with pytest.raises(ValueError, match="target_edge"):
        displace(ball, rng=_rng(), target_edge=-1.0)
    with pytest.raises(ValueError, match="max_triangles"):  # fewer than the input has
        displace(ball, rng=_rng(), target_edge=0.1, max_triangles=10)
    with pytest.raises(ValueError, match="altitude_range"):
        scatter_plants(ball, rng=_rng(), altitude_range=(0.8, 0.2))
    with pytest.raises(ValueError, match="mesh"):
        displace(make_mesh(np.zeros((3, 3)), np.zeros((0, 3), int)), rng=_rng())
    assert surface_area(*mesh_arrays(ball)).sum() > 0


def test_snow_lies_only_where_the_sky_is_seen_and_thickens_on_level_ground():
    """A ground with a roof over part of it: nothing under the roof, nothing steeper than
    the limit; depth never decreases as the surface levels (no drift); every snow vertex's
    upward ray leaves the mesh."""
    from core.meshes import merge_meshes, vertex_normals
    from procgen.amplify import snow_cover

    x = np.linspace(-1, 1, 41)
    hf = 0.4 * np.sin(2 * x)[:, None] * np.ones_like(x)[None, :]   # slopes of 0..39 deg
    ground = heightfield_to_mesh(hf, spacing=0.05)
    gv, gf = mesh_arrays(ground)
    gv = gv - [gv[:, 0].mean(), gv[:, 1].mean(), 0.0]
    roof = o3d.geometry.TriangleMesh.create_box(0.6, 0.6, 0.02).translate((-0.3, -0.3, 1.0))
    mesh = merge_meshes([make_mesh(gv, gf), roof])
    res = snow_cover(mesh, rng=_rng(), depth=0.05, slope_max_deg=30.0, drift=0.0)
    v, f = mesh_arrays(mesh)
    g = np.arange(len(gv))                                    # the ground's vertices
    under = (np.abs(v[g, 0]) < 0.29) & (np.abs(v[g, 1]) < 0.29)
    assert res.depth[g][under].max() == 0.0                   # sheltered by the roof
    n = vertex_normals(v, f)
    slope = np.degrees(np.arccos(np.clip(n[:, 2], -1, 1)))
    assert res.depth[slope >= 30.0].max() == 0.0
    open_ = g[~under & (slope[g] < 25.0)]
    assert len(open_) > 100 and np.all(res.depth[open_] > 0)
    # non-decreasing in n.z among the vertices that see the sky
    seen = np.flatnonzero(res.sky)
    order = seen[np.argsort(n[seen, 2], kind="stable")]
    assert np.all(np.diff(res.depth[order]) >= -1e-12)
    # every vertex of the layer: its upward ray leaves the scene without hitting it
    sv, _ = mesh_arrays(res.mesh)
    assert _sky_seen(mesh, sv).all()


def _sky_seen(mesh, points):
    rs = o3d.t.geometry.RaycastingScene()
    rs.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(mesh))
    rays = np.hstack([points + [0, 0, 1e-6], np.tile([0.0, 0.0, 1.0], (len(points), 1))])
    return ~rs.test_occlusions(o3d.core.Tensor(rays.astype(np.float32))).numpy().astype(bool)


def test_plants_need_the_sky_and_a_gentle_slope():
    """A level ground half under a roof: no root under the roof (its upward ray would hit
    it), none on the roof's vertical sides, every root on the surface."""
    from core.meshes import merge_meshes

    ground = heightfield_to_mesh(np.zeros((21, 21)), spacing=0.1)           # 2 m x 2 m
    roof = o3d.geometry.TriangleMesh.create_box(1.0, 2.0, 0.05).translate((0.0, 0.0, 0.6))
    mesh = merge_meshes([ground, roof])
    res = scatter_plants(mesh, rng=_rng(), density=20.0, height=0.1, slope_max_deg=30.0,
                         variants=1, max_plants=1000)
    p = res.positions
    on_ground = p[:, 2] < 0.3
    assert on_ground.sum() > 10 and (~on_ground).sum() > 3      # ground and roof top
    assert np.all(p[on_ground, 0] > 1.0 - 1e-9)                   # none under the roof
    assert np.allclose(p[~on_ground, 2], 0.65)                    # the roof's top, level
    free = scatter_plants(mesh, rng=_rng(), density=20.0, height=0.1, slope_max_deg=30.0,
                          variants=1, max_plants=1000, need_sky=False)
    assert np.any((free.positions[:, 2] < 0.3) & (free.positions[:, 0] < 1.0))


@pytest.mark.parametrize("hurst", [0.5, 0.8])
def test_displacement_detail_has_the_recipes_hurst_exponent(hurst):
    """fBm displacement of a flat grid: the offsets' variogram over the middle octaves
    grows as r**(2H) with H within 0.1 of the one asked for; smoothed over the first
    octave's wavelength, the surface stays within 0.5 % of the diagonal of the input."""
    from scipy.ndimage import uniform_filter

    n = 480
    plane = heightfield_to_mesh(np.zeros((n, n)), spacing=1.0)
    res = displace(plane, rng=_rng(2), noise="fbm", amplitude=0.3, wavelength=300.0,
                   octaves=10, hurst=hurst)
    z = res.offset.reshape(n, n)
    rs = np.array([2, 4, 8, 16, 32])
    g = [np.mean((z[:, r:] - z[:, :-r]) ** 2) + np.mean((z[r:, :] - z[:-r, :]) ** 2)
         for r in rs]
    h_est = np.polyfit(np.log(rs), np.log(g), 1)[0] / 2
    assert abs(h_est - hurst) < 0.1, h_est
    lam = int(300 * float(np.mean(res.scale)))   # first-octave wavelength, in grid steps
    smooth = uniform_filter(z, size=min(lam, n), mode="reflect")
    assert np.abs(smooth).max() < 0.005 * np.sqrt(2) * (n - 1)


def test_a_vine_walk_that_bounces_back_still_sweeps():
    """A walk that steps off and straight back (a crease) has a zero central-difference
    tangent there: the turning point goes, the tube is built (the monstree mesh failed so)."""
    from procgen.amplify.vines import _untangled
    from procgen.sweeps import sweep

    p = np.array([[0, 0, 0], [1, 0, 0], [0, 0, 0], [0, 1, 0], [0, 1, 0], [0, 2, 0.0]])
    q = _untangled(p, 1e-6)
    np.testing.assert_array_equal(q, [[0, 0, 0], [0, 1, 0], [0, 2, 0]])
    with pytest.raises(ValueError, match="repeated points"):
        sweep(np.array([[1.0, 0], [0, 1], [-1, 0]]), p[:3])
    v, f = sweep(np.array([[1.0, 0], [0, 1], [-1, 0]]) * 0.1, q)
    assert len(f) > 0


def test_vines_start_on_walls_and_climb():
    """A tall box on a ground: walks started on slopes of 60 degrees and more begin on
    the box's sides and, leaning toward up, end higher than they began; without walls to
    start on they start anywhere instead of failing."""
    from core.meshes import merge_meshes
    from procgen.amplify import surface_walks

    ground = heightfield_to_mesh(np.zeros((11, 11)), spacing=0.4)         # 4 m x 4 m
    tower = o3d.geometry.TriangleMesh.create_box(0.6, 0.6, 2.0).translate((1.7, 1.7, 0.0))
    tower = tower.subdivide_midpoint(3)
    mesh = merge_meshes([ground, tower])
    paths, normals = surface_walks(mesh, rng=_rng(), count=20, length=1.0, step=0.05,
                                   slope_min_deg=60.0, climb=0.8)
    starts = np.array([p[0] for p in paths])
    n0 = np.array([n[0] for n in normals])
    assert np.all(np.abs(n0[:, 2]) < 0.5)                         # on the walls
    rise = np.array([p[-1, 2] - p[0, 2] for p in paths])
    assert np.median(rise) > 0.5 and np.all(starts[:, 2] >= 0.0)
    flat, _ = surface_walks(ground, rng=_rng(), count=3, length=0.5, step=0.05,
                            slope_min_deg=60.0)
    assert len(flat) == 3
