"""Spring-mass cloth (Provot 1995): a grid of masses joined by stretch, shear and bend springs.

* stretch springs join grid neighbours ``(i, j)-(i+1, j)`` and ``(i, j)-(i, j+1)``;
  shear springs the diagonals; bend springs every second vertex along rows and columns;
* pinned vertices do not move; gravity, wind and other local forces of
  :mod:`simulate.forces` act on every free vertex;
* strain limiting in the manner of Provot: after each step, stretch and shear springs
  longer than ``(1 + max_strain)`` times their rest length are shortened by moving
  their ends toward each other (only the free end when one is pinned), a few
  Gauss-Seidel passes, velocities corrected by the displacement over the step;
* vertices collide with a mesh through :func:`simulate.collisions.collide`.

Integrator and step size: symplectic Euler by default. It is stable while
``h omega_max < 2`` with ``omega_max^2 <= 2 K / m`` (Gershgorin), ``K`` the largest
sum of spring stiffnesses at a vertex (``4 k_stretch + 4 k_shear + 4 k_bend`` inside
the grid) and ``m`` the vertex mass; :meth:`Cloth.stable_step` returns that limit
(RK4 allows ``2 sqrt 2 / omega_max``) and a larger step logs a warning. Spring damping
``c`` adds a decay rate ``<= 2 C / m`` (``C`` the sum at a vertex) limited by ``2 / rate``.

References
----------
X. Provot, "Deformation constraints in a mass-spring model to describe rigid cloth
behavior", Graphics Interface 1995. doi:10.20380/GI1995.17
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numba as nb
import numpy as np

from core.validate import check_array, check_choice, check_int, check_positive
from simulate.collisions import CollisionStats, ContactParams, collide
from simulate.forces import ForceSet, Springs
from simulate.integrators import METHODS, check_step, stability_limit
from simulate.integrators import step as generic_step

log = logging.getLogger(__name__)

__all__ = ["Cloth", "ClothSpec", "grid_cloth"]


@dataclass(frozen=True)
class ClothSpec:
    """A rectangular cloth.

    Attributes
    ----------
    nx, ny : int
        Vertices along the two grid axes (>= 2).
    spacing : float
        Rest distance between grid neighbours (m).
    origin : (3,) float
        Position of vertex (0, 0).
    axis_u, axis_v : (3,) float
        Unit grid directions (default: a horizontal sheet in the XY plane).
    mass : float
        Total mass (kg), spread evenly over the vertices.
    k_stretch, k_shear, k_bend : float
        Spring stiffnesses (N/m).
    damping : float
        Spring damping along each spring (N s/m), all kinds.
    pinned : tuple of int
        Indices ``i + nx * j`` of pinned vertices.
    max_strain : float or None
        Provot's critical deformation rate (0.1 = 10 %); None disables strain limiting.
    strain_iterations : int
    """

    nx: int = 20
    ny: int = 20
    spacing: float = 0.05
    origin: tuple = (0.0, 0.0, 1.0)
    axis_u: tuple = (1.0, 0.0, 0.0)
    axis_v: tuple = (0.0, 1.0, 0.0)
    mass: float = 0.2
    k_stretch: float = 200.0
    k_shear: float = 50.0
    k_bend: float = 10.0
    damping: float = 0.02
    pinned: tuple = ()
    max_strain: float | None = 0.1
    strain_iterations: int = 20

    def __post_init__(self):
        for name in ("nx", "ny"):
            check_int(getattr(self, name), name, 2)
        for name in ("spacing", "mass"):
            check_positive(getattr(self, name), name)
        for name in ("k_stretch", "k_shear", "k_bend", "damping"):
            check_positive(getattr(self, name), name, allow_zero=True)
        if self.max_strain is not None:
            check_positive(self.max_strain, "max_strain")
        n = self.nx * self.ny
        for p in self.pinned:
            if int(p) != p or not 0 <= p < n:
                raise ValueError(f"pinned: expected vertex indices in [0, {n}), got {p!r}")


def grid_cloth(spec: ClothSpec):
    """Rest positions, triangles and springs of a grid cloth.

    Returns
    -------
    x : (nx*ny, 3) float64
    triangles : (2 (nx-1)(ny-1), 3) int64
    springs : dict kind -> (m, 2) int64 with kinds ``stretch``, ``shear``, ``bend``
    """
    nx, ny = spec.nx, spec.ny
    u = check_array(spec.axis_u, "axis_u", shape=(3,))
    v = check_array(spec.axis_v, "axis_v", shape=(3,))
    o = check_array(spec.origin, "origin", shape=(3,))
    i, j = np.meshgrid(np.arange(nx), np.arange(ny))
    i, j = i.ravel(), j.ravel()
    x = o + spec.spacing * (i[:, None] * u + j[:, None] * v)

    def idx(a, b):
        return a + nx * b

    ii, jj = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1))
    ii, jj = ii.ravel(), jj.ravel()
    a, b, c, d = idx(ii, jj), idx(ii + 1, jj), idx(ii, jj + 1), idx(ii + 1, jj + 1)
    tris = np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])
    hi, hj = np.meshgrid(np.arange(nx - 1), np.arange(ny))
    vi, vj = np.meshgrid(np.arange(nx), np.arange(ny - 1))
    stretch = np.concatenate([
        np.stack([idx(hi, hj).ravel(), idx(hi + 1, hj).ravel()], 1),
        np.stack([idx(vi, vj).ravel(), idx(vi, vj + 1).ravel()], 1)])
    shear = np.concatenate([np.stack([a, d], 1), np.stack([b, c], 1)])
    bi, bj = np.meshgrid(np.arange(nx - 2), np.arange(ny))
    ci, cj = np.meshgrid(np.arange(nx), np.arange(ny - 2))
    bend = np.concatenate([
        np.stack([idx(bi, bj).ravel(), idx(bi + 2, bj).ravel()], 1),
        np.stack([idx(ci, cj).ravel(), idx(ci, cj + 2).ravel()], 1)])
    return x, tris.astype(np.int64), {"stretch": stretch.astype(np.int64),
                                      "shear": shear.astype(np.int64),
                                      "bend": bend.astype(np.int64)}


@nb.njit(cache=True)
def _limit_strain(x, pairs, rest, inv_w, max_ratio, iterations):
    for _ in range(iterations):
        changed = False
        for s in range(pairs.shape[0]):
            i = pairs[s, 0]
            j = pairs[s, 1]
            wi = inv_w[i]
            wj = inv_w[j]
            if wi + wj == 0.0:
                continue
            dx = x[j, 0] - x[i, 0]
            dy = x[j, 1] - x[i, 1]
            dz = x[j, 2] - x[i, 2]
            length = np.sqrt(dx * dx + dy * dy + dz * dz)
            limit = max_ratio * rest[s]
            if length <= limit or length == 0.0:
                continue
            corr = (length - limit) / length / (wi + wj)
            x[i, 0] += wi * corr * dx
            x[i, 1] += wi * corr * dy
            x[i, 2] += wi * corr * dz
            x[j, 0] -= wj * corr * dx
            x[j, 1] -= wj * corr * dy
            x[j, 2] -= wj * corr * dz
            changed = True
        if not changed:
            break


@dataclass
class Cloth:
    """A simulated cloth.

    Parameters
    ----------
    spec : ClothSpec
    forces : ForceSet
        Local forces (gravity, wind, turbulence, damping) acting on the vertices.
    method : str
        Integrator (default ``symplectic_euler``).
    collider : MeshCollider, optional
    contact : ContactParams
    """

    spec: ClothSpec
    forces: ForceSet = field(default_factory=ForceSet)
    method: str = "symplectic_euler"
    collider: object = None
    contact: ContactParams = field(default_factory=lambda: ContactParams(
        restitution=0.0, friction=0.4, rest_speed=0.05))

    def __post_init__(self):
        check_choice(self.method, "method", METHODS)
        if not self.forces.is_local:
            raise ValueError("forces: cloth takes local forces only (its springs are built in)")
        s = self.spec
        self.x, self.triangles, self.spring_pairs = grid_cloth(s)
        self.rest_x = self.x.copy()
        self.v = np.zeros_like(self.x)
        n = len(self.x)
        self.vertex_mass = s.mass / n
        self.pinned = np.zeros(n, bool)
        self.pinned[list(s.pinned)] = True
        pairs, k, rest = [], [], []
        for kind, stiff in (("stretch", s.k_stretch), ("shear", s.k_shear),
                            ("bend", s.k_bend)):
            p = self.spring_pairs[kind]
            pairs.append(p)
            k.append(np.full(len(p), float(stiff)))
            rest.append(np.linalg.norm(self.x[p[:, 1]] - self.x[p[:, 0]], axis=1))
        self.springs = Springs(np.concatenate(pairs), np.concatenate(k), np.concatenate(rest),
                               s.damping)
        self._all = ForceSet([*self.forces.local, self.springs])
        limited = np.concatenate([self.spring_pairs["stretch"], self.spring_pairs["shear"]])
        self._limit_pairs = limited
        self._limit_rest = np.linalg.norm(self.x[limited[:, 1]] - self.x[limited[:, 0]], axis=1)
        self.t = 0.0
        self.steps = 0

    @property
    def omega_max(self) -> float:
        """Gershgorin bound on the highest angular frequency (rad/s)."""
        return self._all.stiffness(self.vertex_mass)[1]

    def stable_step(self) -> float:
        """Largest stable step of the integrator for the springs (and their damping)."""
        rate, omega = self._all.stiffness(self.vertex_mass)
        return stability_limit(self.method, rate=rate, omega=omega)

    def _deriv(self, t, y):
        m = np.full(len(y[0]), self.vertex_mass)
        a = self._all.accel(t, y[0], y[1], m)
        a[self.pinned] = 0.0
        vel = y[1].copy()
        vel[self.pinned] = 0.0
        return np.stack([vel, a])

    def step(self, h: float) -> CollisionStats:
        """Advance by one step ``h`` (s)."""
        x0, v0 = self.x.copy(), self.v.copy()
        y = generic_step(self._deriv, self.t, np.stack([x0, v0]), h, method=self.method)
        x, v = y[0], y[1]
        if self.spec.max_strain is not None:
            before = x.copy()
            inv_w = np.where(self.pinned, 0.0, 1.0)
            _limit_strain(x, self._limit_pairs, self._limit_rest, inv_w,
                          1.0 + float(self.spec.max_strain), int(self.spec.strain_iterations))
            v += (x - before) / h
        stats = CollisionStats()
        if self.collider is not None:
            free = ~self.pinned
            xf, vf, stats = collide(self.collider, x0[free], v0[free], x[free], v[free], h,
                                    self.contact)
            x[free], v[free] = xf, vf
        x[self.pinned] = x0[self.pinned]
        v[self.pinned] = 0.0
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(v))):
            bad = int(np.argmax(~np.all(np.isfinite(x), 1) | ~np.all(np.isfinite(v), 1)))
            raise RuntimeError(f"non-finite state at step {self.steps + 1} (t = {self.t:.6g} s),"
                               f" vertex {bad}: the run was stopped (reduce the step size)")
        self.x, self.v = x, v
        self.t += h
        self.steps += 1
        return stats

    def advance(self, dt: float, substeps: int) -> CollisionStats:
        """One frame: ``substeps`` steps of ``dt / substeps``; warns beyond the stable step."""
        h = dt / substeps
        if self.steps == 0:
            rate, omega = self._all.stiffness(self.vertex_mass)
            check_step(self.method, h, rate=rate, omega=omega, what="dt / substeps")
        total = CollisionStats()
        for _ in range(substeps):
            st = self.step(h)
            total.impacts += st.impacts
            total.resting += st.resting
        return total

    def stretch(self) -> np.ndarray:
        """Length / rest length of every stretch spring ``(m,)``."""
        p = self.spring_pairs["stretch"]
        rest = np.linalg.norm(self.rest_x[p[:, 1]] - self.rest_x[p[:, 0]], axis=1)
        return np.linalg.norm(self.x[p[:, 1]] - self.x[p[:, 0]], axis=1) / rest

    def energy(self) -> dict:
        """Kinetic, gravitational potential and spring energies (J)."""
        m = self.vertex_mass
        g = np.zeros(3)
        for code, row in zip(self.forces.codes, self.forces.params, strict=True):
            if code == 0:
                g += row[:3]
        ii, jj, k, rest, _ = self.springs.arrays()
        length = np.linalg.norm(self.x[jj] - self.x[ii], axis=1)
        return {"kinetic": float(0.5 * m * np.sum(self.v ** 2)),
                "potential": float(-m * np.sum(self.x @ g)),
                "elastic": float(0.5 * np.sum(k * (length - rest) ** 2))}
