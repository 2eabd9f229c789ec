"""Noise displacement: subdivide a mesh to a target edge length, then push every vertex
along its normal by fractal noise (fBm, turbulence or ridged multifractal) scaled to the
local sample spacing — fractal detail beyond a scan's resolution.

>>> import numpy as np, open3d as o3d
>>> from procgen.amplify import displace
>>> ball = o3d.geometry.TriangleMesh.create_sphere(1.0, 10)
>>> out = displace(ball, rng=np.random.default_rng(0), target_edge=0.2, amplitude=0.1)
>>> bool(out.max_edge <= 0.2), round(out.rms_relative, 12)
(True, 0.1)

References
----------
R. L. Cook, "Shade trees", SIGGRAPH 1984 (displacement mapping). doi:10.1145/800031.808602
F. K. Musgrave, in Ebert et al., *Texturing and Modeling*, 3rd ed. 2003 (fBm, ridged).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.meshes import bbox_diagonal, edge_lengths, make_mesh, surface_area, vertex_normals
from core.validate import (
    check_choice,
    check_finite,
    check_int,
    check_positive,
    check_range,
    check_rng,
)
from procgen.amplify.surface import (
    curvature,
    local_edge_length,
    mesh_input,
    slope_deg,
    smoothstep,
    split_long_edges,
)
from procgen.noise.fractal import fbm, ridged, turbulence

__all__ = ["displace", "subdivide_to_edge", "DisplaceResult", "NOISES", "MASKS", "SCALES"]

NOISES = ("fbm", "turbulence", "ridged")
MASKS = ("none", "slope", "curvature")
SCALES = ("local", "global")


@dataclass
class DisplaceResult:
    """What :func:`displace` made.

    Attributes
    ----------
    mesh : open3d.geometry.TriangleMesh
        The displaced mesh (vertex normals recomputed).
    base_vertices : (n, 3) float64
        The subdivided, not yet displaced vertices (same order and triangles as ``mesh``).
    normals : (n, 3) float64
        Unit area-weighted normals of the subdivided mesh: the displacement directions.
    offset : (n,) float64
        Signed displacement along ``normals`` in metres.
    scale : (n,) float64
        Local scale ``h`` the amplitude is relative to.
    mask : (n,) float64
        Mask in [0, 1].
    levels : int
        Rounds of longest-edge bisection applied.
    target_edge : float or None
        The target edge used: the one asked for, lengthened when the triangle budget
        needed it (None: no subdivision).
    max_edge : float
        Longest edge after subdivision (<= the target edge length).
    """

    mesh: object
    base_vertices: np.ndarray
    normals: np.ndarray
    offset: np.ndarray
    scale: np.ndarray
    mask: np.ndarray
    levels: int
    max_edge: float
    target_edge: float | None = None

    @property
    def rms_relative(self) -> float:
        """RMS over vertices of ``offset / scale`` (the amplitude when the mask is 1)."""
        return float(np.sqrt(np.mean((self.offset / self.scale) ** 2)))


def subdivide_to_edge(vertices: np.ndarray, triangles: np.ndarray, target_edge: float, *,
                      attributes: np.ndarray | None = None, max_triangles: int = 2_000_000):
    """Split the edges longer than ``target_edge`` (metres) until none is, within a budget.

    Longest-edge bisection (:func:`procgen.amplify.surface.split_long_edges`) refines
    only where the mesh is coarser than the target, so a reconstruction whose edges vary
    widely is not multiplied everywhere by its longest edge. When the result would pass
    ``max_triangles`` the target is lengthened until it fits, instead of refusing: the
    target used is returned.

    Returns ``(vertices, triangles, attributes, rounds, target_used)``.
    """
    t = check_positive(target_edge, "target_edge")
    max_triangles = check_int(max_triangles, "max_triangles", 1)
    v, f = np.asarray(vertices, np.float64), np.asarray(triangles, np.int64)
    if len(f) > max_triangles:
        raise ValueError(f"max_triangles: the input has {len(f)} triangles already, more "
                         f"than {max_triangles}")
    # no triangle of longest edge <= t is larger than the equilateral one, sqrt(3)/4 t^2:
    # a target below this bound cannot fit the budget whatever the mesh
    area = float(surface_area(v, f).sum())
    t = max(t, float(np.sqrt(area / (np.sqrt(3.0) / 4.0 * max_triangles))))
    while True:
        out = split_long_edges(v, f, t, attributes, max_triangles=max_triangles)
        if out is not None:
            nv, nf, na, rounds = out
            return nv, nf, na, rounds, t
        t *= 1.25


def displace(mesh, *, rng: np.random.Generator, target_edge: float | None = None,
             noise: str = "fbm", amplitude: float = 0.25, scale: str = "local",
             wavelength: float = 4.0, octaves: int = 5, mask: str = "none",
             mask_range: tuple[float, float] = (20.0, 40.0), invert_mask: bool = False,
             max_triangles: int = 2_000_000, hurst: float = 1.0) -> DisplaceResult:
    """Subdivide ``mesh`` to ``target_edge`` and displace it along its normals by noise.

    Vertex ``i`` moves to ``p_i + amplitude * h_i * m_i * z_i * n_i`` where

    - ``n_i`` is the unit area-weighted normal of the subdivided (undisplaced) mesh;
    - ``h_i`` is the local scale: with ``scale='local'`` the mean length of the *input*
      mesh's edges at that vertex (the scan's sample spacing; interpolated linearly for
      vertices created by subdivision), with ``scale='global'`` the input's bounding-box
      diagonal for every vertex;
    - ``z_i`` is the noise ``N(p_i / (wavelength * h_ref))`` standardised over the vertices
      (mean 0, root mean square 1), ``h_ref`` the mean of ``h`` over the input vertices;
    - ``m_i`` is the mask in [0, 1] (1 everywhere with ``mask='none'``).

    So with no mask the root mean square over vertices of ``offset_i / h_i`` is exactly
    ``amplitude``: ``amplitude=0.3`` makes bumps of 30 % of the local edge length, RMS.

    Parameters
    ----------
    mesh : open3d.geometry.TriangleMesh
    rng : numpy.random.Generator
        Draws the noise permutation.
    target_edge : float, optional
        Longest edge after subdivision, in metres (None: no subdivision); only longer
        edges are split, and it is lengthened when ``max_triangles`` needs it.
    noise : {'fbm', 'turbulence', 'ridged'}
    amplitude : float
        RMS displacement relative to the local scale (>= 0).
    scale : {'local', 'global'}
    wavelength : float
        Wavelength of the first octave, in units of ``h_ref`` (> 0).
    octaves : int
        1 to 16; each octave halves the wavelength.
    hurst : float
        Hurst exponent H in (0, 1]: each octave's amplitude is ``2**-H`` of the previous
        one (fBm, turbulence; ridged: its spectral exponent), so the detail's variogram
        grows as ``r**(2H)`` over the middle octaves (measured H 0.53 for 0.5, 0.77 for
        0.8, 0.88 for 1: tests/test_amplify_ops.py); 1 is the smoothest.
    mask : {'none', 'slope', 'curvature'}
        'slope': ramps from 0 at ``mask_range[0]`` to 1 at ``mask_range[1]`` degrees of
        slope (0 flat, 90 vertical; e.g. rock on steep faces); 'curvature': the same on
        ``|curvature| * h`` (dimensionless; 0 flat). Both are measured on the input mesh
        and interpolated through subdivision.
    mask_range : (2,) float
        ``lo <= hi`` (a hard step when equal).
    invert_mask : bool
        Use ``1 - mask``.
    max_triangles : int
        Triangle budget of the subdivision.

    Returns
    -------
    DisplaceResult
    """
    rng = check_rng(rng)
    v0, f0 = mesh_input(mesh)
    check_choice(noise, "noise", NOISES)
    check_choice(scale, "scale", SCALES)
    check_choice(mask, "mask", MASKS)
    amp = check_positive(amplitude, "amplitude", allow_zero=True)
    wl = check_positive(wavelength, "wavelength")
    octaves = check_int(octaves, "octaves", 1, 16)
    hurst = check_range(hurst, "hurst", 0.0, 1.0, lo_open=True)
    max_triangles = check_int(max_triangles, "max_triangles", 1)
    lo, hi = (check_finite(x, "mask_range") for x in mask_range)
    if hi < lo:
        raise ValueError(f"mask_range: expected lo <= hi, got {list(mask_range)}")

    n0 = vertex_normals(v0, f0)
    if scale == "local":
        h0 = local_edge_length(v0, f0)
    else:
        h0 = np.full(len(v0), bbox_diagonal(v0))
    if not np.all(h0 > 0):
        raise ValueError("mesh: expected non-degenerate edges (a local scale > 0)")
    attrs = [h0[:, None], n0]
    if mask == "curvature":
        attrs.append((curvature(v0, f0, n0) * h0)[:, None])
    attrs = np.hstack(attrs)
    if target_edge is None:
        v, f, a, levels = v0, f0, attrs, 0
    else:
        v, f, a, levels, target_edge = subdivide_to_edge(
            v0, f0, target_edge, attributes=attrs, max_triangles=max_triangles)
    h = a[:, 0]
    if mask == "none":
        m = np.ones(len(v))
    elif mask == "slope":
        ni = a[:, 1:4]
        ni = ni / np.maximum(np.linalg.norm(ni, axis=1, keepdims=True), 1e-300)
        m = smoothstep(slope_deg(ni), lo, hi)
    else:
        m = smoothstep(a[:, 4], lo, hi)
    if invert_mask:
        m = 1.0 - m

    normals = vertex_normals(v, f)
    seed = int(rng.integers(0, 2 ** 31 - 1))
    q = v / (wl * float(np.mean(h0)))
    kw = {"h": hurst} if noise == "ridged" else {"gain": 2.0 ** -hurst}
    fn = {"fbm": fbm, "turbulence": turbulence, "ridged": ridged}[noise]
    raw = np.asarray(fn(q[:, 0], q[:, 1], q[:, 2], octaves=octaves, seed=seed, **kw),
                     np.float64)
    z = raw - raw.mean()
    rms = float(np.sqrt(np.mean(z ** 2)))
    z = z / rms if rms > 0 else np.zeros_like(z)
    offset = amp * h * m * z
    out_v = v + offset[:, None] * normals
    longest = float(edge_lengths(v, f).max())
    return DisplaceResult(mesh=make_mesh(out_v, f), base_vertices=v, normals=normals,
                          offset=offset, scale=h, mask=m, levels=levels, max_edge=longest,
                          target_edge=target_edge)
