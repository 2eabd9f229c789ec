"""Hypertexture of a mesh: its signed distance (Open3D ``RaycastingScene``) perturbed by
noise and re-meshed with marching cubes (:func:`procgen.implicit.hypertexture`).

>>> import numpy as np, open3d as o3d
>>> ball = o3d.geometry.TriangleMesh.create_sphere(1.0, 20)
>>> res = hypertexture_mesh(ball, rng=np.random.default_rng(0), amplitude=0.0, resolution=24)
>>> r = np.linalg.norm(np.asarray(res.mesh.vertices), axis=1)
>>> bool(np.all(np.abs(r - 1.0) < res.voxel))
True
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.meshes import is_closed
from core.validate import check_int, check_positive, check_rng
from procgen.amplify.surface import mesh_input
from procgen.implicit import SHELL_VOXELS, hypertexture, shell_sdf

__all__ = ["HyperResult", "hypertexture_mesh", "SHELL_VOXELS"]



@dataclass
class HyperResult:
    """``mesh`` (the re-meshed surface), ``voxel`` (the sampling step in metres) and
    ``inside``: ``"mesh"`` (a closed input's own inside) or ``"shell"`` (an open input
    thickened by ``SHELL_VOXELS`` voxels on each side to give it one)."""

    mesh: object
    voxel: float
    inside: str = "mesh"


def hypertexture_mesh(mesh, *, rng: np.random.Generator, noise: str = "turbulence",
                      amplitude: float = 0.02, frequency: float = 8.0, octaves: int = 4,
                      resolution: int = 96, bias: float = 0.5, gain: float = 0.5) -> HyperResult:
    """Perlin-Hoffert hypertexture of a mesh (an open one is first given an inside: the
    shell of half-width ``SHELL_VOXELS`` voxels around it, :func:`procgen.implicit.shell_sdf`).

    The surface becomes the 0.5 level of ``D(x) = clip(0.5 - (sdf(x) - amplitude *
    N(frequency x)) / (4 voxel))`` shaped by bias and gain; with ``amplitude = 0`` it is
    the input surface resampled at the voxel size.

    Parameters
    ----------
    mesh : open3d.geometry.TriangleMesh
        Closed and consistently oriented, or open (then thickened into a shell).
    rng : numpy.random.Generator
        Draws the noise permutation.
    noise : {'turbulence', 'fbm'}
    amplitude : float
        Metres (>= 0); turbulence (>= 0) grows the shape outward by up to about twice this.
    frequency : float
        Cycles per metre of the first octave.
    octaves : int
    resolution : int
        Voxels along the longest side of the sampled box (8 to 512).
    bias, gain : float
        Perlin's density modulation in (0, 1); 0.5 leaves it unchanged.

    Returns
    -------
    HyperResult
    """
    rng = check_rng(rng)
    v, f = mesh_input(mesh)
    amp = check_positive(amplitude, "amplitude", allow_zero=True)
    resolution = check_int(resolution, "resolution", 8, 512)
    seed = int(rng.integers(0, 2 ** 31 - 1))
    lo, hi = v.min(axis=0), v.max(axis=0)
    pad = 2.5 * amp + 0.05 * float(np.max(hi - lo))
    lo, hi = lo - pad, hi + pad
    voxel = float(np.max(hi - lo)) / (resolution - 1)
    closed = is_closed(f)
    shape = mesh if closed else shell_sdf(mesh, SHELL_VOXELS * voxel)
    out = hypertexture(shape, bounds=(lo, hi), resolution=resolution, noise=noise,
                       amplitude=amp, frequency=frequency, octaves=octaves, bias=bias,
                       gain=gain, seed=seed)
    return HyperResult(mesh=out, voxel=voxel, inside="mesh" if closed else "shell")
