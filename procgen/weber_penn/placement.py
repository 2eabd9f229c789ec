"""Weber & Penn trees placed in a scene: a species tree grown to the height a stand asks,
its crown widened or narrowed to the radius asked, turned about its stem and stood at its
place, its triangles labelled as the L-system trees' (trunk, branch, leaf).

A scene names its species by the forestry codes of :data:`procgen.trees.SPECIES`;
:data:`FORESTRY_SPECIES` gives the species file of each code that has one, and
:func:`species_map` reads a scene's choice (``"all"`` or ``"CODE=species,..."``).

A placed tree keeps the model's proportions where they are the species': its height is the
one asked (the top exactly at ``position + height``), its wood the model's Leonardo radii
(the trunk's base from the species' height-diameter law, or scaled to a ``dbh`` asked), its
crown's horizontal extent scaled (the trunk excepted, which stays round) so the radius of
the circle of its crown's projected area is the radius asked.

>>> import numpy as np
>>> trees = SpeciesTrees(lod="cards")
>>> placed = trees.place("european_beech", position=(5.0, 2.0, 1.0), height=12.0,
...                      rng=np.random.default_rng(0))
>>> round(float(placed.vertices[:, 2].max()), 6), sorted(set(placed.parts.tolist()))
(13.0, [0, 1, 2])
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from core.validate import check_array, check_choice, check_int, check_positive, check_rng
from procgen.weber_penn.appearance import LEAF_LABEL, LODS, SEASONS, tree_mesh
from procgen.weber_penn.growth import Tree, grow
from procgen.weber_penn.params import load_species, species_names

__all__ = ["FORESTRY_SPECIES", "species_map", "PlacedTree", "SpeciesTrees",
           "crown_area_radius", "stem_dbh"]

FORESTRY_SPECIES = {
    "PIAB": "norway_spruce", "ABAL": "silver_fir", "PISY": "scots_pine",
    "LADE": "european_larch", "FASY": "european_beech", "ACPS": "sycamore_maple",
}
"""The shipped species file of each forestry code that has one (``"all"`` plants these)."""

BREAST_HEIGHT = 1.3  # metres above the stem's base where the dbh is measured


def species_map(text: str, *, field_name: str = "weber_penn") -> dict[str, str]:
    """The forestry codes a scene grows with Weber & Penn's model and the species of each.

    ``""`` none, ``"all"`` every code of :data:`FORESTRY_SPECIES`, or
    ``"CODE=species,..."`` (a shipped species name for each code; ``CODE`` alone takes its
    :data:`FORESTRY_SPECIES` entry).

    >>> species_map("FASY, QURO=ca_black_oak")
    {'FASY': 'european_beech', 'QURO': 'ca_black_oak'}
    """
    text = str(text).strip()
    if not text:
        return {}
    if text.lower() == "all":
        return dict(FORESTRY_SPECIES)
    known = species_names()
    out = {}
    for item in text.split(","):
        if not item.strip():
            continue
        code, _, name = (s.strip() for s in item.partition("="))
        code = code.upper()
        if not name:
            if code not in FORESTRY_SPECIES:
                raise ValueError(f"{field_name}: {code!r} has no species file of its own; "
                                 f"name one ({code}=species) or use one of "
                                 f"{', '.join(FORESTRY_SPECIES)}")
            name = FORESTRY_SPECIES[code]
        key = name.lower().replace(" ", "_").replace("-", "_")
        if key not in known:
            raise ValueError(f"{field_name}: unknown species {name!r}; expected one of "
                             f"{', '.join(known)}")
        out[code] = key
    return out


def crown_area_radius(xy: np.ndarray) -> float:
    """Radius (m) of the circle with the area of the convex hull of ``xy (n, 2)``: a
    crown's radius as a segmentation of its projection measures it."""
    from scipy.spatial import ConvexHull

    xy = np.asarray(xy, np.float64)
    if len(xy) < 3:
        return 0.0
    try:
        return float(np.sqrt(ConvexHull(xy).volume / np.pi))
    except Exception:  # all points on a line: no area  # noqa: BLE001
        return 0.0


def stem_dbh(tree: Tree) -> float:
    """The trunk's diameter (m) at breast height, 1.3 m above its base (the base's own
    diameter for a tree shorter than that)."""
    sk = tree.skeleton
    trunk = int(np.flatnonzero(sk.level == 0)[0])
    a, b = sk.ptr[trunk], sk.ptr[trunk + 1]
    z = sk.points[a:b, 2] - sk.points[a, 2]
    if z[-1] < BREAST_HEIGHT:
        return float(2.0 * sk.radius[a])
    return float(2.0 * np.interp(BREAST_HEIGHT, z, sk.radius[a:b]))


@dataclass
class PlacedTree:
    """A tree in scene coordinates: ``vertices`` (n, 3), ``triangles`` (m, 3), ``parts``
    (m,) uint8 (0 trunk, 1 branch, 2 leaf, as :data:`procgen.trees.TREE_PARTS`), its
    ``crown_radius`` and ``dbh`` in metres (as built) and its ``species``."""

    vertices: np.ndarray
    triangles: np.ndarray
    parts: np.ndarray
    crown_radius: float
    dbh: float
    species: str


@dataclass
class SpeciesTrees:
    """Grows and places species trees for a scene.

    ``variants`` 0 grows every tree on its own at its height; ``variants`` k grows k
    individuals of a species (at the first height asked) and places scaled copies of them,
    as a large stand needs. ``lod`` and ``season`` as :func:`tree_mesh`.
    """

    lod: str = "cards"
    season: str = "summer"
    variants: int = 0
    _grown: dict = field(default_factory=dict, repr=False)

    def __post_init__(self):
        check_choice(self.lod, "lod", LODS)
        check_choice(self.season, "season", SEASONS)
        self.variants = check_int(self.variants, "variants", 0, 1024)

    def _model(self, name: str, height: float, dbh, rng):
        """A mesh of ``name`` and the height of its top, its dbh and its crown radius."""
        if self.variants:
            pool = self._grown.setdefault(name, [])
            if len(pool) < self.variants:
                pool.append(self._build(name, height, None, rng))
                return pool[-1]
            return pool[int(rng.integers(len(pool)))]
        return self._build(name, height, dbh, rng)

    def _build(self, name, height, dbh, rng):
        tree = grow(load_species(name), height=height, rng=rng)
        if dbh is not None:  # every radius alike: the forks keep Leonardo's rule
            tree.skeleton.radius *= dbh / max(stem_dbh(tree), 1e-9)
        mesh = tree_mesh(tree, rng=rng, season=self.season, lod=self.lod)
        crown = mesh.labels != 0
        top = float(mesh.vertices[:, 2].max())
        return mesh, top, stem_dbh(tree), crown_area_radius(mesh.vertices[crown, :2])

    def place(self, name: str, *, position, height: float, rng: np.random.Generator,
              crown_radius: float | None = None, dbh: float | None = None,
              azimuth: float = 0.0) -> PlacedTree:
        """One tree of species ``name`` with its stem's base at ``position`` (m) and its top
        exactly ``height`` above; ``crown_radius`` (m, default the model's own) scales the
        crown's horizontal extent; ``dbh`` (m, default the model's own) scales the wood's
        radii (every one alike, so Leonardo's rule still holds) when each tree is grown on
        its own (a copy of a variant keeps its own); ``azimuth`` turns it about its stem
        (radians)."""
        rng = check_rng(rng)
        p = check_array(position, "position", shape=(3,), finite=True)
        h = check_positive(height, "height")
        if dbh is not None:
            dbh = check_positive(dbh, "dbh")
        mesh, top, dbh0, r0 = self._model(name, h, dbh, rng)
        s = h / top                      # the model stands on its stem's base at the origin
        V = mesh.vertices * s
        built_dbh = dbh0 * s
        r = r0 * s
        if crown_radius is not None:
            kxy = check_positive(crown_radius, "crown_radius") / max(r, 1e-9)
            crown = mesh.labels != 0
            V[crown, :2] *= kxy
            r *= kxy
        c, sn = np.cos(azimuth), np.sin(azimuth)
        V[:, :2] = V[:, :2] @ np.array([[c, sn], [-sn, c]])
        V += p
        lab = mesh.labels[mesh.triangles[:, 0]]
        parts = np.where(lab == 0, 0, np.where(lab == LEAF_LABEL, 2, 1)).astype(np.uint8)
        return PlacedTree(V, mesh.triangles, parts, float(r),
                          float(built_dbh), name)
