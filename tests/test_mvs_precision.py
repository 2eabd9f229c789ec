"""Precision of the dense surface: masks drawn against a mesh, what the views saw, the
truth-free precision, and the trim of Poisson vertices that the views looked through."""

import numpy as np
import pytest

from acquire.camera import Camera


def _ring(n=8, size=(160, 120), radius=0.6, height=0.25, target=(0.0, 0.0, 0.06)):
    cams = []
    for k in range(n):
        a = 2 * np.pi * k / n
        eye = [radius * np.cos(a), radius * np.sin(a), height]
        cams.append(Camera.look_at(eye, list(target), width=size[0], height=size[1],
                                   fov_deg=40.0))
    return cams


def _columns():
    """Two upright boxes 4 cm apart (the truth), as an open3d mesh."""
    import open3d as o3d

    mesh = o3d.geometry.TriangleMesh()
    for x in (-0.03, 0.03):
        b = o3d.geometry.TriangleMesh.create_box(0.012, 0.012, 0.12)
        b.translate((x - 0.006, -0.006, 0.0))
        mesh += b
    return mesh


def _fin():
    """A thin slab bridging the gap between the two columns (what Poisson leaves)."""
    import open3d as o3d

    b = o3d.geometry.TriangleMesh.create_box(0.048, 0.002, 0.08)
    b.translate((-0.024, -0.001, 0.02))
    return b


def test_mask_scores_of_a_mesh_against_its_own_silhouettes_and_half_of_them():
    from reconstruct.evaluation.masks import mask_scores, mesh_hits

    cams = _ring(4)
    mesh = _columns()
    sil = mesh_hits(mesh, cams)
    assert all(s.any() for s in sil)
    full = mask_scores(mesh, cams, sil)
    assert full.mean_inside == 1.0 and full.mean_covers == 1.0
    # keep only the left half of each silhouette: inside is the left half's share
    halves = []
    for s in sil:
        h = s.copy()
        cols = np.nonzero(s.any(0))[0]
        h[:, (cols.min() + cols.max()) // 2:] = False
        halves.append(h)
    half = mask_scores(mesh, cams, halves)
    expect = np.mean([h.sum() / s.sum() for h, s in zip(halves, sil, strict=True)])
    assert half.mean_inside == pytest.approx(expect, abs=1e-12)
    assert half.mean_covers == 1.0
    with pytest.raises(ValueError, match="masks"):
        mask_scores(mesh, cams, sil[:2])


def test_truth_free_precision_drops_when_a_fin_is_added():
    """What the views saw: each view's pixels of the two columns (as if every one of them
    had a fused depth). The columns' own mesh lies on them; with a fin between the
    columns it does not,
    and the truth-free precision says so: it falls by at least half the fin's drawn share
    (the rest lies within the 3 px the seen pixels are grown by, or over a column)."""
    from reconstruct.evaluation.masks import mesh_hits
    from reconstruct.mvs.precision import seen_masks, seen_precision

    cams = _ring(8, size=(320, 240))
    truth = _columns()
    seen = seen_masks(mesh_hits(truth, cams), grow=1)
    good = seen_precision(truth, cams, seen)
    assert good.mean_inside > 0.99
    finned = truth + _fin()
    bad = seen_precision(finned, cams, seen)
    drawn_fin = np.mean([(f & ~t).sum() / f.sum() for f, t in
                         zip(mesh_hits(finned, cams), mesh_hits(truth, cams), strict=True)])
    assert drawn_fin > 0.1  # the fin is a real share of the drawn mesh
    assert bad.mean_inside < good.mean_inside - 0.5 * drawn_fin


def test_unseen_votes_count_the_views_that_saw_nothing_at_a_vertex():
    from reconstruct.evaluation.masks import mesh_hits
    from reconstruct.mvs.precision import seen_masks, unseen_votes

    cams = _ring(8)
    truth = _columns()
    seen = seen_masks(mesh_hits(truth, cams), grow=1)
    on = np.array([[-0.03 + 0.006, 0.0, 0.06], [0.03, 0.006, 0.06]])  # column faces
    gap = np.array([[0.0, 0.0, 0.06]])  # between the columns: background in most views
    assert unseen_votes(on, cams, seen).max() == 0
    # the gap point is hidden behind a column in at most the two views along the x axis
    assert unseen_votes(gap, cams, seen)[0] >= 6
    with pytest.raises(ValueError, match="vertices"):
        unseen_votes(np.zeros((3, 2)), cams, seen)
    with pytest.raises(ValueError, match=r"confirmed\[0\]"):
        seen_masks([np.zeros(5, bool)])


# -- the unseen trim on a fused cloud with a fin ------------------------------------------------

def _depth_maps(mesh, cams):
    """Each view's true z-depth of the mesh (0 on the backdrop), float32."""
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(mesh))
    out = []
    for c in cams:
        rays = o3d.t.geometry.RaycastingScene.create_rays_pinhole(
            o3d.core.Tensor(c.K), o3d.core.Tensor(c.cam_from_world), c.width, c.height)
        t = scene.cast_rays(rays)["t_hit"].numpy()
        # t is the range along a unit ray; z-depth is its z component in the camera
        u, v = np.meshgrid(np.arange(c.width), np.arange(c.height))
        d = np.stack([(u - c.cx) / c.fx, (v - c.cy) / c.fy, np.ones_like(u, float)], -1)
        z = t / np.linalg.norm(d, axis=-1)
        out.append(np.where(np.isfinite(z), z, 0.0).astype(np.float32))
    return out


def _cloud(mesh, n, rng):
    from core.sampling import sample_surface

    return sample_surface(np.asarray(mesh.vertices), np.asarray(mesh.triangles), n, rng=rng)


def test_a_fin_of_fused_points_over_the_backdrop_is_trimmed():
    """Two columns seen by a ring of 8 views on a black backdrop, and a fin of fused points
    between them (what a window fattening both columns, in two views that agree, leaves).
    Every view's depth map is the truth: no plane on the backdrop. Without the unseen trim
    the fin stays in the mesh, which leaves the true silhouettes (inside < 0.97); with it
    (2 views: the fin faces two of the eight, the diagonal views see it partly over a
    column) the fin goes, the mesh stays inside (>= 0.985) and covers the columns as much
    as the columns' own points do (within 0.02). The truth-free precision rises with it."""
    from reconstruct.evaluation.masks import mask_scores, mesh_hits
    from reconstruct.mvs.fusion import FusedPoints, FusionOptions, poisson_surface
    from reconstruct.mvs.precision import seen_masks, seen_precision

    rng = np.random.default_rng(0)
    cams = _ring(8, size=(320, 240))
    truth = _columns()
    depths = _depth_maps(truth, cams)
    p1, n1 = _cloud(truth, 60000, rng)
    p2, n2 = _cloud(_fin(), 15000, rng)
    pts, nrm = np.vstack([p1, p2]), np.vstack([n1, n2])
    fused = FusedPoints(pts, nrm, np.full(pts.shape, 0.5), np.ones(len(pts), np.int32), [])
    confirmed = [d > 0 for d in depths]
    sil = mesh_hits(truth, cams)
    seen = seen_masks(confirmed, grow=3)
    got = {}
    for k in (0, 2):
        mesh = poisson_surface(fused, cams, depths, FusionOptions(unseen_views=k),
                               confirmed=confirmed)
        got[k] = (mask_scores(mesh, cams, sil, dilate=2),
                  seen_precision(mesh, cams, seen).mean_inside)
    assert got[0][0].mean_inside < 0.97  # the fins case: fails without the trim
    assert got[2][0].mean_inside >= 0.985  # and holds with it
    # covered as much as the columns' own points cover them (the fin, drawn over the
    # columns in the diagonal views, adds coverage that is not the columns')
    alone = FusedPoints(p1, n1, np.full(p1.shape, 0.5), np.ones(len(p1), np.int32), [])
    ref = mask_scores(poisson_surface(alone, cams, depths, FusionOptions(),
                                      confirmed=confirmed), cams, sil, dilate=2)
    assert got[2][0].mean_covers >= ref.mean_covers - 0.02
    assert got[2][1] > got[0][1] + 0.02


# -- a pattern fixed to the image (a backdrop behind a turntable) -------------------------------

def _phantom(ci, cj, px):
    """Points X of pixels ``px`` of ``ci`` that fall in ``cj`` at the point of the epipolar
    line nearest to the same pixel: where a pattern at the same pixels of both views
    matches itself (found by a search along each ray)."""
    z = np.linspace(0.2, 1.2, 4001)
    out = []
    for u, v in px:
        ray = np.stack([(u - ci.cx) / ci.fx * z, (v - ci.cy) / ci.fy * z, z], 1)
        X = ray @ ci.world_from_cam[:3, :3].T + ci.world_from_cam[:3, 3]
        Y = cj.to_camera(X)
        d = np.hypot(cj.fx * Y[:, 0] / Y[:, 2] + cj.cx - u, cj.fy * Y[:, 1] / Y[:, 2] + cj.cy - v)
        out.append(X[int(np.argmin(d))])
    return np.array(out)


def test_a_match_at_the_same_pixel_does_not_confirm_a_depth():
    """Two neighbouring views of a ring see the true columns and, on the backdrop, a
    pattern fixed to the image (a cloth behind a turntable): the pattern matches itself
    at the same pixels, and the depths it gives agree between the two views at points
    beside the columns that are in no scene. With ``static_match`` those agreements do not
    count (no backdrop pixel is fused), while the columns' depths are confirmed as
    before; the compiled test and the vectorised one (``disparity_tol``) agree."""
    from reconstruct.mvs.fusion import FusionOptions, fuse_points

    cams = _ring(16, size=(160, 120))
    ci, cj = cams[0], cams[1]
    depths = _depth_maps(_columns(), cams[:2])
    rng = np.random.default_rng(1)
    bg = np.argwhere(depths[0] == 0)[:, ::-1]
    px = bg[rng.choice(len(bg), 300, replace=False)].astype(float)
    X = _phantom(ci, cj, px)
    # a surface in front of each view where its pixels see the pattern
    for cam, d, P in ((ci, depths[0], X), (cj, depths[1], X)):
        Y = cam.to_camera(P)
        u = np.rint(cam.fx * Y[:, 0] / Y[:, 2] + cam.cx).astype(int)
        v = np.rint(cam.fy * Y[:, 1] / Y[:, 2] + cam.cy).astype(int)
        ok = (u >= 0) & (v >= 0) & (u < cam.width) & (v < cam.height)
        ok &= d[v.clip(0, cam.height - 1), u.clip(0, cam.width - 1)] == 0
        d[v[ok], u[ok]] = Y[ok, 2]
    up = np.array([0.0, 0.0, 1.0])  # one world normal, in each camera's frame
    normals = [np.broadcast_to(c.cam_from_world[:3, :3] @ up, (*d.shape, 3)).astype(np.float32)
               for c, d in zip(cams[:2], depths, strict=True)]
    colors = [np.zeros((*d.shape, 3), np.uint8) for d in depths]
    on_bg = depths[0] > 0
    on_bg &= _depth_maps(_columns(), cams[:1])[0] == 0
    res = {}
    for static in (0.0, 1.0):
        for dt in (0.0, 1e6):  # compiled (relative depth) and vectorised (disparity) tests
            opt = FusionOptions(static_match=static, disparity_tol=dt, edge_erosion=0,
                                max_normal_deg=180.0)
            res[static, dt] = fuse_points(cams[:2], depths, normals, colors, [[1], [0]],
                                          opt).masks[0]
    cols = depths[0] > 0
    cols &= ~on_bg
    for dt in (0.0, 1e6):
        assert res[0.0, dt][on_bg].mean() > 0.8  # the pattern's depths are fused without
        assert res[1.0, dt][on_bg].mean() < 0.02  # and not with the test
        # the columns: as many confirmed as before (within 1 %)
        assert res[1.0, dt][cols].sum() >= 0.99 * res[0.0, dt][cols].sum()
        assert res[0.0, dt][cols].mean() > 0.5
