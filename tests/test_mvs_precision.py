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
