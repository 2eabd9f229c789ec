"""Scatter: a varied forest of stochastic L-system plants grown from one grammar and
planted on a surface by density, slope and altitude rules.

Planting is a Poisson process: candidate points are drawn uniformly by area with mean
``density * area`` and kept where the surface is gentle and the altitude in range, so the
expected number of plants is ``density * eligible area``. Each plant is one of
``variants`` plants derived from the same grammar with different seeds, scaled to a
jittered height and turned by a random yaw.

>>> import numpy as np
>>> from procgen.terrain import heightfield_to_mesh
>>> ground = heightfield_to_mesh(np.zeros((5, 5)), spacing=1.0)   # 4 m x 4 m
>>> res = scatter_plants(ground, rng=np.random.default_rng(0), density=2.0, height=0.5)
>>> len(res.positions) > 10, bool(np.all(res.positions[:, 2] == 0.0))
(True, True)

References
----------
P. Prusinkiewicz, A. Lindenmayer, *The Algorithmic Beauty of Plants*, Springer 1990
(stochastic L-systems, §1.7). doi:10.1007/978-1-4613-8476-2
O. Deussen et al., "Realistic modeling and rendering of plant ecosystems", SIGGRAPH 1998.
doi:10.1145/280814.280898
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from core.frames import rotation_to
from core.meshes import bbox_diagonal, face_normals, make_mesh, surface_area
from core.sampling import sample_surface
from core.validate import check_finite, check_int, check_positive, check_range, check_rng
from procgen.amplify.snow import sky_visible
from procgen.amplify.surface import mesh_input

__all__ = ["TREE_GRAMMAR", "ScatterResult", "scatter_plants", "grow_variants",
           "species_variants", "tip_leaves", "upward_slope"]

# A small 3-D stochastic tree: each apex branches in three, in two, or grows on.
TREE_GRAMMAR = """\
# 3-D stochastic tree (procgen.amplify.plants.TREE_GRAMMAR)
angle: 30
n: 5
width: 0.3
width_factor: 0.68
axiom: !(0.3)F(1.5)A
A -(0.45)-> !F[&+A][&/(120)+A][&/(240)+A]
A -(0.35)-> !F[&+A]/(137)[&-A]
A -(0.2)-> !F/(90)A
"""


def _grammar(grammar):
    from procgen.lsystem import Grammar, load_grammar, parse_grammar

    if grammar is None or (isinstance(grammar, str) and grammar == "tree"):
        return parse_grammar(TREE_GRAMMAR, source="<tree>")
    if isinstance(grammar, Grammar):
        return grammar
    return load_grammar(grammar)


def tip_leaves(starts: np.ndarray, ends: np.ndarray, parents: np.ndarray, *, count: int,
               size: float) -> tuple[np.ndarray, np.ndarray]:
    """Leaves at the branch tips: ``count`` two-sided diamond blades of length ``size`` at
    the end of every segment no other segment continues, spread around the segment by
    the golden angle and raised 45 degrees from it (phyllotaxis). Returns
    ``(vertices (4 count t, 3), triangles (4 count t, 3))`` for ``t`` tips."""
    starts, ends = np.asarray(starts, np.float64), np.asarray(ends, np.float64)
    tips = np.setdiff1d(np.arange(len(starts)), np.asarray(parents, np.int64))
    if count == 0 or len(tips) == 0:
        return np.empty((0, 3)), np.empty((0, 3), np.int64)
    h = ends[tips] - starts[tips]
    h /= np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-12)
    # any unit vector across each tip, then turned by the golden angle per leaf
    a = np.where(np.abs(h[:, [2]]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    u = np.cross(h, a)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    w = np.cross(h, u)
    phi = np.radians(137.508) * np.arange(count)
    side = (np.cos(phi)[None, :, None] * u[:, None] + np.sin(phi)[None, :, None] * w[:, None])
    axis = np.sqrt(0.5) * (h[:, None] + side)                     # 45 degrees off the tip
    across = np.cross(axis, side) * 0.25 * size
    base = np.broadcast_to(ends[tips][:, None], axis.shape)
    blade = np.stack([base, base + 0.5 * size * axis + across, base + size * axis,
                      base + 0.5 * size * axis - across], axis=2).reshape(-1, 3)
    quad = np.array([[0, 1, 2], [0, 2, 3], [0, 2, 1], [0, 3, 2]])   # both sides
    tris = (quad[None] + 4 * np.arange(len(tips) * count)[:, None, None]).reshape(-1, 3)
    return blade, tris


def grow_variants(grammar=None, *, rng: np.random.Generator, variants: int = 6,
                  steps: int | None = None, sides: int = 6, leaves: int = 4,
                  leaf_size: float = 0.07) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Derive ``variants`` plants from one grammar with independent seeds.

    Each is returned as ``(vertices (k, 3), triangles (t, 3), leaf (k,) bool)``
    normalised to stand on the origin (lowest point at z = 0, trunk base at x = y = 0)
    with height 1; ``leaf`` marks the leaf vertices (the rest is bark).

    Parameters
    ----------
    grammar : Grammar, str or None
        None or ``'tree'``: :data:`TREE_GRAMMAR`; a shipped example name or a file path.
    rng : numpy.random.Generator
    variants : int
    steps : int, optional
        Derivation steps (default: the grammar's ``n``).
    sides : int
        Tube resolution.
    leaves : int
        Leaves at each branch tip (:func:`tip_leaves`), 0 to 16; a grammar's own
        ``{ . }`` polygons are leaves too.
    leaf_size : float
        Leaf length over the plant's (branch) height.
    """
    from procgen.lsystem import derive, interpret, tube_arrays
    from procgen.lsystem.geometry import polygon_arrays

    rng = check_rng(rng)
    g = _grammar(grammar)
    variants = check_int(variants, "variants", 1, 1024)
    sides = check_int(sides, "sides", 3, 64)
    leaves = check_int(leaves, "leaves", 0, 16)
    leaf_size = check_range(leaf_size, "leaf_size", 0.0, 1.0, lo_open=True)
    out = []
    for seed in rng.integers(0, 2 ** 63 - 1, size=variants):
        r = interpret(derive(g, steps, rng=np.random.default_rng(int(seed))), g)
        if len(r) == 0:
            raise ValueError("grammar: the derived plant draws no segment")
        v, f = tube_arrays(r, sides=sides)
        span = float(v[:, 2].max() - v[:, 2].min())
        lv, lf = tip_leaves(r.starts, r.ends, r.parents, count=leaves, size=leaf_size * span)
        pv, pf = polygon_arrays(r)
        n_bark, n_tips = len(v), len(lv)
        f = np.vstack([np.asarray(f, np.int64), lf + n_bark,
                       np.asarray(pf, np.int64) + n_bark + n_tips])
        v = np.vstack([v, lv, pv])
        leaf = np.arange(len(v)) >= n_bark
        base = r.starts[0]
        v = v - [base[0], base[1], v[:, 2].min()]
        height = float(v[:, 2].max())
        if height <= 0:
            raise ValueError("grammar: the derived plant has no height (a flat drawing)")
        out.append((v / height, f, leaf))
    return out


def species_variants(species, *, rng: np.random.Generator, variants: int = 6,
                     max_triangles: int = 12_000) -> list[tuple[np.ndarray, np.ndarray,
                                                                np.ndarray]]:
    """Grow ``variants`` Weber & Penn trees (:mod:`procgen.weber_penn`), cycling over
    ``species`` (shipped names or ``.toml`` parameter files), in the form of
    :func:`grow_variants`: ``(vertices, triangles, leaf mask)`` standing on the origin with
    height 1.

    Each tree is grown at its species' own height (``Scale ± ScaleV``) so its proportions
    are the species', with leaf cards (``lod='cards'``). A forest repeats each variant many
    times, so a tree over ``max_triangles`` keeps its leaves (thinned at random to half the
    budget when they alone exceed it) and has its bark decimated (quadric error) to the
    rest: a 20 m spruce's 90 000 triangles become about 12 000.
    """
    from procgen.weber_penn import grow, load_species, tree_mesh
    from procgen.weber_penn.appearance import LEAF_LABEL

    rng = check_rng(rng)
    names = [species] if isinstance(species, str) else list(species)
    if not names:
        raise ValueError("species: expected at least one species name or .toml file")
    params = [load_species(s) for s in names]
    variants = check_int(variants, "variants", 1, 1024)
    max_triangles = check_int(max_triangles, "max_triangles", 100, 10_000_000)
    out = []
    for k in range(variants):
        p = params[k % len(params)]
        m = tree_mesh(grow(p, rng=rng), rng=rng, lod="cards")
        v, f = m.vertices, m.triangles
        on_leaf = m.labels[f[:, 0]] == LEAF_LABEL
        lf, bf = f[on_leaf], f[~on_leaf]
        if len(f) > max_triangles:
            if len(lf) > max_triangles // 2:   # leaf cards are two triangles each
                cards = lf.reshape(-1, 2, 3) if len(lf) % 2 == 0 else lf[:, None]
                keep = rng.choice(len(cards), size=max(1, max_triangles // 2 // cards.shape[1]),
                                  replace=False)
                lf = cards[np.sort(keep)].reshape(-1, 3)
            budget = max(max_triangles - len(lf), 100)
            if len(bf) > budget:
                bark = make_mesh(v, bf).simplify_quadric_decimation(budget)
                bv, bf = np.asarray(bark.vertices), np.asarray(bark.triangles, np.int64)
            else:
                bv = v
        else:
            bv = v
        base = v[f[~on_leaf]].reshape(-1, 3)
        base = base[np.argmin(base[:, 2])]
        vv = np.vstack([bv, v])
        ff = np.vstack([bf, lf + len(bv)]).astype(np.int64)
        used = np.unique(ff)
        remap = np.full(len(vv), -1, np.int64)
        remap[used] = np.arange(len(used))
        vv, ff = vv[used], remap[ff]
        leaf = np.zeros(len(vv), bool)
        leaf[remap[np.unique(lf) + len(bv)]] = True
        vv = vv - [base[0], base[1], vv[:, 2].min()]
        out.append((vv / float(vv[:, 2].max()), ff, leaf))
    return out


def upward_slope(normals: np.ndarray) -> np.ndarray:
    """Slope in degrees of surfaces with unit ``normals (n, 3)``: 0 facing up, 90 vertical,
    180 facing down (an overhang)."""
    return np.degrees(np.arccos(np.clip(np.asarray(normals, np.float64)[:, 2], -1.0, 1.0)))


@dataclass
class ScatterResult:
    """What :func:`scatter_plants` made.

    Attributes
    ----------
    mesh : open3d.geometry.TriangleMesh or None
        All plants in one mesh (None when nothing was planted).
    leaf : (n,) bool
        Which vertices of ``mesh`` belong to leaves (the rest is bark).
    positions : (k, 3) float64
        Plant bases on the surface.
    triangle : (k,) int64
        Surface triangle under each plant.
    heights : (k,) float64
    variant : (k,) int64
    candidates : int
        Points drawn before the rules.
    eligible_area : float
        Area (m^2) of the surface where the slope rule holds (altitude not included).
    truncated : bool
        More plants qualified than ``max_plants``.
    """

    mesh: object
    positions: np.ndarray
    triangle: np.ndarray
    heights: np.ndarray
    variant: np.ndarray
    candidates: int
    eligible_area: float
    truncated: bool
    leaf: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))


def _altitude_span(mesh, v: np.ndarray, f: np.ndarray, area: np.ndarray,
                   *, fragment: float = 0.01) -> tuple[float, float]:
    """``(zmin, zmax)`` over the connected pieces of ``mesh`` holding at least
    ``fragment`` of its area (all of it when none does)."""
    labels, _, _ = mesh.cluster_connected_triangles()
    labels = np.asarray(labels, np.int64)
    if len(labels) != len(f):
        main = np.ones(len(f), bool)
    else:
        piece_area = np.bincount(labels, weights=area)
        main = piece_area[labels] >= fragment * float(area.sum())
        if not main.any():
            main[:] = True
    z = v[f[main]][:, :, 2]
    return float(z.min()), float(z.max())


def scatter_plants(mesh, *, rng: np.random.Generator, grammar=None, density: float = 4.0,
                   height: float = 0.2, height_jitter: float = 0.3,
                   slope_max_deg: float = 30.0, altitude_range=(0.0, 1.0),
                   variants: int = 6, steps: int | None = None, sides: int = 6,
                   max_plants: int = 400, upright: bool = True, min_plants: int = 0,
                   max_candidates: int = 2_000_000, need_sky: bool = True, leaves: int = 5,
                   leaf_size: float = 0.1, species=None) -> ScatterResult:
    """Plant a varied forest on ``mesh``.

    Parameters
    ----------
    mesh : open3d.geometry.TriangleMesh
    rng : numpy.random.Generator
    grammar : Grammar, str or None
        See :func:`grow_variants` (a stochastic grammar gives varied plants).
    density : float
        Plants per square metre of eligible surface (> 0).
    height : float
        Mean plant height in metres; each is scaled by ``1 + height_jitter * U(-1, 1)``.
    height_jitter : float
        In [0, 1).
    slope_max_deg : float
        Plant only where the surface's upward slope (:func:`upward_slope` of the face
        normal) is at most this, 0 to 90; overhangs never qualify.
    altitude_range : (2,) float
        Plant only where ``(z - zmin) / (zmax - zmin)`` lies in this range, within [0, 1].
        ``zmin`` and ``zmax`` span the mesh's main parts: connected pieces holding less
        than 1 % of the area (a reconstruction's stray fragments, often centimetres off)
        do not stretch the altitude scale; points below or above it count as 0 or 1.
    variants : int
        Distinct plants derived (each plant is one of them, turned and scaled).
    steps : int, optional
        Derivation steps (default: the grammar's).
    max_plants : int
        Keep at most this many (the first drawn).
    upright : bool
        Grow along +z (True) or along the surface normal.
    need_sky : bool
        Plant only where the upward ray from the surface leaves the mesh (nothing under
        an overhang, a roof or a branch).
    min_plants : int
        A floor: when the Poisson draw leaves fewer plants than this (a small mesh, a
        low density), more candidates are drawn uniformly by area until the floor is
        met, provided some surface satisfies the rules (up to 16 extra rounds).
    leaves, leaf_size : int, float
        Leaves per branch tip and their length over the plant height (see
        :func:`grow_variants`).
    species : str or sequence of str, optional
        Weber & Penn species (names or ``.toml`` files): the variants are those species'
        trees (:func:`species_variants`, cycling over the list) instead of ``grammar``'s
        plants; ``grammar``, ``steps``, ``sides``, ``leaves`` and ``leaf_size`` then do
        not apply.
    max_candidates : int
        Refuse a density that needs more candidate points than this.

    Returns
    -------
    ScatterResult
    """
    rng = check_rng(rng)
    v, f = mesh_input(mesh)
    dens = check_positive(density, "density")
    h_mean = check_positive(height, "height")
    jit = check_range(height_jitter, "height_jitter", 0.0, 1.0, hi_open=True)
    smax = check_range(slope_max_deg, "slope_max_deg", 0.0, 90.0)
    a_lo, a_hi = (check_finite(x, "altitude_range") for x in altitude_range)
    if not 0.0 <= a_lo <= a_hi <= 1.0:
        raise ValueError(f"altitude_range: expected 0 <= lo <= hi <= 1, got {list(altitude_range)}")
    max_plants = check_int(max_plants, "max_plants", 0)
    min_plants = min(check_int(min_plants, "min_plants", 0), max_plants)
    fn = face_normals(v, f)
    area = surface_area(v, f)
    diag = bbox_diagonal(v)
    slope_ok = upward_slope(fn) <= smax + 1e-9
    eligible_area = float(area[slope_ok].sum())
    lam = dens * float(area.sum())
    if lam > max_candidates:
        raise ValueError(f"density: {dens:g} plants/m^2 over {area.sum():.4g} m^2 needs "
                         f"{lam:.3g} candidates > {max_candidates}; lower the density")
    z0, z1 = _altitude_span(mesh, v, f, area)

    def draw(n):
        p, _, t = sample_surface(v, f, n, rng=rng, return_index=True)
        rel = np.clip((p[:, 2] - z0) / (z1 - z0), 0.0, 1.0) if z1 > z0 else np.zeros(len(p))
        ok = slope_ok[t] & (rel >= a_lo) & (rel <= a_hi)
        if need_sky and ok.any():  # no plant under an overhang
            ok[ok] = sky_visible(v, f, fn[t[ok]], points=p[ok], offset=1e-6 * diag)
        return p[ok], t[ok]

    n_cand = int(rng.poisson(lam))
    pts, tri = draw(n_cand)
    if len(pts) < min_plants and eligible_area > 0:
        # the floor: enough extra candidates for the missing plants at the eligible
        # fraction seen so far (at least 64 per missing plant), a bounded number of rounds
        batch = min(max_candidates, max(64 * min_plants, int(4 * lam)))
        for _ in range(16):
            p, t = draw(batch)
            n_cand += batch
            need = min_plants - len(pts)
            pts, tri = np.vstack([pts, p[:need]]), np.concatenate([tri, t[:need]])
            if len(pts) >= min_plants:
                break
    truncated = len(pts) > max_plants
    pts, tri = pts[:max_plants], tri[:max_plants]
    k = len(pts)
    var_id = rng.integers(0, check_int(variants, "variants", 1, 1024), size=k)
    yaw = rng.uniform(0.0, 2 * np.pi, size=k)
    heights = h_mean * (1.0 + jit * rng.uniform(-1.0, 1.0, size=k))
    if k == 0:
        return ScatterResult(None, pts, tri, heights, var_id, n_cand, eligible_area, truncated)
    if species:
        shapes = species_variants(species, rng=rng, variants=variants)
    else:
        shapes = grow_variants(grammar, rng=rng, variants=variants, steps=steps, sides=sides,
                               leaves=leaves, leaf_size=leaf_size)
    vs, fs, ls, off = [], [], [], 0
    for i in range(k):
        pv, pf, pl = shapes[var_id[i]]
        ls.append(pl)
        c, s = np.cos(yaw[i]), np.sin(yaw[i])
        R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        if not upright:
            R = rotation_to(fn[tri[i]]) @ R
        # sink the base a little so trunks meet curved ground
        local = pv * heights[i] - [0.0, 0.0, 0.02 * heights[i]]
        vs.append(local @ R.T + pts[i])
        fs.append(pf + off)
        off += len(pv)
    plants = make_mesh(np.vstack(vs), np.vstack(fs))
    return ScatterResult(plants, pts, tri, heights, var_id, n_cand, eligible_area, truncated,
                         leaf=np.concatenate(ls))
