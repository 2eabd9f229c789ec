"""Where and how particles are born: shapes, birth counts, velocity and lifetime draws.

Shapes sample positions (and a surface normal used by velocity distributions):
:class:`PointShape`, :class:`DiscShape`, :class:`BoxShape`, :class:`MeshSurface`
(area-weighted, uniform over a mesh such as a scan). Births per frame are
``max(0, round(N(mean, std)))`` (:func:`birth_count`). :class:`VelocityDist` draws
initial velocities; :class:`Emitter` ties them with lifetimes, mass and temperature.
Everything takes an ``rng: numpy.random.Generator``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from core.validate import check_array, check_choice, check_positive, check_unit_vector

__all__ = ["PointShape", "DiscShape", "BoxShape", "MeshSurface", "VelocityDist", "Emitter",
           "birth_count", "normal_clamped", "birth_count_moments"]


def _basis(n):
    """Two unit vectors orthogonal to unit ``n`` (3,)."""
    helper = np.array([1.0, 0, 0]) if abs(n[0]) < 0.9 else np.array([0, 1.0, 0])
    u = np.cross(n, helper)
    u /= np.linalg.norm(u)
    return u, np.cross(n, u)


@dataclass(frozen=True)
class PointShape:
    """All particles born at ``position``; normal ``+Z``."""

    position: tuple = (0.0, 0.0, 0.0)

    def sample(self, n: int, rng: np.random.Generator):
        p = check_array(self.position, "position", shape=(3,))
        return np.tile(p, (n, 1)), np.tile([0.0, 0.0, 1.0], (n, 1))


@dataclass(frozen=True)
class DiscShape:
    """Uniform over a disc of ``radius`` at ``center`` facing ``normal``."""

    center: tuple = (0.0, 0.0, 0.0)
    normal: tuple = (0.0, 0.0, 1.0)
    radius: float = 0.1

    def sample(self, n: int, rng: np.random.Generator):
        c = check_array(self.center, "center", shape=(3,))
        nn = check_unit_vector(self.normal, "normal")
        u, w = _basis(nn)
        r = check_positive(self.radius, "radius", allow_zero=True) * np.sqrt(rng.random(n))
        phi = rng.uniform(0, 2 * np.pi, n)
        pts = c + (r * np.cos(phi))[:, None] * u + (r * np.sin(phi))[:, None] * w
        return pts, np.tile(nn, (n, 1))


@dataclass(frozen=True)
class BoxShape:
    """Uniform inside the axis-aligned box ``[lo, hi]``; normal ``+Z``."""

    lo: tuple = (-0.5, -0.5, -0.5)
    hi: tuple = (0.5, 0.5, 0.5)

    def sample(self, n: int, rng: np.random.Generator):
        lo = check_array(self.lo, "lo", shape=(3,))
        hi = check_array(self.hi, "hi", shape=(3,))
        if np.any(hi < lo):
            raise ValueError(f"hi: expected hi >= lo on every axis, got lo={lo}, hi={hi}")
        return lo + rng.random((n, 3)) * (hi - lo), np.tile([0.0, 0.0, 1.0], (n, 1))


class MeshSurface:
    """Uniform over a triangle mesh's surface (triangles picked by area).

    Parameters
    ----------
    vertices : (n, 3) float64
    triangles : (m, 3) int
    offset : float
        Distance along the face normal at which particles are born (m).
    """

    def __init__(self, vertices: np.ndarray, triangles: np.ndarray, *, offset: float = 0.0):
        self.v = check_array(vertices, "vertices", shape=(None, 3))
        self.f = check_array(triangles, "triangles", shape=(None, 3), dtype=np.int64)
        e1 = self.v[self.f[:, 1]] - self.v[self.f[:, 0]]
        e2 = self.v[self.f[:, 2]] - self.v[self.f[:, 0]]
        cr = np.cross(e1, e2)
        self.area = 0.5 * np.linalg.norm(cr, axis=1)
        total = self.area.sum()
        if not total > 0:
            raise ValueError("mesh: expected triangles with positive total area, got 0")
        self.normals = cr / np.where(self.area > 0, 2 * self.area, 1.0)[:, None]
        self.cdf = np.cumsum(self.area) / total
        self.offset = float(offset)

    @classmethod
    def from_mesh(cls, mesh, *, offset: float = 0.0) -> MeshSurface:
        from core.meshes import mesh_arrays

        return cls(*mesh_arrays(mesh), offset=offset)

    def sample(self, n: int, rng: np.random.Generator):
        tri = np.minimum(np.searchsorted(self.cdf, rng.random(n), side="right"),
                         len(self.cdf) - 1)
        r1 = np.sqrt(rng.random(n))
        r2 = rng.random(n)
        f = self.f[tri]
        p = ((1 - r1)[:, None] * self.v[f[:, 0]] + (r1 * (1 - r2))[:, None] * self.v[f[:, 1]]
             + (r1 * r2)[:, None] * self.v[f[:, 2]])
        nrm = self.normals[tri]
        return p + self.offset * nrm, nrm


def normal_clamped(rng: np.random.Generator, mean: float, std: float, size=None, *,
                   minimum: float = 0.0):
    """Normal draws clamped below at ``minimum``."""
    return np.maximum(rng.normal(mean, std, size), minimum)


def birth_count(rng: np.random.Generator, mean: float, std: float) -> int:
    """Births in one frame: ``max(0, round(N(mean, std)))``."""
    return int(max(0.0, np.rint(rng.normal(mean, std)))) if std > 0 else \
        int(max(0.0, np.rint(mean)))


def birth_count_moments(mean: float, std: float) -> tuple[float, float]:
    """Exact mean and variance of :func:`birth_count` (for tests and reports)."""
    from scipy.stats import norm

    if std == 0:
        k = max(0.0, float(np.rint(mean)))
        return k, 0.0
    kmax = int(np.ceil(mean + 12 * std)) + 2
    k = np.arange(0, kmax + 1)
    upper = norm.cdf((k + 0.5 - mean) / std)
    lower = np.where(k == 0, 0.0, norm.cdf((k - 0.5 - mean) / std))
    p = upper - lower
    m = float(np.sum(k * p))
    return m, float(np.sum((k - m) ** 2 * p))


@dataclass(frozen=True)
class VelocityDist:
    """Initial velocities.

    kind:
      ``"cone"``     speed ``N(speed, speed_std)`` in a cone of ``spread_deg`` about
                     ``direction`` (uniform over the spherical cap);
      ``"normal"``   the same cone about each birth point's surface normal;
      ``"sphere"``   isotropic directions;
      ``"gaussian"`` ``direction * speed + N(0, speed_std)`` per component.
    """

    kind: str = "cone"
    direction: tuple = (0.0, 0.0, 1.0)
    speed: float = 1.0
    speed_std: float = 0.0
    spread_deg: float = 15.0

    def sample(self, normals: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        check_choice(self.kind, "kind", ("cone", "normal", "sphere", "gaussian"))
        n = len(normals)
        if self.kind == "gaussian":
            d = check_array(self.direction, "direction", shape=(3,))
            return d * self.speed + rng.normal(0.0, self.speed_std, (n, 3))
        speed = np.maximum(rng.normal(self.speed, self.speed_std, n), 0.0) \
            if self.speed_std > 0 else np.full(n, float(self.speed))
        if self.kind == "sphere":
            d = rng.normal(size=(n, 3))
            d /= np.linalg.norm(d, axis=1, keepdims=True)
            return d * speed[:, None]
        axes = (np.tile(check_unit_vector(self.direction, "direction"), (n, 1))
                if self.kind == "cone" else np.asarray(normals, np.float64))
        cos_max = np.cos(np.radians(self.spread_deg))
        cz = 1.0 - rng.random(n) * (1.0 - cos_max)
        phi = rng.uniform(0, 2 * np.pi, n)
        sz = np.sqrt(np.maximum(0.0, 1.0 - cz * cz))
        out = np.empty((n, 3))
        for i0 in range(0, n, 65536):  # per-particle frames, in chunks
            ax = axes[i0:i0 + 65536]
            helper = np.where((np.abs(ax[:, 0]) < 0.9)[:, None], [1.0, 0, 0], [0, 1.0, 0])
            u = np.cross(ax, helper)
            u /= np.linalg.norm(u, axis=1, keepdims=True)
            w = np.cross(ax, u)
            sl = slice(i0, i0 + len(ax))
            out[sl] = (cz[sl, None] * ax + (sz[sl] * np.cos(phi[sl]))[:, None] * u
                       + (sz[sl] * np.sin(phi[sl]))[:, None] * w)
        return out * speed[:, None]


@dataclass
class Emitter:
    """A particle source.

    Attributes
    ----------
    shape : PointShape | DiscShape | BoxShape | MeshSurface
    rate : float
        Mean births per frame; ``rate_std`` their standard deviation.
    velocity : VelocityDist
    lifetime, lifetime_std : float
        Lifetime draws (s), clamped at 1e-6.
    mass : float
        kg.
    temperature, temperature_std : float
        Initial temperature draws (for buoyancy and colour by temperature).
    start, stop : float
        Emission window (s); ``stop`` may be ``inf``.
    burst_of : str or None
        Name of another emitter: this one fires at each death of that emitter's
        particles (``rate`` births per death), at the dead particle's position, adding
        ``inherit`` times its velocity (fireworks).
    name : str
    """

    shape: object = field(default_factory=PointShape)
    rate: float = 10.0
    rate_std: float = 0.0
    velocity: VelocityDist = field(default_factory=VelocityDist)
    lifetime: float = 2.0
    lifetime_std: float = 0.0
    mass: float = 1.0
    temperature: float = 0.0
    temperature_std: float = 0.0
    start: float = 0.0
    stop: float = float("inf")
    burst_of: str | None = None
    inherit: float = 1.0
    name: str = "emitter"

    def __post_init__(self):
        check_positive(self.rate, "rate", allow_zero=True)
        check_positive(self.rate_std, "rate_std", allow_zero=True)
        check_positive(self.lifetime, "lifetime")
        check_positive(self.mass, "mass")

    def births(self, t: float, rng: np.random.Generator) -> int:
        """Number of particles born in the frame starting at ``t``."""
        if self.burst_of is not None or not (self.start <= t < self.stop):
            return 0
        return birth_count(rng, self.rate, self.rate_std)

    def spawn(self, n: int, rng: np.random.Generator, *, at: np.ndarray | None = None,
              base_velocity: np.ndarray | None = None) -> dict:
        """Draw ``n`` particles: dict of ``x, v (n, 3)``, ``lifetime, mass, temperature (n,)``.

        ``at (n, 3)`` overrides the shape (bursts); ``base_velocity (n, 3)`` is added
        times ``inherit``.
        """
        if at is None:
            x, nrm = self.shape.sample(n, rng)
        else:
            x = np.asarray(at, np.float64)
            nrm = np.tile([0.0, 0.0, 1.0], (n, 1))
        v = self.velocity.sample(nrm, rng)
        if base_velocity is not None:
            v = v + self.inherit * np.asarray(base_velocity, np.float64)
        life = normal_clamped(rng, self.lifetime, self.lifetime_std, n, minimum=1e-6) \
            if self.lifetime_std > 0 else np.full(n, float(self.lifetime))
        temp = rng.normal(self.temperature, self.temperature_std, n) \
            if self.temperature_std > 0 else np.full(n, float(self.temperature))
        return {"x": x, "v": v, "lifetime": life, "mass": np.full(n, float(self.mass)),
                "temperature": temp}
