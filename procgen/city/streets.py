"""Street network statistics as Boeing measures real cities.

Boeing (2019), "Urban spatial order: street network orientation, configuration, and
entropy", Applied Network Science 4:67 (doi:10.1007/s41109-019-0189-1), measures each
city on its *simplified* street graph, where a node is an intersection or a dead end and
an edge is the street between two of them, however it bends:

- **orientation order** ``phi = 1 - ((H - H_g) / (H_max - H_g))^2`` from the entropy ``H``
  of the edges' bearings in 36 bins of 10 degrees (each edge counted both ways), with
  ``H_max = ln 36`` (uniform bearings) and ``H_g = ln 4`` (a perfect grid): 1 for a grid,
  0 for no order (Chicago 0.90, Charlotte 0.002);
- **mean node degree** ``2 m / n``;
- **dead-end share**, the proportion of nodes of degree 1;
- **circuity**, the summed street lengths over the summed straight-line distances between
  their ends (1 for straight streets).

>>> import numpy as np
>>> ends = [(0, 1), (3, 1), (0, 2), (3, 2), (1, 0), (1, 3), (2, 0), (2, 3)]
>>> nodes = 100.0 * np.array([(1, 1), (2, 1), (1, 2), (2, 2)] + ends)  # a '#' of streets
>>> edges = np.array([(4, 0), (0, 1), (1, 5), (6, 2), (2, 3), (3, 7),
...                   (8, 0), (0, 2), (2, 9), (10, 1), (1, 3), (3, 11)])
>>> s = street_statistics(nodes, edges)
>>> s["orientation_order"], s["circuity"], round(s["dead_end_share"], 3), s["mean_degree"]
(1.0, 1.0, 0.667, 2.0)
"""

from __future__ import annotations

import numpy as np

from core.validate import check_array

__all__ = ["simplify_graph", "street_statistics", "orientation_order", "bearings"]

_BINS = 36


def simplify_graph(nodes: np.ndarray, edges: np.ndarray):
    """Merge chains through nodes of degree 2 into single streets.

    Parameters
    ----------
    nodes : (k, 2) float64
    edges : (e, 2) int64

    Returns
    -------
    list of (m, 2) float64
        Each street as the polyline of its nodes, from one intersection or dead end to
        another (a closed ring of degree-2 nodes is one street starting and ending at the
        same node).
    """
    nodes = check_array(nodes, "nodes", shape=(None, 2))
    edges = np.asarray(edges, np.int64).reshape(-1, 2)
    adj: dict[int, list[tuple[int, int]]] = {}
    for k, (a, b) in enumerate(edges):
        adj.setdefault(int(a), []).append((int(b), k))
        adj.setdefault(int(b), []).append((int(a), k))
    deg = {v: len(n) for v, n in adj.items()}
    used = np.zeros(len(edges), bool)
    streets = []

    def walk(v, nxt, k):
        path = [v]
        while True:
            used[k] = True
            path.append(nxt)
            if deg[nxt] != 2 or nxt == path[0]:
                return path
            (a, ka), (b, kb) = adj[nxt]
            v, (nxt, k) = nxt, ((a, ka) if not used[ka] else (b, kb))
            if used[k]:
                return path

    for v in sorted(adj):
        if deg[v] == 2:
            continue
        for nxt, k in adj[v]:
            if not used[k]:
                streets.append(nodes[walk(v, nxt, k)])
    for k in np.flatnonzero(~used):      # rings made only of degree-2 nodes
        if not used[k]:
            a, b = edges[k]
            streets.append(nodes[walk(int(a), int(b), int(k))])
    return streets


def bearings(streets) -> np.ndarray:
    """Compass bearing (degrees clockwise from north, [0, 360)) of each street from its
    first to its last node; NaN for a closed street."""
    out = []
    for s in streets:
        d = s[-1] - s[0]
        out.append(np.nan if np.hypot(*d) < 1e-9 else np.degrees(np.arctan2(d[0], d[1])) % 360)
    return np.array(out, np.float64)


def orientation_order(bearing_deg) -> float:
    """Boeing's orientation order of street bearings (degrees; each counted both ways)."""
    b = np.asarray(bearing_deg, np.float64)
    b = b[np.isfinite(b)]
    if len(b) == 0:
        return float("nan")
    both = np.concatenate([b, (b + 180.0) % 360.0])
    # bins centred on 0, 10, ... 350 degrees: shift by half a bin
    counts = np.bincount(((both + 5.0) % 360.0 // 10.0).astype(int), minlength=_BINS)
    p = counts[counts > 0] / counts.sum()
    h = float(-(p * np.log(p)).sum())
    h_max, h_g = np.log(_BINS), np.log(4.0)
    return float(1.0 - ((h - h_g) / (h_max - h_g)) ** 2)


def street_statistics(nodes: np.ndarray, edges: np.ndarray) -> dict:
    """Boeing's statistics of a street network (see the module docstring).

    Parameters
    ----------
    nodes : (k, 2) float64
        Node positions, metres.
    edges : (e, 2) int64
        Segments between nodes.

    Returns
    -------
    dict
        ``orientation_order``, ``mean_degree``, ``dead_end_share``, ``circuity``,
        ``intersections`` (nodes of degree >= 3), ``streets``, ``length_m``.
    """
    nodes = check_array(nodes, "nodes", shape=(None, 2))
    edges = np.asarray(edges, np.int64).reshape(-1, 2)
    streets = simplify_graph(nodes, edges)
    deg = np.bincount(edges.ravel(), minlength=len(nodes))
    kept = deg[deg > 0]
    kept = kept[kept != 2]
    n = len(kept)
    m = len(streets)
    length = sum(float(np.linalg.norm(np.diff(s, axis=0), axis=1).sum()) for s in streets)
    straight = sum(float(np.linalg.norm(s[-1] - s[0])) for s in streets)
    return {
        "orientation_order": orientation_order(bearings(streets)),
        "mean_degree": 2.0 * m / n if n else float("nan"),
        "dead_end_share": float(np.mean(kept == 1)) if n else float("nan"),
        "circuity": length / straight if straight > 0 else float("nan"),
        "intersections": int(np.sum(kept >= 3)),
        "streets": m,
        "length_m": length,
    }
