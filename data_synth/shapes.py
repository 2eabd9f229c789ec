"""Meshes of the scene spec's shapes, in their object frames (metres, Z up).

Each builder returns ``(mesh, analytic)`` where ``analytic`` is the exact shape the
mesh approximates (for the renderer's exact depth) or None.
"""

from __future__ import annotations

import numpy as np

from core.meshes import make_mesh, mesh_arrays
from core.validate import check_positive, check_range
from procgen.noise import perlin

__all__ = ["sphere", "box", "cylinder", "torus", "plane", "blob", "icosphere", "terrain",
           "lsystem_plant", "seashell"]


def icosphere(subdivisions: int):
    """Unit icosphere: near-uniform triangles, ``20 * 4**subdivisions`` of them."""
    import open3d as o3d

    m = o3d.geometry.TriangleMesh.create_icosahedron(1.0)
    if subdivisions:
        m = m.subdivide_midpoint(int(subdivisions))
    v, f = mesh_arrays(m)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    return v, f


def sphere(radius: float, *, subdivisions: int = 5):
    r = check_positive(radius, "radius")
    v, f = icosphere(subdivisions)
    return make_mesh(v * r, f, vertex_normals=v), {"type": "sphere", "center": [0, 0, 0],
                                                    "radius": r}


def box(size):
    import open3d as o3d

    sx, sy, sz = (check_positive(s, "size") for s in size)
    m = o3d.geometry.TriangleMesh.create_box(sx, sy, sz)
    m.translate([-sx / 2, -sy / 2, -sz / 2])
    # flat shading: split vertices per face
    v, f = mesh_arrays(m)
    vv = v[f.reshape(-1)]
    ff = np.arange(len(vv)).reshape(-1, 3)
    return _flat(vv, ff), None


def _flat(v, f):
    e1 = v[f[:, 1]] - v[f[:, 0]]
    e2 = v[f[:, 2]] - v[f[:, 0]]
    n = np.cross(e1, e2)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return make_mesh(v, f, vertex_normals=np.repeat(n, 3, axis=0))


def cylinder(radius: float, height: float, *, segments: int = 96):
    """Closed cylinder along Z centred at the origin, flat caps, smooth side."""
    r = check_positive(radius, "radius")
    h = check_positive(height, "height")
    a = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    ring = np.stack([r * np.cos(a), r * np.sin(a)], axis=1)
    side_n = np.concatenate([ring / r, np.zeros((segments, 1))], axis=1)
    bot = np.concatenate([ring, np.full((segments, 1), -h / 2)], axis=1)
    top = np.concatenate([ring, np.full((segments, 1), h / 2)], axis=1)
    i = np.arange(segments)
    j = (i + 1) % segments
    side_v = np.vstack([bot, top])
    side_f = np.vstack([np.stack([i, j, segments + j], 1),
                        np.stack([i, segments + j, segments + i], 1)])
    side = make_mesh(side_v, side_f, vertex_normals=np.vstack([side_n, side_n]))
    caps_v, caps_f, caps_n = [], [], []
    for z, sgn in ((-h / 2, -1.0), (h / 2, 1.0)):
        base = len(np.vstack(caps_v)) if caps_v else 0
        cv = np.vstack([[0, 0, z], np.concatenate([ring, np.full((segments, 1), z)], 1)])
        tri = np.stack([np.zeros(segments, int), 1 + i, 1 + j], 1)
        if sgn < 0:
            tri = tri[:, [0, 2, 1]]
        caps_v.append(cv)
        caps_f.append(tri + base)
        caps_n.append(np.tile([0, 0, sgn], (len(cv), 1)))
    v = np.vstack([side_v, *caps_v])
    f = np.vstack([side_f, *[c + len(side_v) for c in caps_f]])
    n = np.vstack([np.asarray(side.vertex_normals), *caps_n])
    return make_mesh(v, f, vertex_normals=n), None


def torus(radius: float, tube: float, *, segments: int = 96, tube_segments: int = 48):
    import open3d as o3d

    R = check_positive(radius, "radius")
    r = check_positive(tube, "tube")
    if r >= R:
        raise ValueError(f"tube: expected less than radius ({R}), got {r}")
    m = o3d.geometry.TriangleMesh.create_torus(R, r, segments, tube_segments)
    m.compute_vertex_normals()
    return m, None


def plane(size):
    sx, sy = (check_positive(s, "size") for s in size)
    v = np.array([[-sx / 2, -sy / 2, 0], [sx / 2, -sy / 2, 0], [sx / 2, sy / 2, 0],
                  [-sx / 2, sy / 2, 0]], float)
    f = np.array([[0, 1, 2], [0, 2, 3]])
    return (make_mesh(v, f, vertex_normals=np.tile([0, 0, 1.0], (4, 1))),
            {"type": "plane", "point": [0, 0, 0], "normal": [0, 0, 1]})


def blob(radius: float, *, amplitude: float = 0.18, frequency: float = 1.4,
         subdivisions: int = 6, seed: int | None = 0):
    """A closed organic shape: an icosphere displaced radially by Perlin fBm.

    ``r(u) = radius * (1 + amplitude * fbm(frequency * u))`` for unit directions u,
    star-shaped (so closed and free of self-intersections while amplitude < 1).
    """
    R = check_positive(radius, "radius")
    A = check_range(amplitude, "amplitude", 0, 0.9)
    F = check_positive(frequency, "frequency")
    u, f = icosphere(int(subdivisions))
    disp = np.zeros(len(u))
    amp, fr = 1.0, F
    for _ in range(3):
        disp += amp * perlin(u[:, 0] * fr + 11.3, u[:, 1] * fr + 5.7, u[:, 2] * fr + 2.1,
                             seed=seed)
        amp *= 0.35
        fr *= 2.0
    v = u * (R * (1.0 + A * disp / 0.7))[:, None]
    return make_mesh(v, f), None


def terrain(size: float, *, samples: int = 65, height: float = 0.005,
            method: str = "fbm", hurst: float = 0.8, frequency: float = 3.0,
            seed: int = 0):
    """A square fractal heightfield ``size`` metres a side, centred on the origin at z = 0.

    Heights from :func:`procgen.terrain.fractal_terrain` (standard deviation ``height``),
    triangulated by :func:`procgen.terrain.heightfield_to_mesh` (an open surface facing +z).
    ``samples`` is the grid size a side, ``2**n + 1``.
    """
    from procgen.terrain import fractal_terrain, heightfield_to_mesh

    s = check_positive(size, "size")
    h = check_positive(height, "height", allow_zero=True)
    z = fractal_terrain(int(samples), rng=np.random.default_rng(seed), method=method,
                        hurst=hurst, height=h, frequency=frequency)
    import open3d as o3d

    d = s / (int(samples) - 1)
    mesh = heightfield_to_mesh(z, spacing=d, origin=(-s / 2, -s / 2, 0.0))
    mesh.triangle_uvs = o3d.utility.Vector2dVector()  # solid materials need no UVs; PLY can't
    return mesh, None


def lsystem_plant(grammar: str, *, height: float, n: int | None = None, seed: int = 0,
                  min_radius: float = 0.0, sides: int = 8, leaves: bool = False):
    """An L-system plant (:mod:`procgen.lsystem`) scaled to ``height`` metres tall.

    The grammar (a shipped example name or a ``.lsys`` path) is derived ``n`` steps
    (default: the grammar's), interpreted by the turtle (growing along +z from the origin)
    and meshed as tubes; the whole plant is scaled so its z extent is ``height``.
    ``min_radius`` (metres, after scaling) keeps thin twigs visible to scanners.
    """
    from procgen.lsystem import derive, interpret, load_grammar, to_mesh

    h = check_positive(height, "height")
    r_min = check_positive(min_radius, "min_radius", allow_zero=True)
    g = load_grammar(grammar)
    result = interpret(derive(g, n, rng=np.random.default_rng(seed)), g)
    if len(result) == 0:
        raise ValueError(f"grammar: {grammar!r} drew no segments")
    z = np.concatenate([result.starts[:, 2], result.ends[:, 2]])
    extent = float(z.max() - z.min())
    if not extent > 0:
        raise ValueError(f"grammar: {grammar!r} draws no height to scale to {h} m")
    k = h / extent
    mesh = to_mesh(result, sides=int(sides), caps=True, leaves=bool(leaves),
                   min_radius=r_min / k, colors=False)
    mesh.scale(k, center=np.zeros(3))
    mesh.compute_vertex_normals()
    return mesh, None


def seashell(preset: str = "spherical", *, size: float = 0.05, n_theta: int = 240,
             n_s: int = 32):
    """A Cortie seashell (:func:`procgen.shells.cortie_shell`, a preset of
    :data:`procgen.shells.SHAPES`) scaled so its largest extent is ``size`` metres,
    centred on the origin."""
    from procgen.shells import cortie_shell

    s = check_positive(size, "size")
    v, f = cortie_shell(preset, n_theta=int(n_theta), n_s=int(n_s))
    v = v - 0.5 * (v.max(axis=0) + v.min(axis=0))
    v *= s / float(np.ptp(v, axis=0).max())
    mesh = make_mesh(v, f)
    mesh.compute_vertex_normals()
    return mesh, None
