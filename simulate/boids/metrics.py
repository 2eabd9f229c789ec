"""Order parameters of a flock: polarization, milling, nearest-neighbour distance, groups.

Polarization is the Vicsek order parameter ``|mean(v_i / |v_i|)|`` (1: all aligned,
about ``1/sqrt(n)`` for random headings). Milling is Couzin's group angular momentum
``|mean(r_ic x v_i)|`` with unit ``r_ic`` (from the centroid to boid ``i``) and unit
``v_i`` (1: a perfect torus about the centroid). Groups are the connected components
of the graph joining boids closer than a radius.

>>> import numpy as np
>>> v = np.tile([1.0, 0, 0], (4, 1))
>>> polarization(v)
1.0
>>> t = np.linspace(0, 2 * np.pi, 8, endpoint=False)
>>> ring = np.c_[np.cos(t), np.sin(t), 0 * t]
>>> round(milling(ring, np.c_[-np.sin(t), np.cos(t), 0 * t]), 12)
1.0
"""

from __future__ import annotations

import numpy as np

from core.frames import unit
from core.validate import check_array, check_positive
from simulate.neighbours import neighbour_lists

__all__ = ["polarization", "milling", "nearest_neighbour_distances", "groups",
           "flock_metrics", "METRIC_NAMES"]

METRIC_NAMES = ("polarization", "milling", "nearest_neighbour", "groups")


def polarization(velocities: np.ndarray) -> float:
    """Vicsek order parameter in [0, 1].

    Parameters
    ----------
    velocities : (n, 3) float64
        Boids with zero velocity count as headings of length 0.
    """
    v = check_array(velocities, "velocities", shape=(None, 3), min_rows=1)
    return float(np.linalg.norm(unit(v).mean(axis=0)))


def milling(positions: np.ndarray, velocities: np.ndarray) -> float:
    """Normalized angular momentum about the centroid, in [0, 1].

    Parameters
    ----------
    positions, velocities : (n, 3) float64
    """
    x = check_array(positions, "positions", shape=(None, 3), min_rows=1)
    v = check_array(velocities, "velocities", shape=(len(x), 3))
    r = unit(x - x.mean(axis=0))
    return float(np.linalg.norm(np.cross(r, unit(v)).mean(axis=0)))


def nearest_neighbour_distances(positions: np.ndarray) -> np.ndarray:
    """Distance ``(n,) float64`` from each boid to its nearest other (inf for one boid)."""
    from scipy.spatial import cKDTree

    x = check_array(positions, "positions", shape=(None, 3), min_rows=1)
    if len(x) < 2:
        return np.full(len(x), np.inf)
    d, _ = cKDTree(x).query(x, k=2)
    return d[:, 1]


def groups(positions: np.ndarray, radius: float) -> tuple[int, np.ndarray]:
    """Groups: connected components of the graph of pairs closer than ``radius``.

    Returns
    -------
    count : int
    labels : (n,) int64
        Group of each boid, numbered in order of their lowest boid index.
    """
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    x = check_array(positions, "positions", shape=(None, 3), min_rows=1)
    r = check_positive(radius, "radius")
    offsets, indices = neighbour_lists(x, r)
    n = len(x)
    graph = csr_matrix((np.ones(len(indices), np.int8), indices, offsets), shape=(n, n))
    count, labels = connected_components(graph, directed=False)
    return int(count), labels.astype(np.int64)


def flock_metrics(positions: np.ndarray, velocities: np.ndarray, *,
                  group_radius: float) -> dict:
    """All four measures: ``polarization``, ``milling``, ``nearest_neighbour`` (mean
    nearest-neighbour distance) and ``groups`` (count)."""
    return {"polarization": polarization(velocities),
            "milling": milling(positions, velocities),
            "nearest_neighbour": float(np.mean(nearest_neighbour_distances(positions))),
            "groups": groups(positions, group_radius)[0]}
