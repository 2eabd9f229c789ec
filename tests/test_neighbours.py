import numpy as np
import pytest

from simulate.neighbours import build_grid, neighbour_lists, neighbour_lists_reference, threads_for


def _same(a, b):
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])


@pytest.mark.parametrize("n,radius", [(1, 1.0), (2, 0.1), (700, 0.8), (1500, 2.5)])
def test_grid_lists_equal_all_pairs(rng, n, radius):
    pts = rng.uniform(-5, 5, (n, 3))
    _same(neighbour_lists(pts, radius), neighbour_lists_reference(pts, radius))


def test_clustered_duplicates_and_parallel_path(rng):
    # clusters, exact duplicates (distance 0 is a neighbour) and enough points for threads
    centres = rng.uniform(-20, 20, (30, 3))
    pts = centres[rng.integers(0, 30, 5000)] + rng.normal(0, 0.3, (5000, 3))
    pts[:50] = pts[50:100]
    a = neighbour_lists(pts, 0.5)
    _same(a, neighbour_lists_reference(pts, 0.5))
    off, idx = a
    assert 50 in idx[off[0]:off[1]]  # a duplicate is found
    with threads_for(10):  # the one-thread path gives the same lists
        _same(neighbour_lists(pts, 0.5), a)


def test_far_outlier_grows_cells_and_stays_exact(rng):
    pts = np.vstack([rng.uniform(0, 1, (200, 3)), [[1e6, 0, 0]]])
    g = build_grid(pts, 0.1)
    assert g.cell_size >= 0.1 and int(np.prod(g.dims)) <= max(8 * len(pts), 1 << 15)
    _same(neighbour_lists(pts, 0.1, grid=g), neighbour_lists_reference(pts, 0.1))


def test_huge_spread_does_not_overflow_the_cell_count(rng):
    # (1e12 / 1e-3)^3 cells would overflow int64: the count is taken in floats
    pts = np.vstack([rng.uniform(0, 1e-2, (50, 3)), [[1e12, 1e12, 1e12]]])
    g = build_grid(pts, 1e-3)
    assert 0 < int(np.prod(g.dims)) <= 1 << 15
    _same(neighbour_lists(pts, 1e-3, grid=g), neighbour_lists_reference(pts, 1e-3))
    with pytest.raises(ValueError, match="extent"):
        build_grid(np.array([[-1e308, 0, 0], [1e308, 0, 0]]), 1.0)


def test_grid_is_sorted_by_cell_and_stable(rng):
    pts = rng.uniform(0, 3, (400, 3))
    g = build_grid(pts, 0.5)
    cells = g.cell[g.order]
    assert np.all(np.diff(cells) >= 0)
    same = np.diff(cells) == 0
    assert np.all(np.diff(g.order)[same] > 0)  # index order inside a cell
    for c in np.unique(g.cell)[:20]:
        np.testing.assert_array_equal(g.order[g.start[c]:g.start[c + 1]],
                                      np.nonzero(g.cell == c)[0])


def test_points_outside_box_are_clamped_not_lost(rng):
    pts = rng.uniform(-2, 2, (300, 3))
    g = build_grid(pts, 0.5, lo=np.full(3, -1.0), hi=np.full(3, 1.0))
    _same(neighbour_lists(pts, 0.5, grid=g), neighbour_lists_reference(pts, 0.5))


def test_bad_input():
    with pytest.raises(ValueError, match="radius"):
        neighbour_lists(np.zeros((3, 3)), 0.0)
    with pytest.raises(ValueError, match="points"):
        neighbour_lists(np.array([[0, 0, np.nan]]), 1.0)
    with pytest.raises(ValueError, match="points"):
        neighbour_lists(np.zeros((3, 2)), 1.0)
    with pytest.raises(ValueError, match="grid"):
        neighbour_lists(np.zeros((3, 3)), 1.0, grid=build_grid(np.zeros((3, 3)), 0.5))
