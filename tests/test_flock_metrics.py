import numpy as np
import pytest

from simulate.boids.metrics import (
    flock_metrics,
    groups,
    milling,
    nearest_neighbour_distances,
    polarization,
)


def test_polarization_closed_forms(rng):
    assert polarization(np.tile([0, 2.0, 0], (10, 1))) == pytest.approx(1.0)
    assert polarization(np.array([[1.0, 0, 0], [-3.0, 0, 0]])) == pytest.approx(0.0)
    # random headings: |mean| ~ 1/sqrt(n)
    v = rng.normal(size=(40000, 3))
    assert polarization(v) < 0.02


def test_milling_of_a_ring_and_a_parallel_group():
    t = np.linspace(0, 2 * np.pi, 50, endpoint=False)
    ring = np.c_[3 * np.cos(t), 3 * np.sin(t), np.zeros_like(t)] + [5, 5, 5]
    tangent = np.c_[-np.sin(t), np.cos(t), np.zeros_like(t)]
    assert milling(ring, tangent) == pytest.approx(1.0)
    assert polarization(tangent) == pytest.approx(0.0, abs=1e-12)
    assert milling(ring, np.tile([0, 0, 1.0], (50, 1))) == pytest.approx(0.0, abs=1e-12)
    # half clockwise, half anticlockwise: the momenta cancel
    mixed = tangent * np.where(np.arange(50) % 2, 1, -1)[:, None]
    assert milling(ring, mixed) == pytest.approx(0.0, abs=1e-12)


def test_nearest_neighbour_on_a_lattice():
    g = np.stack(np.meshgrid(*[np.arange(4.0)] * 3), -1).reshape(-1, 3) * 0.7
    np.testing.assert_allclose(nearest_neighbour_distances(g), 0.7)
    assert np.isinf(nearest_neighbour_distances(np.zeros((1, 3)))[0])


def test_groups_are_connected_components(rng):
    a = rng.uniform(0, 1, (30, 3))
    b = a + [10, 0, 0]
    chain = np.c_[np.arange(10) * 0.9, np.zeros(10), np.zeros(10)] + [0, 20, 0]
    count, labels = groups(np.vstack([a, b, chain]), 1.0)
    assert count == 3  # the chain links through 0.9 steps
    assert len(set(labels[:30])) == 1 and labels[0] != labels[30] != labels[60]
    assert groups(np.vstack([a, b, chain]), 0.5)[0] > 3
    m = flock_metrics(a, np.ones_like(a), group_radius=5.0)
    assert m["groups"] == 1 and m["polarization"] == pytest.approx(1.0)


def test_bad_input():
    with pytest.raises(ValueError, match="velocities"):
        polarization(np.zeros((0, 3)))
    with pytest.raises(ValueError, match="radius"):
        groups(np.zeros((2, 3)), -1)
    with pytest.raises(ValueError, match="velocities"):
        milling(np.zeros((3, 3)), np.zeros((2, 3)))
