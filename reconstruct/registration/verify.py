"""Checking a candidate alignment of two scans on their geometry, lines of sight included.

A wrong match between two scans can still look good on distances alone: a plane laid on
its own back, a repeated structure slid by one period, a surface that agrees on its
overlap while the rest of the scan floats in front of the other. Each candidate
``target_from_source`` is therefore judged on:

- **overlap**: the fraction of the smaller scan's samples within ``tau`` of the other;
- **agreement**: the RMS point-to-plane distance over that overlap (a fraction of
  ``tau``: a wrong fit spreads its distances over the whole band), and the normals there (a surface
  that the two scanners saw from opposite sides -- normals opposed -- is *seen from the
  back*);
- **free space**: each scanner saw through the space between itself and its surface. A
  sample of the other scan lying in that space, well in front of what this scanner saw
  along the same line of sight, *would block* its view: the two cannot both be right.

Both scans are checked against each other. The verdict names its reason.

References
----------
D. Huber and M. Hebert, "Fully automatic registration of multiple 3D data sets",
Image and Vision Computing 21(7), 2003 (visibility consistency). doi:10.1016/S0262-8856(03)00070-2
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.frames import transform_points

from .oriented import Oriented

__all__ = ["Verdict", "VerifyOptions", "verify_pair", "ViewMap"]


@dataclass(frozen=True)
class VerifyOptions:
    """Thresholds of :func:`verify_pair` (fractions are of the samples concerned)."""

    min_overlap: float = 0.15
    max_backfacing: float = 0.1
    max_blocking: float = 0.03
    max_plane_rms: float = 0.25   # of tau


@dataclass(frozen=True)
class Verdict:
    """The checks of one candidate.

    ``overlap``: fraction of the smaller scan's samples within ``tau`` of the other;
    ``rms``: RMS point-to-plane distance over the overlap (metres); ``backfacing``: fraction of the
    overlap with opposed normals; ``blocking``: fraction of the samples that project into
    the other scan's view and lie in front of what it saw (the larger of the two ways);
    ``reason``: empty when accepted.
    """

    overlap: float
    rms: float
    backfacing: float
    blocking: float
    n_overlap: int
    reason: str

    @property
    def accepted(self) -> bool:
        return not self.reason

    @property
    def score(self) -> float:
        """Ranks accepted candidates: overlap, discounted by violations."""
        return self.overlap * (1.0 - self.backfacing) * (1.0 - 10.0 * self.blocking)


class ViewMap:
    """What one scanner saw, as a depth map over its lines of sight.

    The map is orthographic along the mean line of sight when the lines are parallel
    (within 2 degrees, as for a linear-sweep scanner), else perspective from the point
    the lines meet (least squares). Each cell keeps the nearest depth seen.

    Parameters
    ----------
    view : Oriented
        The scan's samples in its own (or any) frame.
    cell : float
        Cell size at the surface (metres).
    """

    def __init__(self, view: Oriented, cell: float):
        s = view.sight
        d = s.mean(axis=0)
        d /= np.linalg.norm(d)
        self.axis = d
        helper = np.array([1.0, 0, 0]) if abs(d[0]) < 0.9 else np.array([0, 1.0, 0])
        u = np.cross(d, helper)
        u /= np.linalg.norm(u)
        self.basis = np.stack([u, np.cross(d, u)])
        self.origin = None
        if np.min(s @ d) < np.cos(np.radians(2.0)):
            # rays x = p + l s; the point nearest all of them
            m = np.eye(3)[None] - s[:, :, None] * s[:, None, :]
            self.origin = np.linalg.solve(m.sum(axis=0), np.einsum("nij,nj->i", m, view.points))
            self.range = float(np.median(np.linalg.norm(view.points - self.origin, axis=1)))
        self.cell = cell
        uv, depth = self._project(view.points)
        self.lo = uv.min(axis=0) - 2
        key = uv - self.lo
        self.shape = tuple(int(x) for x in key.max(axis=0) + 3)
        grid = np.full(self.shape, np.inf)
        np.minimum.at(grid, (key[:, 0], key[:, 1]), depth)
        # the nearest surface around each cell: conservative at depth edges
        near = grid.copy()
        for du in (-1, 0, 1):
            for dv in (-1, 0, 1):
                near = np.minimum(near, np.roll(np.roll(grid, du, 0), dv, 1))
        seen = np.isfinite(grid)
        self.near = np.where(seen, near, np.nan)

    def _project(self, points: np.ndarray):
        if self.origin is None:
            uv = points @ self.basis.T
            depth = -(points @ self.axis)
        else:
            q = points - self.origin
            depth = np.linalg.norm(q, axis=1)
            along = -(q @ self.axis)
            with np.errstate(divide="ignore", invalid="ignore"):
                uv = (q @ self.basis.T) / np.maximum(along, 1e-9)[:, None] * self.range
        return np.floor(uv / self.cell).astype(np.int64), depth

    def depth_of(self, points: np.ndarray):
        """For points in the map's frame: ``(seen_depth, own_depth)``, NaN where the map
        has nothing."""
        uv, depth = self._project(points)
        key = uv - self.lo
        inside = np.all((key >= 0) & (key < np.array(self.shape)), axis=1)
        seen = np.full(len(points), np.nan)
        seen[inside] = self.near[key[inside, 0], key[inside, 1]]
        return seen, depth


def _blocking(view: ViewMap, other: np.ndarray, tau: float) -> tuple[float, int]:
    seen, depth = view.depth_of(other)
    has = np.isfinite(seen)
    if not has.any():
        return 0.0, 0
    blocked = depth[has] < seen[has] - 3.0 * tau
    return float(blocked.mean()), int(has.sum())


def verify_pair(target: Oriented, source: Oriented, target_from_source: np.ndarray, *,
                tau: float, target_map: ViewMap | None = None,
                source_map: ViewMap | None = None, target_tree=None,
                options: VerifyOptions | None = None) -> Verdict:
    """Judge ``target_from_source`` (4x4) on the geometry of both scans (module docstring).

    Parameters
    ----------
    target, source : Oriented
        Samples of each scan in its own frame.
    tau : float
        Distance at which two samples are the same surface (metres).
    target_map, source_map : ViewMap, optional
        Built once per scan when checking many candidates (cell ``tau``).
    target_tree : scipy.spatial.cKDTree, optional
        Of ``target.points``.
    """
    from scipy.spatial import cKDTree

    options = VerifyOptions() if options is None else options
    tree = cKDTree(target.points) if target_tree is None else target_tree
    moved = source.transformed(target_from_source)
    d, j = tree.query(moved.points, distance_upper_bound=tau)
    near = np.isfinite(d)
    n_near = int(near.sum())
    overlap = n_near / max(1, min(len(source), len(target)))
    overlap = min(overlap, 1.0)
    gap = np.sum((moved.points[near] - target.points[j[near]]) * target.normals[j[near]],
                 axis=1)
    rms = float(np.sqrt(np.mean(gap ** 2))) if n_near else float("nan")
    back = float(np.mean(np.sum(moved.normals[near] * target.normals[j[near]], axis=1) < 0)
                 ) if n_near else 0.0
    target_map = ViewMap(target, tau) if target_map is None else target_map
    source_map = ViewMap(source, tau) if source_map is None else source_map
    b1, _ = _blocking(target_map, moved.points, tau)
    inv = np.linalg.inv(target_from_source)
    b2, _ = _blocking(source_map, transform_points(inv, target.points), tau)
    blocking = max(b1, b2)
    reason = ""
    if overlap < options.min_overlap:
        reason = f"overlap {100 * overlap:.0f} % < {100 * options.min_overlap:.0f} %"
    elif rms > options.max_plane_rms * tau:
        reason = (f"the surfaces disagree (RMS {rms:.3g} m over the overlap > "
                  f"{options.max_plane_rms * tau:.3g} m)")
    elif back > options.max_backfacing:
        reason = f"seen from the back ({100 * back:.0f} % of the overlap has opposed normals)"
    elif blocking > options.max_blocking:
        reason = (f"would block the other scanner's view ({100 * blocking:.1f} % of the "
                  f"samples lie in space it saw through)")
    return Verdict(overlap, rms, back, blocking, n_near, reason)
