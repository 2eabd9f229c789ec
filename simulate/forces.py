"""Forces on particles, as accelerations ``a(t, x, v)``.

Local forces (each particle alone) are small frozen dataclasses that pack into a
table evaluated by one compiled kernel (:func:`local_accel`, also inlined into the
fused particle stepper of :mod:`simulate.particles`):

* :class:`Gravity` ``a = g``
* :class:`Wind` ``a = c (w - v) / m`` (linear drag toward the wind velocity)
* :class:`Damping` ``a = -rate v``
* :class:`Turbulence` Perlin vector noise ``a = A (n1, n2, n3)(x / s)`` or curl noise
  ``a = A grad n1 x grad n2`` — the curl of ``n1 grad n2``, divergence-free exactly
  (analytic gradients of improved noise, no finite differences; both potentials come
  from one lattice walk, :func:`curl_potentials`)
* :class:`Attractor` softened inverse square toward (or, negative, away from) a point
* :class:`Vortex` swirl about an axis, ``a = S axis x r_perp / (|r_perp|^2 + R^2)``
* :class:`Buoyancy` ``a = beta T up`` with a per-particle temperature ``T``

Interacting forces: :class:`Pairwise` attraction/repulsion within a cut-off radius
through a uniform neighbour grid (:func:`pairwise_accel`; the O(n^2)
:func:`pairwise_accel_reference` is the test oracle) and :class:`Springs`
(Hooke with damping along the spring, :func:`spring_forces`).

:class:`ForceSet` gathers forces and gives the total acceleration.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numba as nb
import numpy as np

from core.validate import check_array, check_choice, check_positive
from procgen.noise import curl_potentials, noise3, perm_table
from simulate.neighbours import neighbour_lists, threads_for

__all__ = ["Gravity", "Wind", "Damping", "Turbulence", "Attractor", "Vortex", "Buoyancy",
           "Pairwise", "Springs", "ForceSet", "local_accel", "pairwise_accel",
           "pairwise_accel_reference", "spring_forces", "curl_potentials", "NPARAM"]

NPARAM = 10
_GRAVITY, _WIND, _DAMPING, _TURB_PERLIN, _TURB_CURL, _ATTRACTOR, _VORTEX, _BUOYANCY = range(8)


def _vec3(value, name):
    return check_array(value, name, shape=(3,))


@dataclass(frozen=True)
class Gravity:
    """Uniform gravity ``g (3,)`` in m/s^2 (default 9.81 down the Z axis)."""

    g: tuple = (0.0, 0.0, -9.81)

    def pack(self):
        return _GRAVITY, list(_vec3(self.g, "g")), None


@dataclass(frozen=True)
class Wind:
    """Linear drag toward the wind: ``a = drag (velocity - v) / m``.

    ``drag`` in kg/s; a particle's velocity relaxes to the wind with rate ``drag / m``.
    """

    velocity: tuple = (0.0, 0.0, 0.0)
    drag: float = 0.1

    def pack(self):
        return _WIND, [*_vec3(self.velocity, "velocity"),
                       check_positive(self.drag, "drag", allow_zero=True)], None


@dataclass(frozen=True)
class Damping:
    """Velocity damping ``a = -rate v`` (1/s, independent of mass)."""

    rate: float = 0.1

    def pack(self):
        return _DAMPING, [check_positive(self.rate, "rate", allow_zero=True)], None


@dataclass(frozen=True)
class Turbulence:
    """Noise turbulence with amplitude ``amplitude`` (m/s^2) and feature size ``scale`` (m).

    ``kind="perlin"``: three Perlin noises at offset coordinates; ``kind="curl"``:
    ``grad n1 x grad n2`` (divergence-free). ``speed`` (1/s) scrolls the field in time
    along the noise's z axis; ``seed`` picks the permutation table.
    """

    amplitude: float = 1.0
    scale: float = 1.0
    kind: str = "curl"
    speed: float = 0.0
    seed: int = 0

    def pack(self):
        check_choice(self.kind, "kind", ("perlin", "curl"))
        code = _TURB_CURL if self.kind == "curl" else _TURB_PERLIN
        return code, [float(self.amplitude), 1.0 / check_positive(self.scale, "scale"),
                      float(self.speed)], perm_table(int(self.seed))


@dataclass(frozen=True)
class Attractor:
    """Point attractor: ``a = strength (p - x) / (|p - x|^2 + softening^2)^(3/2)``.

    Negative ``strength`` repels. ``strength`` in m^3/s^2 (like G M).
    """

    position: tuple = (0.0, 0.0, 0.0)
    strength: float = 1.0
    softening: float = 0.05

    def pack(self):
        return _ATTRACTOR, [*_vec3(self.position, "position"), float(self.strength),
                            check_positive(self.softening, "softening")], None


@dataclass(frozen=True)
class Vortex:
    """Swirl about the line through ``center`` along ``axis``.

    ``a = strength * axis x r_perp / (|r_perp|^2 + radius^2)``: strongest at ``|r_perp|
    = radius``, counter-clockwise seen from the tip of ``axis`` for positive strength.
    """

    center: tuple = (0.0, 0.0, 0.0)
    axis: tuple = (0.0, 0.0, 1.0)
    strength: float = 1.0
    radius: float = 0.2

    def pack(self):
        ax = _vec3(self.axis, "axis")
        n = np.linalg.norm(ax)
        if n == 0:
            raise ValueError("axis: expected a non-zero vector, got (0, 0, 0)")
        return _VORTEX, [*_vec3(self.center, "center"), *(ax / n), float(self.strength),
                         check_positive(self.radius, "radius")], None


@dataclass(frozen=True)
class Buoyancy:
    """Buoyancy of hot particles: ``a = beta * T * up`` (T: per-particle temperature)."""

    beta: float = 0.01
    up: tuple = (0.0, 0.0, 1.0)

    def pack(self):
        return _BUOYANCY, [*_vec3(self.up, "up"), float(self.beta)], None


@dataclass(frozen=True)
class Pairwise:
    """Pairwise attraction/repulsion within ``radius`` (m), through a neighbour grid.

    The force of j on i is ``F = (attraction w - repulsion w^2) (x_j - x_i) / |x_j - x_i|``
    with ``w = 1 - r / radius``: repulsive at short range when ``repulsion >
    attraction``, attractive further out, zero beyond ``radius`` (newtons).
    """

    attraction: float = 0.0
    repulsion: float = 1.0
    radius: float = 0.1

    def __post_init__(self):
        check_positive(self.radius, "radius")


@dataclass(frozen=True)
class Springs:
    """Damped springs between particle pairs.

    Parameters
    ----------
    pairs : (m, 2) int
    stiffness : (m,) or float, N/m
    rest : (m,) or float, m
    damping : (m,) or float, N s/m (along the spring)
    """

    pairs: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.int64))
    stiffness: np.ndarray | float = 100.0
    rest: np.ndarray | float = 1.0
    damping: np.ndarray | float = 0.0

    def arrays(self):
        p = check_array(self.pairs, "pairs", shape=(None, 2), dtype=np.int64)
        m = len(p)
        k = np.broadcast_to(np.asarray(self.stiffness, np.float64), (m,)).copy()
        r = np.broadcast_to(np.asarray(self.rest, np.float64), (m,)).copy()
        d = np.broadcast_to(np.asarray(self.damping, np.float64), (m,)).copy()
        return np.ascontiguousarray(p[:, 0]), np.ascontiguousarray(p[:, 1]), k, r, d


# -- curl noise: two potentials in one lattice walk --------------------------------------

# Offsets decorrelating the Perlin-vector components (irrational, far from lattice points).
_O1 = (31.416, 47.853, 12.734)
_O2 = (-19.271, 8.917, 53.129)


def _accel_py(codes, params, perms, t, x, y, z, vx, vy, vz, inv_m, temp):
    """Acceleration of one particle under the packed local forces (compiled twice below)."""
    ax = 0.0
    ay = 0.0
    az = 0.0
    for k in range(codes.shape[0]):
        c = codes[k]
        if c == 0:  # gravity
            ax += params[k, 0]
            ay += params[k, 1]
            az += params[k, 2]
        elif c == 1:  # wind drag
            s = params[k, 3] * inv_m
            ax += s * (params[k, 0] - vx)
            ay += s * (params[k, 1] - vy)
            az += s * (params[k, 2] - vz)
        elif c == 2:  # damping
            r = params[k, 0]
            ax -= r * vx
            ay -= r * vy
            az -= r * vz
        elif c == 3 or c == 4:  # turbulence
            amp = params[k, 0]
            f = params[k, 1]
            qx = x * f
            qy = y * f
            qz = z * f + params[k, 2] * t
            p = perms[k]
            if c == 3:
                ax += amp * noise3(p, qx, qy, qz)
                ay += amp * noise3(p, qx + _O1[0], qy + _O1[1], qz + _O1[2])
                az += amp * noise3(p, qx + _O2[0], qy + _O2[1], qz + _O2[2])
            else:
                _, ux, uy, uz, _, wx, wy, wz = curl_potentials(p, qx, qy, qz)
                ax += amp * (uy * wz - uz * wy)
                ay += amp * (uz * wx - ux * wz)
                az += amp * (ux * wy - uy * wx)
        elif c == 5:  # attractor
            dx = params[k, 0] - x
            dy = params[k, 1] - y
            dz = params[k, 2] - z
            r2 = dx * dx + dy * dy + dz * dz + params[k, 4] * params[k, 4]
            s = params[k, 3] / (r2 * np.sqrt(r2))
            ax += s * dx
            ay += s * dy
            az += s * dz
        elif c == 6:  # vortex
            dx = x - params[k, 0]
            dy = y - params[k, 1]
            dz = z - params[k, 2]
            nx = params[k, 3]
            ny = params[k, 4]
            nz = params[k, 5]
            along = dx * nx + dy * ny + dz * nz
            dx -= along * nx
            dy -= along * ny
            dz -= along * nz
            s = params[k, 6] / (dx * dx + dy * dy + dz * dz + params[k, 7] * params[k, 7])
            ax += s * (ny * dz - nz * dy)
            ay += s * (nz * dx - nx * dz)
            az += s * (nx * dy - ny * dx)
        elif c == 7:  # buoyancy
            s = params[k, 3] * temp
            ax += s * params[k, 0]
            ay += s * params[k, 1]
            az += s * params[k, 2]
    return ax, ay, az


# The kernel, compiled once as a function (the generic path) and inlined at the one call
# site of the fused particle stepper (simulate.particles), where inlining is ~10 % faster.
_accel = nb.njit(cache=True, fastmath=True)(_accel_py)
_accel_inline = nb.njit(fastmath=True, inline="always")(_accel_py)


@nb.njit(parallel=True, cache=True)
def _accel_all(codes, params, perms, t, x, v, inv_m, temp, out):
    for i in nb.prange(x.shape[0]):
        ax, ay, az = _accel(codes, params, perms, t, x[i, 0], x[i, 1], x[i, 2],
                            v[i, 0], v[i, 1], v[i, 2], inv_m[i], temp[i])
        out[i, 0] = ax
        out[i, 1] = ay
        out[i, 2] = az


def local_accel(forces, t: float, x: np.ndarray, v: np.ndarray, mass, *,
                temperature=None) -> np.ndarray:
    """Sum of the local forces' accelerations ``(n, 3)`` at positions/velocities ``(n, 3)``."""
    codes, params, perms = _pack(forces)
    n = len(x)
    inv_m = 1.0 / np.broadcast_to(np.asarray(mass, np.float64), (n,))
    temp = np.broadcast_to(np.asarray(0.0 if temperature is None else temperature,
                                      np.float64), (n,))
    out = np.empty((n, 3))
    with threads_for(n):
        _accel_all(codes, params, perms, float(t), np.ascontiguousarray(x, np.float64),
                   np.ascontiguousarray(v, np.float64), np.ascontiguousarray(inv_m),
                   np.ascontiguousarray(temp), out)
    return out


def _pack(forces):
    rows, codes, perms = [], [], []
    for f in forces:
        code, row, perm = f.pack()
        codes.append(code)
        rows.append(list(row) + [0.0] * (NPARAM - len(row)))
        perms.append(perm_table(None) if perm is None else perm)
    if not codes:
        return (np.zeros(0, np.int64), np.zeros((0, NPARAM)), np.zeros((0, 512), np.int64))
    return (np.array(codes, np.int64), np.array(rows, np.float64),
            np.ascontiguousarray(np.stack(perms).astype(np.int64)))


# -- pairwise forces through a neighbour grid ---------------------------------------

@nb.njit(parallel=True, cache=True)
def _pairwise_sum(x, inv_m, offsets, indices, radius, att, rep, out):
    for i in nb.prange(x.shape[0]):
        ax = 0.0
        ay = 0.0
        az = 0.0
        for k in range(offsets[i], offsets[i + 1]):
            j = indices[k]
            dx = x[j, 0] - x[i, 0]
            dy = x[j, 1] - x[i, 1]
            dz = x[j, 2] - x[i, 2]
            r = np.sqrt(dx * dx + dy * dy + dz * dz)
            if r == 0.0:
                continue
            w = 1.0 - r / radius
            s = (att * w - rep * w * w) / r * inv_m[i]
            ax += s * dx
            ay += s * dy
            az += s * dz
        out[i, 0] = ax
        out[i, 1] = ay
        out[i, 2] = az


def pairwise_accel(x: np.ndarray, mass, force: Pairwise) -> np.ndarray:
    """Accelerations ``(n, 3)`` from :class:`Pairwise` forces, through a uniform grid.

    Neighbours come from :func:`simulate.neighbours.neighbour_lists` (a uniform grid,
    points counting-sorted by cell, the 27 cells around each particle): cost O(n k)
    for k neighbours, summed in neighbour-index order. A non-finite position gives NaN accelerations
    (the caller detects and reports the blow-up).
    """
    x = np.ascontiguousarray(check_array(x, "x", shape=(None, 3), finite=False))
    n = len(x)
    inv_m = np.ascontiguousarray(1.0 / np.broadcast_to(np.asarray(mass, np.float64), (n,)))
    out = np.zeros((n, 3))
    if n < 2:
        return out
    if not np.all(np.isfinite(x.max(axis=0) - x.min(axis=0))):  # also an overflowing extent
        return np.full((n, 3), np.nan)
    offsets, indices = neighbour_lists(x, force.radius)
    with threads_for(n):
        _pairwise_sum(x, inv_m, offsets, indices, float(force.radius),
                      float(force.attraction), float(force.repulsion), out)
    return out


def pairwise_accel_reference(x: np.ndarray, mass, force: Pairwise) -> np.ndarray:
    """The exact O(n^2) sum of :func:`pairwise_accel` (test oracle, small n)."""
    x = np.asarray(x, np.float64)
    n = len(x)
    m = np.broadcast_to(np.asarray(mass, np.float64), (n,))
    d = x[None, :, :] - x[:, None, :]
    r = np.linalg.norm(d, axis=2)
    w = np.where((r < force.radius) & (r > 0), 1.0 - r / force.radius, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(w > 0, (force.attraction * w - force.repulsion * w * w) / r, 0.0)
    return np.einsum("ij,ijk->ik", s, d) / m[:, None]


# -- springs -------------------------------------------------------------------------

@nb.njit(cache=True)
def _springs(x, v, ii, jj, k, rest, kd, out):
    for s in range(ii.shape[0]):
        i = ii[s]
        j = jj[s]
        dx = x[j, 0] - x[i, 0]
        dy = x[j, 1] - x[i, 1]
        dz = x[j, 2] - x[i, 2]
        length = np.sqrt(dx * dx + dy * dy + dz * dz)
        if length == 0.0:
            continue
        ux = dx / length
        uy = dy / length
        uz = dz / length
        rel = (v[j, 0] - v[i, 0]) * ux + (v[j, 1] - v[i, 1]) * uy + (v[j, 2] - v[i, 2]) * uz
        f = k[s] * (length - rest[s]) + kd[s] * rel
        out[i, 0] += f * ux
        out[i, 1] += f * uy
        out[i, 2] += f * uz
        out[j, 0] -= f * ux
        out[j, 1] -= f * uy
        out[j, 2] -= f * uz


def spring_forces(x: np.ndarray, v: np.ndarray, springs: Springs, *,
                  out: np.ndarray | None = None) -> np.ndarray:
    """Forces ``(n, 3)`` (newtons) of damped springs; added into ``out`` when given."""
    x = np.ascontiguousarray(x, np.float64)
    v = np.ascontiguousarray(v, np.float64)
    ii, jj, k, r, d = springs.arrays()
    if len(ii) and (min(ii.min(), jj.min()) < 0 or max(ii.max(), jj.max()) >= len(x)):
        raise ValueError(f"pairs: expected particle indices in [0, {len(x)})")
    if out is None:
        out = np.zeros_like(x)
    _springs(x, v, ii, jj, k, r, d, out)
    return out


# -- a set of forces --------------------------------------------------------------------

class ForceSet:
    """Forces acting together; ``accel(t, x, v)`` gives the total acceleration.

    Parameters
    ----------
    forces : iterable of force objects
    """

    def __init__(self, forces=()):
        forces = list(forces)
        self.local = [f for f in forces if hasattr(f, "pack")]
        self.pairwise = [f for f in forces if isinstance(f, Pairwise)]
        self.springs = [f for f in forces if isinstance(f, Springs)]
        other = [f for f in forces if f not in self.local + self.pairwise + self.springs]
        if other:
            raise ValueError(f"forces: unknown force {type(other[0]).__name__}")
        self.codes, self.params, self.perms = _pack(self.local)

    @property
    def is_local(self) -> bool:
        """True when no force couples particles (the fused kernel can integrate them)."""
        return not self.pairwise and not self.springs

    def accel(self, t: float, x: np.ndarray, v: np.ndarray, mass, *,
              temperature=None) -> np.ndarray:
        """Total acceleration ``(n, 3)``; ``mass`` (n,) or scalar (kg)."""
        n = len(x)
        m = np.ascontiguousarray(np.broadcast_to(np.asarray(mass, np.float64), (n,)))
        temp = np.ascontiguousarray(np.broadcast_to(
            np.asarray(0.0 if temperature is None else temperature, np.float64), (n,)))
        out = np.empty((n, 3))
        with threads_for(n):
            _accel_all(self.codes, self.params, self.perms, float(t),
                       np.ascontiguousarray(x, np.float64), np.ascontiguousarray(v, np.float64),
                       1.0 / m, temp, out)
        for p in self.pairwise:
            out += pairwise_accel(x, m, p)
        if self.springs:
            f = np.zeros((n, 3))
            for s in self.springs:
                spring_forces(x, v, s, out=f)
            out += f / m[:, None]
        return out

    def stiffness(self, mass) -> tuple[float, float]:
        """Estimates ``(decay rate 1/s, angular frequency rad/s)`` for step-size checks.

        Drag and damping give rates ``drag / m`` and ``rate``; springs give
        ``sqrt(2 k_node / m)`` with ``k_node`` the largest total stiffness at one particle
        (Gershgorin's bound on the stiffness matrix).
        """
        m = np.asarray(mass, np.float64)
        m_min = float(m.min()) if m.size else 1.0
        rate = 0.0
        for code, row in zip(self.codes, self.params, strict=True):
            if code == _WIND:
                rate += row[3] / m_min
            elif code == _DAMPING:
                rate += row[0]
        omega = 0.0
        for s in self.springs:
            ii, jj, k, _, kd = s.arrays()
            if len(ii):
                n = int(max(ii.max(), jj.max())) + 1
                node = np.bincount(ii, k, n) + np.bincount(jj, k, n)
                omega = max(omega, math.sqrt(2.0 * float(node.max()) / m_min))
                node_d = np.bincount(ii, kd, n) + np.bincount(jj, kd, n)
                rate += 2.0 * float(node_d.max()) / m_min
        return rate, omega
