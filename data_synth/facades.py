"""A building's facade with a strip of ground, as a multi-view stereo tool gives it: an
open surface of what the street saw, whose largest plane is the wall, not the ground.

The wall stands in the plane y = 0 facing -y (the street), x in [0, width], z in
[0, height]; windows on a grid of floors and bays are recessed into it by ``recess``
(their reveals join them to the wall), each with a sill that sticks out; a cornice
runs along the top. The ground is a strip z = 0 in front of it, y in [-ground_depth, 0],
with a kerb step ``kerb`` down at ``kerb_at`` of its depth. Up is +z; a random rotation
(``facade_mesh(..., rotate=True)``) hides it the way another tool's frame does, and the
true up comes back beside the mesh.

>>> import numpy as np
>>> v, f, up = facade_mesh(np.random.default_rng(0), rotate=False)
>>> up.tolist(), round(float(v[:, 2].max())), round(float(-v[:, 1].min()))
([0.0, 0.0, 1.0], 12, 5)
"""

from __future__ import annotations

import numpy as np

__all__ = ["facade_mesh"]


def _quad(out_v: list, out_f: list, corners) -> None:
    """Two triangles of the quad ``corners`` (4, 3), counter-clockwise seen from the
    side its normal points to."""
    base = sum(len(v) for v in out_v)
    out_v.append(np.asarray(corners, np.float64))
    out_f.append(np.array([[0, 1, 2], [0, 2, 3]]) + base)


def _box_front(out_v, out_f, x0, x1, z0, z1, y_front, y_back=0.0) -> None:
    """A block sticking out of the wall toward -y: its front, top, bottom and sides."""
    yf, yb = y_front, y_back
    _quad(out_v, out_f, [[x0, yf, z0], [x1, yf, z0], [x1, yf, z1], [x0, yf, z1]])  # -y
    _quad(out_v, out_f, [[x0, yf, z1], [x1, yf, z1], [x1, yb, z1], [x0, yb, z1]])  # +z
    _quad(out_v, out_f, [[x0, yb, z0], [x1, yb, z0], [x1, yf, z0], [x0, yf, z0]])  # -z
    _quad(out_v, out_f, [[x0, yb, z0], [x0, yf, z0], [x0, yf, z1], [x0, yb, z1]])  # -x
    _quad(out_v, out_f, [[x1, yf, z0], [x1, yb, z0], [x1, yb, z1], [x1, yf, z1]])  # +x


def _wall(out_v, out_f, xs, zs, window, recess) -> None:
    """The wall on the grid ``xs`` x ``zs``: a cell is wall (y = 0) or window (y =
    recess); a reveal joins each window cell to its wall neighbours."""
    for i in range(len(xs) - 1):
        for j in range(len(zs) - 1):
            x0, x1, z0, z1 = xs[i], xs[i + 1], zs[j], zs[j + 1]
            y = recess if window[i, j] else 0.0
            _quad(out_v, out_f, [[x0, y, z0], [x1, y, z0], [x1, y, z1], [x0, y, z1]])
            if not window[i, j]:
                continue
            r = recess
            if i == 0 or not window[i - 1, j]:   # left reveal, facing +x
                _quad(out_v, out_f, [[x0, 0, z0], [x0, r, z0], [x0, r, z1], [x0, 0, z1]])
            if i == len(xs) - 2 or not window[i + 1, j]:  # right reveal, facing -x
                _quad(out_v, out_f, [[x1, r, z0], [x1, 0, z0], [x1, 0, z1], [x1, r, z1]])
            if j == 0 or not window[i, j - 1]:   # bottom reveal (the inner sill), +z
                _quad(out_v, out_f, [[x0, r, z0], [x1, r, z0], [x1, 0, z0], [x0, 0, z0]])
            if j == len(zs) - 2 or not window[i, j + 1]:  # top reveal, facing -z
                _quad(out_v, out_f, [[x0, 0, z1], [x1, 0, z1], [x1, r, z1], [x0, r, z1]])


def _weld(v: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One vertex per distinct position (the quads share their corners), and no face
    left with a repeated vertex (a zero-height kerb)."""
    uniq, inverse = np.unique(np.round(v, 9), axis=0, return_inverse=True)
    f = inverse.reshape(-1)[f]
    keep = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])
    return uniq, f[keep]


def facade_mesh(rng: np.random.Generator, *, width: float = 20.0, height: float = 12.0,
                ground_depth: float = 5.0, floors: int = 4, bays: int = 6,
                window_fraction: float = 0.45, recess: float = 0.3, kerb: float = 0.15,
                kerb_at: float = 0.6, noise: float = 0.01, rotate: bool = True):
    """A facade with windows, sills, a cornice and a strip of ground (module docstring).

    Parameters
    ----------
    rng : numpy.random.Generator
        The window sizes' jitter, the surface noise and the rotation.
    width, height, ground_depth, recess, kerb, noise : float
        Metres (noise: the standard deviation of each vertex's displacement).
    floors, bays : int
        The window grid.
    window_fraction : float
        A window's width over its bay's (its height over its floor's: 1.3 times this).
    rotate : bool
        Turn the whole mesh by a random rotation (and shift it), as another tool's frame.

    Returns
    -------
    vertices : (n, 3) float64
    triangles : (m, 3) int64
    up : (3,) float64
        The true up (+z turned by the rotation).
    """
    bay, floor = width / bays, height / floors
    wf = window_fraction * (1 + 0.1 * rng.uniform(-1, 1))
    xs, zs = [0.0], [0.0]
    for b in range(bays):
        c = (b + 0.5) * bay
        xs += [c - wf * bay / 2, c + wf * bay / 2, (b + 1) * bay]
    for k in range(floors):
        lo = k * floor + 0.35 * floor * (1 - 1.3 * wf)
        zs += [lo, lo + 1.3 * wf * floor, (k + 1) * floor]
    xs, zs = np.array(xs), np.array(zs)
    window = np.zeros((len(xs) - 1, len(zs) - 1), bool)
    window[1::3, 1::3] = True
    out_v, out_f = [], []
    _wall(out_v, out_f, xs, zs, window, recess)
    for i in range(1, len(xs) - 1, 3):  # sills under the windows
        for j in range(1, len(zs) - 1, 3):
            _box_front(out_v, out_f, xs[i] - 0.1, xs[i + 1] + 0.1, zs[j] - 0.12, zs[j],
                       -0.15)
    _box_front(out_v, out_f, 0.0, width, height - 0.5, height, -0.45)  # cornice
    y_kerb = -kerb_at * ground_depth  # the pavement, then the road a kerb lower
    for x0, x1 in zip(xs[:-1], xs[1:], strict=True):  # split as the wall is: welded to it
        _quad(out_v, out_f, [[x0, y_kerb, 0], [x1, y_kerb, 0], [x1, 0, 0], [x0, 0, 0]])
        _quad(out_v, out_f, [[x0, y_kerb, -kerb], [x1, y_kerb, -kerb], [x1, y_kerb, 0],
                             [x0, y_kerb, 0]])
        _quad(out_v, out_f, [[x0, -ground_depth, -kerb], [x1, -ground_depth, -kerb],
                             [x1, y_kerb, -kerb], [x0, y_kerb, -kerb]])
    v, f = _weld(np.concatenate(out_v), np.concatenate(out_f).astype(np.int64))
    v = v + rng.normal(0.0, noise, v.shape)
    up = np.array([0.0, 0.0, 1.0])
    if rotate:
        from scipy.spatial.transform import Rotation

        R = Rotation.random(random_state=rng).as_matrix()
        v = v @ R.T + rng.uniform(-50, 50, 3)
        up = R @ up
    return v, f, up
