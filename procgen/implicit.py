"""Implicit surfaces and Perlin-Hoffert hypertexture.

A shape is a signed distance function ``sdf(points (n, 3)) -> (n,)`` (negative inside)
or an open3d triangle mesh (its signed distance from Open3D's ``RaycastingScene``).
Hypertexture turns the distance into a soft density, shapes it with Perlin's bias and
gain, perturbs it with noise or turbulence, and extracts the 0.5 isosurface with
marching cubes (VTK's flying edges, through pyvista):

    D(x) = gain(bias(clip(0.5 - (sdf(x) - amplitude N(frequency x)) / (2 thickness))))

With ``amplitude = 0`` and ``bias = gain = 0.5`` the surface is the shape itself.

>>> import numpy as np
>>> mesh = hypertexture(sphere_sdf(radius=1.0), bounds=((-1.5,) * 3, (1.5,) * 3),
...                     resolution=24, amplitude=0.0)
>>> r = np.linalg.norm(np.asarray(mesh.vertices), axis=1)
>>> bool(abs(r.mean() - 1.0) < 0.02)
True

References
----------
K. Perlin, E. M. Hoffert, "Hypertexture", SIGGRAPH 1989. doi:10.1145/74334.74359
W. E. Lorensen, H. E. Cline, "Marching cubes", SIGGRAPH 1987. doi:10.1145/37401.37422
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from core.meshes import from_pyvista, mesh_arrays
from core.validate import check_array, check_choice, check_finite, check_positive, check_range
from procgen.noise.fractal import bias as _bias
from procgen.noise.fractal import fbm, turbulence
from procgen.noise.fractal import gain as _gain

__all__ = ["sphere_sdf", "egg_sdf", "sweep_sdf", "mesh_sdf", "shell_sdf", "isosurface",
           "hypertexture", "fractal_egg", "architexture", "watertight", "SHELL_VOXELS"]

SHELL_VOXELS = 1.5  # half-width of the shell built around an open mesh, in voxels


def sphere_sdf(center=(0.0, 0.0, 0.0), radius: float = 1.0) -> Callable:
    """Signed distance to a sphere: ``|p - center| - radius``."""
    c = check_array(center, "center", shape=(3,))
    r = check_positive(radius, "radius")

    def sdf(p):
        return np.linalg.norm(p - c, axis=1) - r

    sdf.bounds = (c - r, c + r)
    return sdf


def egg_sdf(radius: float = 1.0, *, elongation: float = 1.4) -> Callable:
    """An egg about the origin along +z: a sphere of ``radius`` whose upper half is
    stretched by ``elongation`` (an approximate distance, exact on the lower half)."""
    r = check_positive(radius, "radius")
    e = check_range(elongation, "elongation", 1.0, None)

    def sdf(p):
        q = p.copy()
        top = q[:, 2] > 0
        q[top, 2] /= e
        return np.linalg.norm(q, axis=1) - r

    sdf.bounds = (np.array([-r, -r, -r]), np.array([r, r, r * e]))
    return sdf


def sweep_sdf(polyline, radius: float) -> Callable:
    """Distance field of a sphere of ``radius`` swept along a polyline (a chain of capsules).

    Parameters
    ----------
    polyline : (k, 3) float, k >= 2
    radius : float
    """
    P = check_array(polyline, "polyline", shape=(None, 3), min_rows=2)
    r = check_positive(radius, "radius")
    A = P[:-1]
    AB = P[1:] - A
    L2 = np.maximum(np.einsum("ij,ij->i", AB, AB), 1e-300)

    def sdf(p):
        best = np.full(len(p), np.inf)
        chunk = max(1, 2_000_000 // max(len(A), 1))
        for s in range(0, len(p), chunk):
            q = p[s:s + chunk, None, :] - A[None]
            t = np.clip(np.einsum("nkj,kj->nk", q, AB) / L2, 0.0, 1.0)
            d = np.linalg.norm(q - t[..., None] * AB[None], axis=2)
            best[s:s + chunk] = d.min(axis=1)
        return best - r

    sdf.bounds = (P.min(axis=0) - r, P.max(axis=0) + r)
    return sdf


def _raycasting_scene(mesh):
    """Open3D ``RaycastingScene`` of a mesh, and its vertices."""
    import open3d as o3d

    v, f = mesh_arrays(mesh)
    if len(v) == 0 or len(f) == 0:
        raise ValueError("mesh: expected a triangle mesh with triangles, got an empty mesh")
    tmesh = o3d.t.geometry.TriangleMesh()
    tmesh.vertex.positions = o3d.core.Tensor(v.astype(np.float32))
    tmesh.triangle.indices = o3d.core.Tensor(f.astype(np.int32))
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(tmesh)
    return scene, v


def _query(p):
    import open3d as o3d

    return o3d.core.Tensor(np.ascontiguousarray(p, dtype=np.float32))


def mesh_sdf(mesh) -> Callable:
    """Signed distance to a closed triangle mesh (Open3D ``RaycastingScene``; negative inside).

    Raises
    ------
    ValueError
        When the mesh has no triangles.
    """
    scene, v = _raycasting_scene(mesh)

    def sdf(p):
        return scene.compute_signed_distance(_query(p), nsamples=3).numpy().astype(np.float64)

    sdf.bounds = (v.min(axis=0), v.max(axis=0))
    return sdf


def shell_sdf(mesh, thickness: float) -> Callable:
    """Signed distance to the solid shell of half-width ``thickness`` around a surface
    (its unsigned distance minus ``thickness``): an inside for an open mesh, such as a
    reconstruction with holes or a ground sheet, where :func:`mesh_sdf` has none."""
    thickness = check_positive(thickness, "thickness")
    scene, v = _raycasting_scene(mesh)

    def sdf(p):
        return scene.compute_distance(_query(p)).numpy().astype(np.float64) - thickness

    sdf.bounds = (v.min(axis=0) - thickness, v.max(axis=0) + thickness)
    return sdf


def watertight(mesh, *, resolution: int = 128):
    """A closed version of ``mesh`` for what needs an inside (colliders, particles):
    the mesh itself when it is closed, else the surface of its shell of half-width
    ``SHELL_VOXELS`` voxels (:func:`shell_sdf`) by marching cubes on a grid of
    ``resolution`` voxels along the longest side (a voxel remesh).

    Returns ``(mesh, half_width)``: half-width 0 when the input was closed.
    """
    from core.meshes import is_closed

    v, f = mesh_arrays(mesh)
    if len(f) == 0:
        raise ValueError("mesh: expected a mesh with faces, got 0 triangles")
    if is_closed(f):
        return mesh, 0.0
    if isinstance(resolution, bool) or not isinstance(resolution, (int, np.integer)) \
            or not 16 <= resolution <= 512:
        raise ValueError(f"resolution: expected an integer in [16, 512], got {resolution!r}")
    lo, hi = v.min(axis=0), v.max(axis=0)
    pad = 0.1 * float(np.max(hi - lo))
    step = (float(np.max(hi - lo)) + 2 * pad) / (resolution - 1)
    half = SHELL_VOXELS * step
    solid = hypertexture(shell_sdf(mesh, half), bounds=(lo - pad, hi + pad),
                         resolution=resolution, amplitude=0.0)
    return solid, half


def isosurface(values, level: float, *, origin=(0.0, 0.0, 0.0), spacing=1.0):
    """Marching cubes (VTK flying edges) of a scalar grid; the canonical mesh.

    Parameters
    ----------
    values : (nx, ny, nz) float
        Samples at ``origin + (i, j, k) * spacing``.
    level : float
        Iso-value. Triangles face away from larger values (a density's outside).

    Returns
    -------
    open3d.geometry.TriangleMesh (empty when the level is not crossed)
    """
    import pyvista as pv

    vol = check_array(values, "values", shape=(None, None, None))
    lv = check_finite(level, "level")
    o = check_array(origin, "origin", shape=(3,))
    sp = np.broadcast_to(np.asarray(spacing, dtype=np.float64), (3,))
    grid = pv.ImageData(dimensions=vol.shape, spacing=tuple(sp), origin=tuple(o))
    grid.point_data["v"] = vol.ravel(order="F")
    surf = grid.contour([lv], scalars="v", method="flying_edges")
    if surf.n_cells == 0:
        from core.meshes import make_mesh

        return make_mesh(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64))
    mesh = from_pyvista(surf)
    v, f = mesh_arrays(mesh)
    # orient: the normals should point down the gradient (towards smaller values)
    centroid = v[f].mean(axis=1)
    normal = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    idx = np.clip(np.round((centroid - o) / sp).astype(np.int64), 1, np.array(vol.shape) - 2)
    gx = vol[idx[:, 0] + 1, idx[:, 1], idx[:, 2]] - vol[idx[:, 0] - 1, idx[:, 1], idx[:, 2]]
    gy = vol[idx[:, 0], idx[:, 1] + 1, idx[:, 2]] - vol[idx[:, 0], idx[:, 1] - 1, idx[:, 2]]
    gz = vol[idx[:, 0], idx[:, 1], idx[:, 2] + 1] - vol[idx[:, 0], idx[:, 1], idx[:, 2] - 1]
    agree = np.einsum("ij,ij->i", normal, np.stack([gx, gy, gz], 1))
    if np.sum(agree > 0) > np.sum(agree < 0):
        mesh.triangles = type(mesh.triangles)(np.ascontiguousarray(f[:, ::-1].astype(np.int32)))
    mesh.compute_vertex_normals()
    return mesh


def _bounds_of(shape, bounds, margin):
    if bounds is None:
        b = getattr(shape, "bounds", None)
        if b is None:
            raise ValueError("bounds: required for a signed distance function without .bounds")
        lo, hi = np.asarray(b[0], np.float64), np.asarray(b[1], np.float64)
        pad = margin + 0.05 * np.max(hi - lo)
        return lo - pad, hi + pad
    lo = check_array(bounds[0], "bounds[0]", shape=(3,))
    hi = check_array(bounds[1], "bounds[1]", shape=(3,))
    if np.any(hi <= lo):
        raise ValueError(f"bounds: expected lower < upper corner, got {lo} and {hi}")
    return lo, hi


def hypertexture(shape, *, bounds=None, resolution: int = 96, thickness: float | None = None,
                 noise: str = "turbulence", amplitude: float = 0.1, frequency: float = 4.0,
                 octaves: int = 5, bias: float = 0.5, gain: float = 0.5,
                 seed: int | None = None):
    """Perlin-Hoffert hypertexture of a shape, as a triangle mesh.

    Parameters
    ----------
    shape : callable or open3d.geometry.TriangleMesh
        A signed distance function ``(n, 3) -> (n,)`` (negative inside), or a closed mesh
        (e.g. a reconstruction to amplify) whose signed distance Open3D computes.
    bounds : ((3,), (3,)) float, optional
        Box sampled; default: the shape's bounds grown by the noise amplitude.
    resolution : int
        Samples along the longest side of the box (8 to 512).
    thickness : float, optional
        Half-width of the soft shell where density falls from 1 to 0 (default: 2 voxels).
    noise : {'turbulence', 'fbm'}
        Perturbation of the distance: ``amplitude * N(frequency * x)``.
    amplitude, frequency : float
        In metres and cycles per metre.
    octaves : int
    bias, gain : float
        Perlin's density modulation, in (0, 1); 0.5 leaves the density unchanged.
    seed : int or None
        Noise permutation.

    Returns
    -------
    open3d.geometry.TriangleMesh
        The 0.5 isosurface of the density, normals outwards.

    Raises
    ------
    ValueError
        An empty mesh, a bad option.
    """
    if hasattr(shape, "triangles") and hasattr(shape, "vertices"):
        sdf = mesh_sdf(shape)
    elif callable(shape):
        sdf = shape
    else:
        raise ValueError(f"shape: expected a signed distance function or a triangle mesh, "
                         f"got {type(shape).__name__}")
    noise = check_choice(noise, "noise", {"turbulence", "fbm"})
    amp = check_positive(amplitude, "amplitude", allow_zero=True)
    freq = check_positive(frequency, "frequency")
    b = check_range(bias, "bias", 0.0, 1.0, lo_open=True, hi_open=True)
    g = check_range(gain, "gain", 0.0, 1.0, lo_open=True, hi_open=True)
    if isinstance(resolution, bool) or not isinstance(resolution, (int, np.integer)) \
            or not 8 <= resolution <= 512:
        raise ValueError(f"resolution: expected an integer in [8, 512], got {resolution!r}")
    lo, hi = _bounds_of(sdf, bounds, 1.5 * amp)
    step = float(np.max(hi - lo)) / (resolution - 1)
    th = 2.0 * step if thickness is None else check_positive(thickness, "thickness")
    dims = np.maximum(np.ceil((hi - lo) / step).astype(np.int64) + 1, 2)
    axes = [lo[k] + step * np.arange(dims[k]) for k in range(3)]
    X, Y, Z = np.meshgrid(*axes, indexing="ij")
    pts = np.stack([X.ravel(), Y.ravel(), Z.ravel()], 1)
    d = np.asarray(sdf(pts), dtype=np.float64).reshape(-1)
    if d.shape[0] != pts.shape[0] or not np.all(np.isfinite(d)):
        raise ValueError("shape: the signed distance function must return (n,) finite values")
    if amp > 0:
        q = pts * freq
        fn = turbulence if noise == "turbulence" else fbm
        d = d - amp * fn(q[:, 0], q[:, 1], q[:, 2], octaves=octaves, seed=seed)
    dens = np.clip(0.5 - d / (2.0 * th), 0.0, 1.0)
    if b != 0.5:
        dens = _bias(dens, b)
    if g != 0.5:
        dens = _gain(dens, g)
    mesh = isosurface(dens.reshape(tuple(dims)), 0.5, origin=lo, spacing=step)
    if len(mesh.triangles) == 0:
        raise RuntimeError("hypertexture: the density never crosses 0.5 inside the bounds")
    return mesh


def fractal_egg(*, radius: float = 1.0, elongation: float = 1.4, amplitude: float = 0.08,
                frequency: float = 3.0, octaves: int = 6, resolution: int = 96,
                seed: int | None = None):
    """Perlin's fractal egg: an egg whose surface is displaced by fBm (a hypertexture)."""
    return hypertexture(egg_sdf(radius, elongation=elongation), noise="fbm",
                        amplitude=amplitude, frequency=frequency, octaves=octaves,
                        resolution=resolution, seed=seed)


def architexture(polyline, radius: float, *, amplitude: float = 0.05, frequency: float = 6.0,
                 octaves: int = 5, noise: str = "turbulence", resolution: int = 96,
                 seed: int | None = None):
    """Architexture: a sphere swept along a polyline, as a distance field, hypertextured.

    Parameters
    ----------
    polyline : (k, 3) float
    radius : float
        Radius of the swept sphere.

    Returns
    -------
    open3d.geometry.TriangleMesh
    """
    return hypertexture(sweep_sdf(polyline, radius), noise=noise, amplitude=amplitude,
                        frequency=frequency, octaves=octaves, resolution=resolution, seed=seed)
