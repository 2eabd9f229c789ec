"""How a grown tree looks: tubes with bark, leaves with their shapes and colours.

- **Bark**: each species' colour and a procedural texture (:data:`BARK_TEXTURES`:
  smooth, lenticels, furrowed, plated, scaly, ringed) from fBm noise in metres on the
  bark's surface, so furrows and plates keep their size on the trunk and on a twig.
- **Leaves**: the species' outline (:data:`procgen.weber_penn.params.LEAF_SHAPES`) fanned
  into triangles, or a tuft of needles for conifers; the colour varies between trees
  (one tint a tree), within a crown (lighter in the sun at the top) and leaf to leaf.
- **Seasons**: ``summer``; ``autumn`` (each leaf between its green and the species'
  autumn colour, the crown's top first); ``winter`` (deciduous species leafless).
- **Level of detail**: ``lod="cards"`` draws one card per twig in place of its leaves,
  for forests (a few percent of the triangles).

Vertex labels (:data:`TREE_LABELS`): 0 the trunk, 1-3 the branch order, 4 a leaf.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from core.validate import check_choice, check_rng
from procgen.noise import fbm
from procgen.weber_penn.growth import Tree
from procgen.weber_penn.params import leaf_shape_name
from procgen.weber_penn.shapes import flare_factor

__all__ = ["TREE_LABELS", "SEASONS", "LODS", "TreeMesh", "tree_mesh", "bark_pattern",
           "bark_texture", "leaf_outline"]

TREE_LABELS = {0: "trunk", 1: "branch_1", 2: "branch_2", 3: "branch_3", 4: "leaf"}
LEAF_LABEL = 4
SEASONS = ("summer", "autumn", "winter")
LODS = ("full", "cards")
RING_SIDES = (20, 8, 5, 4)
NEEDLES_PER_TUFT = 6
LEAF_BLOCK = 2048  # leaves built at a time (their temporaries stay in cache)


@dataclass
class TreeMesh:
    """A tree as one triangle mesh: ``vertices`` (n, 3), ``triangles`` (m, 3),
    ``colors`` (n, 3) float in [0, 1], ``labels`` (n,) int (:data:`TREE_LABELS`)."""

    vertices: np.ndarray
    triangles: np.ndarray
    colors: np.ndarray
    labels: np.ndarray

    def part(self, label: int) -> tuple[np.ndarray, np.ndarray]:
        """Vertices and triangles of the triangles whose first vertex has ``label``."""
        sel = self.labels[self.triangles[:, 0]] == label
        return self.vertices, self.triangles[sel]


# ---------------------------------------------------------------- bark

def bark_pattern(kind: str, u, v, *, seed: int = 0) -> np.ndarray:
    """How dark the bark is (0 light .. 1 the dark colour) at surface coordinates ``u``
    (around the stem) and ``v`` (along it), both in metres."""
    u, v = np.asarray(u, float), np.asarray(v, float)
    if kind == "smooth":
        return np.clip(0.25 + 0.35 * fbm(u * 8, v * 3, octaves=3, seed=seed), 0, 1)
    if kind == "lenticels":  # dark horizontal scars on pale bark (aspens, birches)
        n = fbm(u * 6, v * 30, octaves=2, seed=seed)
        return np.clip((n - 0.25) * 4, 0, 1) * 0.9
    if kind == "furrowed":  # long vertical ridges and dark furrows
        w = fbm(u * 4, v * 0.7, octaves=3, seed=seed)
        ridge = np.abs(np.sin(2 * np.pi * (u / 0.07 + 0.6 * w)))
        return np.clip(1.0 - ridge ** 0.35 + 0.2 * w, 0, 1)
    if kind == "plated":  # plates split by dark cracks
        n = fbm(u * 9, v * 4, octaves=3, seed=seed)
        return np.clip(1.0 - np.abs(n) * 8, 0, 1) * 0.9 + 0.1 * (n > 0)
    if kind == "scaly":  # small flakes
        n = fbm(u * 25, v * 18, octaves=2, seed=seed)
        return np.clip(0.5 + 1.6 * n, 0, 1)
    if kind == "ringed":  # leaf scars round a palm's trunk
        w = fbm(u * 3, v * 2, octaves=2, seed=seed)
        return np.clip(np.abs(np.sin(np.pi * (v / 0.12 + 0.2 * w))) ** 6 * 0.9, 0, 1)
    raise ValueError(f"kind: expected one of smooth, lenticels, furrowed, plated, scaly, "
                     f"ringed, got {kind!r}")


def bark_texture(params, *, size: tuple[int, int] = (256, 256), extent: float = 0.5,
                 seed: int = 0) -> np.ndarray:
    """The species' bark as an RGB image (h, w, 3) float in [0, 1] covering ``extent``
    metres a side (a texture for renderers, and the docs' swatches)."""
    h, w = size
    v, u = np.meshgrid(np.linspace(0, extent, h), np.linspace(0, extent, w), indexing="ij")
    t = bark_pattern(params.appearance["bark_texture"], u, v, seed=seed)[..., None]
    a, b = np.array(params.appearance["bark"]), np.array(params.appearance["bark_dark"])
    return (1 - t) * a + t * b


def _tubes(tree: Tree, seed: int):
    sk = tree.skeleton
    p = tree.params
    stem_of = sk.stem_of_point()
    lvl = sk.level[stem_of]
    V, T, C, L = [], [], [], []
    n0 = 0
    lobes, depth = p["Lobes"], p["LobeDepth"]
    for level in range(int(sk.level.max()) + 1):
        pts = np.flatnonzero(lvl == level)
        if not len(pts):
            continue
        m = max(RING_SIDES[level], 4 * lobes) if level == 0 else RING_SIDES[level]
        theta = 2 * np.pi * np.arange(m) / m
        r = sk.radius[pts][:, None] * np.ones(m)
        if level == 0:
            trunk = ~sk.clone[stem_of[pts]]
            z = sk.arc[pts] / sk.stem_length[stem_of[pts]]
            r = r * np.where(trunk, flare_factor(z, p["Flare"]), 1.0)[:, None]
            if lobes:
                r = r * (1 + depth * np.sin(lobes * theta))[None, :]
        ring = (np.cos(theta)[None, :, None] * sk.xaxis[pts][:, None, :]
                + np.sin(theta)[None, :, None] * sk.yaxis[pts][:, None, :])
        verts = sk.points[pts][:, None, :] + r[..., None] * ring
        # quads between consecutive points of one stem
        same = stem_of[pts[:-1]] == stem_of[pts[1:]]
        i = np.flatnonzero(same)
        a = (i[:, None] * m + np.arange(m)[None, :])
        b = (i[:, None] * m + (np.arange(m)[None, :] + 1) % m)
        quads = np.stack([a, b, b + m, a + m], -1).reshape(-1, 4)
        tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
        a_col, b_col = np.array(p.appearance["bark"]), np.array(p.appearance["bark_dark"])
        if level <= 1:  # the texture where it can be seen; twigs take its mean
            circ = 2 * np.pi * np.maximum(sk.radius[pts], 1e-4)
            u = theta[None, :] / (2 * np.pi) * circ[:, None]
            dark = bark_pattern(p.appearance["bark_texture"], u,
                                np.repeat(sk.arc[pts][:, None], m, 1), seed=seed)
        else:
            dark = np.full((len(pts), m), 0.35)
        col = (1 - dark[..., None]) * a_col + dark[..., None] * b_col
        V.append(verts.reshape(-1, 3))
        T.append(tris + n0)
        C.append(col.reshape(-1, 3))
        L.append(np.full(len(pts) * m, min(level, 3)))
        n0 += len(pts) * m
    return V, T, C, L


# ---------------------------------------------------------------- leaves

def leaf_outline(shape: str, n: int = 10) -> np.ndarray:
    """A leaf's outline (k, 2) in units of its width (x, centred) and length (y, base at 0,
    tip at 1), counter-clockwise."""
    if shape in ("palm", "square"):
        return np.array([[-0.5, 0.0], [0.5, 0.0], [0.5, 1.0], [-0.5, 1.0]])
    if shape == "lobed":  # palmate, five lobes (maples)
        phi = np.linspace(0, 2 * np.pi, 4 * n, endpoint=False)
        rad = 0.5 * (0.55 + 0.45 * np.abs(np.cos(2.5 * (phi - np.pi / 2))) ** 1.5)
        return np.stack([rad * np.cos(phi), 0.5 + rad * np.sin(phi)], 1)
    y = np.linspace(0, 1, n + 1)[1:-1]
    if shape == "disc":
        half = 0.5 * np.sqrt(np.clip(1 - (2 * y - 1) ** 2, 0, 1))
    elif shape == "disc1":  # ovate, pointed
        half = 0.5 * np.sin(np.pi * y) ** 0.8 * (1 - y) ** 0.3 * 1.25
    elif shape == "disc2":  # lanceolate
        half = 0.5 * np.sin(np.pi * y ** 0.8)
    elif shape == "disc3":  # broad base, pointed
        half = 0.5 * (1 - y) ** 0.8 * np.sin(np.pi * np.minimum(y * 2, 1) / 2) * 1.3
    else:
        raise ValueError(f"shape: no outline for {shape!r}")
    right = np.stack([half, y], 1)
    left = np.stack([-half[::-1], y[::-1]], 1)
    return np.concatenate([[[0.0, 0.0]], right, [[0.0, 1.0]], left])


def _leaf_colours(tree: Tree, season: str, rng: np.random.Generator) -> np.ndarray:
    lv = tree.leaves
    app = tree.params.appearance
    var = app["leaf_variation"]
    base = np.array(app["leaf"])
    tint = 1 + rng.normal(0, var / 2, 3)                      # between trees
    hfrac = np.clip(lv.position[:, 2] / max(tree.height, 1e-9), 0, 1)
    sun = 0.85 + 0.3 * hfrac                                  # within the crown
    each = 1 + rng.normal(0, var, len(lv))                    # leaf to leaf
    col = base[None, :] * tint[None, :] * (sun * each)[:, None]
    if season == "autumn" and app["deciduous"]:
        t = np.clip(0.35 + 0.6 * hfrac + rng.normal(0, 0.25, len(lv)), 0, 1)[:, None]
        col = (1 - t) * col + t * np.array(app["autumn"]) * (each[:, None] * 0.5 + 0.5)
    return np.clip(col, 0, 1)


def _leaf_sizes(tree: Tree) -> tuple[int, int]:
    """Vertices and triangles a leaf (or needle tuft) of ``tree`` is drawn with."""
    shape = leaf_shape_name(tree.params["LeafShape"])
    if shape == "needles":
        return 3 * NEEDLES_PER_TUFT, NEEDLES_PER_TUFT
    k = len(leaf_outline(shape))
    return k + 1, k


def _leaf_geometry(tree: Tree, rng, verts: np.ndarray, tris: np.ndarray, n0: int) -> None:
    """Write every leaf's vertices into ``verts`` (k * per-leaf, 3) and its triangles
    (offset by ``n0``) into ``tris``, in place.

    A crown holds up to a few hundred thousand leaves: they are built a block of
    :data:`LEAF_BLOCK` at a time, so the temporaries stay in cache instead of being a
    mesh's size (on a weeping willow that was most of the mesh's time).
    """
    lv = tree.leaves
    n = len(lv)
    shape = leaf_shape_name(tree.params["LeafShape"])
    if shape == "needles":
        k = NEEDLES_PER_TUFT
        ang = 2 * np.pi * (np.arange(k) / k)[None, :] + rng.uniform(0, 2 * np.pi, (n, 1))
        spread = math.radians(40) * min(tree.params["LeafScaleX"], 1.5)
        out = verts.reshape(n, k, 3, 3)
        for a in range(0, n, LEAF_BLOCK):
            s = slice(a, a + LEAF_BLOCK)
            axis, normal, pos = lv.axis[s], lv.normal[s], lv.position[s]
            side = np.cross(normal, axis)
            c, sn = np.cos(ang[s])[..., None], np.sin(ang[s])[..., None]
            d = (np.cos(spread) * axis[:, None, :]
                 + np.sin(spread) * (c * side[:, None, :] + sn * normal[:, None, :]))
            wid = 0.004 * (c * normal[:, None, :] - sn * side[:, None, :])
            np.add(pos[:, None, :], wid, out=out[s, :, 0])
            np.subtract(pos[:, None, :], wid, out=out[s, :, 1])
            np.add(pos[:, None, :], lv.length[s, None, None] * d, out=out[s, :, 2])
        tris[:] = np.arange(len(tris) * 3).reshape(-1, 3) + n0
        return
    outline = leaf_outline(shape)
    k = len(outline)
    pts2 = np.concatenate([[[0.0, 0.5]], outline])           # fan about the centre
    px, py = pts2[:, 0][None, :, None], pts2[:, 1][None, :, None]
    out = verts.reshape(n, k + 1, 3)
    for a in range(0, n, LEAF_BLOCK):
        s = slice(a, a + LEAF_BLOCK)
        side = np.cross(lv.normal[s], lv.axis[s])
        x = px * lv.width[s, None, None] * side[:, None, :]
        y = py * lv.length[s, None, None] * lv.axis[s, None, :]
        np.add(lv.position[s, None, :], x, out=out[s])
        out[s] += y
    fan = np.stack([np.zeros(k, int), np.arange(1, k + 1), np.arange(2, k + 2)], 1)
    fan[-1, 2] = 1
    t = tris.reshape(n, k, 3)
    t[:] = fan[None] + n0
    t += (np.arange(n) * (k + 1))[:, None, None]


def _leaf_cards(tree: Tree, colours: np.ndarray):
    """One card a twig: a quad through its leaves' centre, as wide as they spread."""
    lv = tree.leaves
    stems, inv = np.unique(lv.stem, return_inverse=True)
    n = len(stems)
    cnt = np.bincount(inv, minlength=n)[:, None]

    def mean(a):
        out = np.zeros((n, a.shape[1]))
        np.add.at(out, inv, a)
        return out / cnt
    centre = mean(lv.position + 0.5 * lv.length[:, None] * lv.axis)
    normal = mean(lv.normal)
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-9)
    spread = np.zeros(n)
    np.maximum.at(spread, inv, np.linalg.norm(lv.position - centre[inv], axis=1))
    half = 0.5 * np.maximum(spread, lv.length[0]) + 0.5 * lv.length.max()
    a = np.cross(normal, [1.0, 0.0, 0.0])
    bad = np.linalg.norm(a, axis=1) < 1e-6
    a[bad] = [0.0, 1.0, 0.0]
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b = np.cross(normal, a)
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float)
    verts = (centre[:, None, :] + half[:, None, None] * (corners[None, :, 0:1] * a[:, None, :]
                                                        + corners[None, :, 1:2] * b[:, None, :]))
    tris = (np.arange(n)[:, None, None] * 4 + np.array([[0, 1, 2], [0, 2, 3]])[None]).reshape(-1, 3)
    return verts.reshape(-1, 3), tris, np.repeat(mean(colours), 4, 0)


def tree_mesh(tree: Tree, *, rng: np.random.Generator, season: str = "summer",
              lod: str = "full") -> TreeMesh:
    """The tree as one coloured, labelled triangle mesh (see the module docstring)."""
    rng = check_rng(rng)
    check_choice(season, "season", SEASONS)
    check_choice(lod, "lod", LODS)
    seed = int(rng.integers(2 ** 31))
    V, T, C, L = _tubes(tree, seed)
    n0 = sum(len(v) for v in V)
    t0 = sum(len(t) for t in T)
    leafless = season == "winter" and tree.params.appearance["deciduous"]
    has_leaves = bool(len(tree.leaves)) and not leafless
    colours = _leaf_colours(tree, season, rng) if has_leaves else None
    cards = None
    nv = nt = 0
    if has_leaves and lod == "cards":
        cards = _leaf_cards(tree, colours)
        nv, nt = len(cards[0]), len(cards[1])
    elif has_leaves:
        per_v, per_t = _leaf_sizes(tree)
        nv, nt = per_v * len(tree.leaves), per_t * len(tree.leaves)
    # the whole mesh is filled in place: a crown's leaves are millions of vertices
    verts = np.empty((n0 + nv, 3))
    tris = np.empty((t0 + nt, 3), np.int64)
    cols = np.empty((n0 + nv, 3))
    labels = np.empty(n0 + nv, np.int64)
    for dst, parts in ((verts, V), (tris, T), (cols, C), (labels, L)):
        if parts:
            np.concatenate(parts, out=dst[:len(dst) - (nt if dst is tris else nv)])
    labels[n0:] = LEAF_LABEL
    if cards is not None:
        verts[n0:], tris[t0:], cols[n0:] = cards[0], cards[1] + n0, cards[2]
    elif has_leaves:
        _leaf_geometry(tree, rng, verts[n0:], tris[t0:], n0)
        cols[n0:].reshape(len(tree.leaves), -1, 3)[:] = colours[:, None, :]
    return TreeMesh(verts, tris, cols, labels)
