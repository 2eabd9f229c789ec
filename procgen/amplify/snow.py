"""Snow cover: a layer on the parts of a surface that face the sky and see it.

Snow settles where the surface is not too steep and nothing above shelters it. Each
vertex whose upward ray (along +z, from just off the surface) escapes the mesh gets a
depth that grows with how level the surface is there,

    depth_i = depth * smoothstep(cos(slope_max), 1, n_i . z) * (1 + drift * z_i)

(``n_i`` the unit vertex normal, ``z_i`` standardised fBm noise clipped to keep the factor
in [0, 2]: wind drifts), so flat ground carries the full depth, a slope at ``slope_max``
none, and no vertex under an overhang any. The layer is the covered triangles lifted by
their depths along +z: its own mesh, laid on the surface.

>>> import numpy as np
>>> from procgen.terrain import heightfield_to_mesh
>>> ground = heightfield_to_mesh(np.zeros((5, 5)), spacing=1.0)
>>> res = snow_cover(ground, rng=np.random.default_rng(0), depth=0.1, drift=0.0)
>>> bool(np.allclose(res.depth, 0.1)), res.covered_fraction
(True, 1.0)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.meshes import compact, make_mesh, vertex_normals
from core.validate import check_positive, check_range, check_rng
from procgen.amplify.surface import mesh_input, smoothstep
from procgen.noise.fractal import fbm

__all__ = ["SnowResult", "snow_cover", "sky_visible"]


@dataclass
class SnowResult:
    """``mesh``: the snow layer (None when nothing is covered); ``depth (n,)``: depth per
    input vertex (0 where bare); ``sky (n,)``: which vertices see the sky."""

    mesh: object
    depth: np.ndarray
    sky: np.ndarray

    @property
    def covered_fraction(self) -> float:
        return float(np.mean(self.depth > 0))


def sky_visible(vertices: np.ndarray, triangles: np.ndarray, normals: np.ndarray, *,
                offset: float, points: np.ndarray | None = None) -> np.ndarray:
    """Which points' upward rays (+z, started ``offset`` off the surface along their
    ``normals``) leave the mesh ``(vertices, triangles)`` without hitting it; the points
    are the vertices unless given."""
    import open3d as o3d

    tmesh = o3d.t.geometry.TriangleMesh()
    tmesh.vertex.positions = o3d.core.Tensor(np.asarray(vertices, np.float32))
    tmesh.triangle.indices = o3d.core.Tensor(np.asarray(triangles, np.int32))
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(tmesh)
    origin = (vertices if points is None else points) + offset * normals
    rays = np.hstack([origin, np.tile([0.0, 0.0, 1.0], (len(origin), 1))]).astype(np.float32)
    hit = scene.test_occlusions(o3d.core.Tensor(rays)).numpy()
    return ~hit.astype(bool)


def snow_cover(mesh, *, rng: np.random.Generator, depth: float, slope_max_deg: float = 60.0,
               drift: float = 0.3, drift_wavelength: float | None = None) -> SnowResult:
    """A snow layer on ``mesh`` (up is +z; see the module docstring).

    Parameters
    ----------
    mesh : open3d.geometry.TriangleMesh
    rng : numpy.random.Generator
        Draws the drift noise.
    depth : float
        Depth on level ground, metres (> 0).
    slope_max_deg : float
        No snow at or beyond this slope (0 level, 90 vertical), in (0, 90].
    drift : float
        Relative variation of the depth by fBm noise, in [0, 1].
    drift_wavelength : float, optional
        Wavelength of the drift noise, metres (default: 20 depths).

    Returns
    -------
    SnowResult
    """
    rng = check_rng(rng)
    v, f = mesh_input(mesh)
    depth = check_positive(depth, "depth")
    check_range(slope_max_deg, "slope_max_deg", 0.0, 90.0, lo_open=True)
    check_range(drift, "drift", 0.0, 1.0)
    wl = 20.0 * depth if drift_wavelength is None else check_positive(drift_wavelength,
                                                                      "drift_wavelength")
    n = vertex_normals(v, f)
    sky = sky_visible(v, f, n, offset=1e-3 * depth)
    level = smoothstep(n[:, 2], float(np.cos(np.radians(slope_max_deg))), 1.0)
    d = depth * level * sky
    if drift > 0:
        seed = int(rng.integers(0, 2 ** 31 - 1))
        q = v / wl
        z = np.asarray(fbm(q[:, 0], q[:, 1], q[:, 2], octaves=4, seed=seed), np.float64)
        z = (z - z.mean()) / max(float(z.std()), 1e-300)
        d = d * np.clip(1.0 + drift * z, 0.0, 2.0)
    covered = np.all(d[f] > 0, axis=1)
    layer = None
    if covered.any():
        used, tris = compact(f[covered])
        layer = make_mesh(v[used] + np.outer(d[used], [0.0, 0.0, 1.0]), tris)
    return SnowResult(mesh=layer, depth=d, sky=sky)
