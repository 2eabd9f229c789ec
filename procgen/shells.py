"""Seashells: the helico-spiral model and Cortie's fuller parameterization.

- :func:`helicospiral_shell` — Fowler, Meinhardt and Prusinkiewicz (1992), "Modeling
  seashells", SIGGRAPH '92 (doi:10.1145/133994.134096): a generating circle (or ellipse)
  swept along a helico-spiral ``(r cos t, r sin t, -h)`` with ``r, h, scale`` all growing as
  ``exp(k t)``; built with :func:`procgen.sweeps.sweep`.
- :func:`cortie_shell` — Cortie (1989) as written out by Picado (2009), "Seashells: the
  plainness and beauty of their mathematical description": chirality ``D``, spiral angle
  ``alpha``, enlarging angle ``beta``, aperture ellipse ``a, b`` rotated by ``phi, mu, omega``,
  distance ``A`` of the aperture from the axis, and nodules (``L, P, W1, W2, N``).

:data:`SHAPES` holds presets for the five shape classes of Fowler et al. (turbinate,
patelliform, tubular, spherical, discoid); the numbers are ours, chosen to reproduce each
class, not values copied from a table. Units are arbitrary (scale the mesh to metres).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.validate import check_choice, check_range
from procgen.sweeps import sweep

__all__ = ["CortieParams", "SHAPES", "cortie_shell", "cortie_points", "helicospiral_shell"]


@dataclass(frozen=True)
class CortieParams:
    """Parameters of the Cortie/Picado shell model (angles in degrees).

    Attributes
    ----------
    D : {1, -1}
        Chirality (1 dextral, -1 sinistral).
    A : float
        Distance from the aperture centre to the coiling axis at ``theta = 0``.
    alpha : float
        Equiangular spiral angle; growth per radian is ``exp(theta cot(alpha))``.
    beta : float
        Angle between the coiling axis and the line to the aperture (90: planispiral).
    phi, mu, omega : float
        Rotations of the aperture ellipse.
    a, b : float
        Semi-axes of the aperture ellipse.
    L, P, W1, W2, N : float
        Nodule height, position on the aperture (degrees), angular widths (degrees) and
        number of nodules per whorl (``L = 0``: none).
    turns : float
        Whorls from ``theta_start``.
    theta_start : float
        First angle in turns (negative: start near the apex).
    """

    D: int = 1
    A: float = 25.0
    alpha: float = 83.0
    beta: float = 42.0
    phi: float = 70.0
    mu: float = 10.0
    omega: float = 30.0
    a: float = 12.0
    b: float = 20.0
    L: float = 0.0
    P: float = 0.0
    W1: float = 10.0
    W2: float = 10.0
    N: float = 0.0
    turns: float = 6.0
    theta_start: float = -5.0


SHAPES = {
    # tall conical spire, many slowly growing whorls (Turritella-like)
    "turbinate": CortieParams(A=20, alpha=87.5, beta=8, phi=50, mu=1, omega=-2, a=4, b=4.5,
                              turns=12, theta_start=-11),
    # limpet: huge expansion, less than a turn, wide aperture (Patella-like)
    "patelliform": CortieParams(A=2, alpha=55, beta=60, phi=0, mu=0, omega=0, a=5, b=7,
                                turns=0.7, theta_start=-0.5),
    # a loosely coiled tube whose whorls do not touch (Vermetus-like)
    "tubular": CortieParams(A=12, alpha=88, beta=50, phi=0, mu=0, omega=0, a=1.2, b=1.2,
                            turns=4, theta_start=-3),
    # globose: low spire, fast growth, whorls enclosing the earlier ones (Natica-like)
    "spherical": CortieParams(A=25, alpha=83, beta=42, phi=70, mu=10, omega=30, a=12, b=20,
                              turns=6, theta_start=-5),
    # planispiral: all whorls in one plane (Planorbis-like)
    "discoid": CortieParams(A=6, alpha=85, beta=90, phi=0, mu=0, omega=0, a=2.5, b=2.5,
                            turns=5, theta_start=-4),
}


def cortie_points(params: CortieParams, theta: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Surface points ``(len(theta), len(s), 3)`` for coiling angles ``theta`` (radians)
    and aperture angles ``s`` (radians)."""
    p = params
    al, be, ph, mu, om = np.radians([p.alpha, p.beta, p.phi, p.mu, p.omega])
    th = np.asarray(theta, np.float64)[:, None]
    ss = np.asarray(s, np.float64)[None, :]
    R = 1.0 / np.sqrt(np.cos(ss) ** 2 / p.a**2 + np.sin(ss) ** 2 / p.b**2)
    if p.L and p.N:
        g = 2 * np.pi / p.N * (p.N * th / (2 * np.pi) - np.round(p.N * th / (2 * np.pi)))
        w1, w2, pp = np.radians([p.W1, p.W2, p.P])
        R = R + p.L * np.exp(-(2 * (ss - pp) / w1) ** 2 - (2 * g / w2) ** 2)
    grow = np.exp(th / np.tan(al))
    x = p.D * (p.A * np.sin(be) * np.cos(th) + R * np.cos(ss + ph) * np.cos(th + om)
               - R * np.sin(mu) * np.sin(ss + ph) * np.sin(th)) * grow
    y = (-p.A * np.sin(be) * np.sin(th) - R * np.cos(ss + ph) * np.sin(th + om)
         - R * np.sin(mu) * np.sin(ss + ph) * np.cos(th)) * grow
    z = (-p.A * np.cos(be) + R * np.sin(ss + ph) * np.cos(mu)) * grow
    return np.stack([x, y, z], axis=-1)


def cortie_shell(params: CortieParams | str, *, n_theta: int = 400, n_s: int = 48,
                 caps: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Triangle mesh of a Cortie shell.

    Parameters
    ----------
    params : CortieParams or str
        A parameter set or a name in :data:`SHAPES`.
    n_theta, n_s : int
        Samples along the coiling and around the aperture.
    caps : bool
        Close the apex and the aperture with fans (the surface is then closed; later
        whorls may pass through earlier ones, as real shells' whorls touch).

    Returns
    -------
    vertices : (k, 3) float64
    triangles : (t, 3) int64
    """
    if isinstance(params, str):
        params = SHAPES[check_choice(params, "params", SHAPES)]
    if n_theta < 2 or n_s < 3:
        raise ValueError(f"n_theta, n_s: expected >= 2 and >= 3, got {n_theta}, {n_s}")
    check_range(params.alpha, "alpha", 0, 90, lo_open=True, hi_open=False)
    theta = 2 * np.pi * np.linspace(params.theta_start, params.theta_start + params.turns,
                                    n_theta)
    s = np.linspace(-np.pi, np.pi, n_s, endpoint=False)
    P = cortie_points(params, theta, s)
    verts = P.reshape(-1, 3)
    i = np.arange(n_theta - 1)[:, None]
    j = np.arange(n_s)[None, :]
    a0, a1 = i * n_s + j, i * n_s + (j + 1) % n_s
    b0, b1 = a0 + n_s, a1 + n_s
    tris = np.concatenate([np.stack([a0, a1, b1], -1).reshape(-1, 3),
                           np.stack([a0, b1, b0], -1).reshape(-1, 3)])
    if caps:
        c = len(verts)
        verts = np.vstack([verts, P[0].mean(axis=0), P[-1].mean(axis=0)])
        jj = np.arange(n_s)
        last = (n_theta - 1) * n_s
        tris = np.concatenate([tris, np.stack([np.full(n_s, c), (jj + 1) % n_s, jj], -1),
                               np.stack([np.full(n_s, c + 1), last + jj, last + (jj + 1) % n_s],
                                        -1)])
    tris = tris.astype(np.int64)
    from procgen.sweeps import mesh_volume

    if caps and mesh_volume(verts, tris) < 0:  # orientation depends on chirality and angles
        tris = tris[:, ::-1].copy()
    return verts, tris


def helicospiral_shell(*, turns: float = 5.0, expansion: float = 2.0, spire: float = 1.0,
                       radius: float = 1.0, aperture: float = 0.45, ellipse: float = 1.0,
                       n_path: int = 400, n_profile: int = 32, handedness: int = 1,
                       caps: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Fowler et al.'s helico-spiral shell: a scaled circle swept along a helico-spiral.

    The sweep curve is ``(r cos t, handedness * r sin t, -spire * r)`` with
    ``r = radius * expansion ** (t / 2 pi - turns)``, so the aperture (t at ``turns``
    whorls) sits at distance ``radius`` from the axis; the generating circle's radius is
    ``aperture * r`` (an ellipse with axis ratio ``ellipse``).

    Parameters
    ----------
    turns : float
        Number of whorls.
    expansion : float
        Growth factor per whorl (> 1).
    spire : float
        Height gained per unit of radius (0: discoid; large: turbinate).
    radius, aperture, ellipse : float
    n_path, n_profile : int
    handedness : {1, -1}
    caps : bool

    Returns
    -------
    vertices : (k, 3) float64
    triangles : (t, 3) int64
    """
    check_range(expansion, "expansion", 1.0, None, lo_open=True)
    check_range(turns, "turns", 0.0, None, lo_open=True)
    check_range(aperture, "aperture", 0.0, None, lo_open=True)
    check_choice(handedness, "handedness", {1, -1})
    t = np.linspace(0, 2 * np.pi * turns, n_path)
    r = radius * expansion ** (t / (2 * np.pi) - turns)
    path = np.c_[r * np.cos(t), handedness * r * np.sin(t), -spire * r]
    u = np.linspace(0, 2 * np.pi, n_profile, endpoint=False)
    profile = aperture * np.c_[np.cos(u), ellipse * np.sin(u)]
    # the frame's normal points away from the axis at the start: keeps the aperture upright
    v, f = sweep(profile, path, scale=r, caps=caps,
                 normal=np.array([path[0, 0], path[0, 1], 0.0]) + [0.0, 0.0, 1e-9])
    return v, f
