"""Trees with species-like architecture, grown by parametric L-systems.

Two architectures, after Prusinkiewicz and Lindenmayer, *The Algorithmic Beauty of Plants*
(1990), chapter 2 (monopodial and sympodial branching):

- **conifer** (monopodial): a single leader that lays down one whorl of branches a year,
  and two shorter interwhorl branches (the apex rolls by the golden angle between whorls);
  every branch elongates each year, so the lower (older) branches are the longest and the
  crown is a cone. Branches droop by tropism toward -Z. The crown reaches down to
  ``1 - crown_ratio`` of the height. Its needles are added when the tree is placed, in
  metres (:func:`needle_clusters`): decimetre clusters on the last ``needle_reach``
  metres of every axis, across a flat spray of side shoots that widens away from the tip.
- **broadleaf** (sympodial): a clear bole up to the crown base, then forks of two or three
  daughters (chosen by a stochastic production) that spread and turn up, ending in leaf
  clusters; the crown is an ellipsoidal dome.

The turtle's colour index marks what it draws (``'(0)`` the stem, ``'(1)`` branches), and
the ``{ . }`` polygons are leaves or needle clusters, so every triangle carries a part:
:data:`TREE_PARTS`. A grown tree is normalised so its stem stands at the origin and its top
is at ``z = 1`` (:class:`TreeModel`); :func:`place_tree` scales it to a height, a crown
radius and a stem diameter at breast height.

>>> import numpy as np
>>> m = grow_tree("PIAB", rng=np.random.default_rng(0))
>>> m.form, float(m.vertices[:, 2].max())
('conifer', 1.0)
>>> v, f, p = place_tree(m, position=(0.0, 0.0, 0.0), height=20.0, crown_radius=3.0,
...                      rng=np.random.default_rng(1))
>>> sorted(set(p.tolist())), float(v[:, 2].max())  # trunk, branch, needle triangles
([0, 1, 2], 20.0)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.validate import check_array, check_positive, check_rng

__all__ = ["TREE_PARTS", "SPECIES", "Species", "TreeModel", "species_for", "species_fallback",
           "grow_tree",
           "place_tree", "needle_clusters", "crown_years", "LEADER_GROWTH", "NEEDLE_CLUSTER",
           "NEEDLE_DENSITY", "FAN", "WHORL_AREA", "spray_scale", "hull_radius",
           "LEAF_AREA_INDEX", "crown_envelope", "SUN_CROWN_DEPTH", "SUN_CROWN_RATIO",
           "crown_media"]

TREE_PARTS = ("trunk", "branch", "leaf")
"""Part of each tree triangle: the stem, a branch, a leaf or needle cluster."""

BREAST_HEIGHT = 1.3  # metres: where the diameter (dbh) is measured


@dataclass(frozen=True)
class Species:
    """Architecture of a species (or a generic form).

    Attributes
    ----------
    code : str
        The forestry 4-letter code (genus + species initials: PIAB = Picea abies).
    latin : str
    form : {'conifer', 'broadleaf'}
    crown_ratio : float
        Crown length / tree height.
    crown_width : float
        Crown radius / tree height when the inventory gives none.
    branch_angle : float
        Degrees between a branch and the stem at its base.
    droop : float
        Tropism toward -Z of the branches (0: straight).
    whorl : int
        Conifers: branches per whorl. Broadleaves: forking levels.
    needle_reach : float
        Conifers: metres of each shoot, back from its tip, that still carry needles (the
        years a needle lives times a year's shoot growth).
    spray : float
        Conifers: half-width of a branch's foliage (its lateral shoots), metres.
    """

    code: str
    latin: str
    form: str
    crown_ratio: float
    crown_width: float
    branch_angle: float
    droop: float
    whorl: int
    needle_reach: float = 1.5
    spray: float = 0.3


SPECIES = {s.code: s for s in (
    Species("PIAB", "Picea abies", "conifer", 0.75, 0.12, 80, 0.25, 5, 2.0, 0.35),
    Species("ABAL", "Abies alba", "conifer", 0.65, 0.12, 85, 0.10, 5, 2.0, 0.35),
    Species("ABCO", "Abies concolor", "conifer", 0.65, 0.12, 85, 0.10, 5, 2.0, 0.35),
    Species("PISY", "Pinus sylvestris", "conifer", 0.40, 0.14, 60, 0.05, 4, 0.8, 0.25),
    Species("PSME", "Pseudotsuga menziesii", "conifer", 0.60, 0.13, 75, 0.15, 5, 1.5, 0.35),
    Species("LADE", "Larix decidua", "conifer", 0.55, 0.12, 70, 0.15, 5, 0.8, 0.25),
    Species("PIPO", "Pinus ponderosa", "conifer", 0.50, 0.14, 65, 0.05, 4, 1.0, 0.30),
    Species("FASY", "Fagus sylvatica", "broadleaf", 0.60, 0.20, 35, 0.0, 6),
    Species("QURO", "Quercus robur", "broadleaf", 0.55, 0.24, 45, 0.0, 6),
    Species("BEPE", "Betula pendula", "broadleaf", 0.60, 0.16, 30, 0.1, 6),
    Species("ACPS", "Acer pseudoplatanus", "broadleaf", 0.55, 0.20, 40, 0.0, 6),
    Species("GENB", "generic broadleaf", "broadleaf", 0.55, 0.20, 40, 0.0, 6),
    Species("GENC", "generic conifer", "conifer", 0.60, 0.13, 75, 0.10, 5, 1.5, 0.3),
)}
"""The species known by code; :func:`species_for` also takes the Latin names."""


# genus -> the species standing in for it: same leaf habit and, for conifers, shade
# tolerance (Abies, Picea, Tsuga, Taxus: tolerant, crowns low; Pinus, Larix: light-demanding)
_GENERA = {"abies": "ABAL", "picea": "PIAB", "tsuga": "ABAL", "taxus": "ABAL",
           "pinus": "PISY", "larix": "LADE", "pseudotsuga": "PSME", "fagus": "FASY",
           "quercus": "QURO", "betula": "BEPE", "acer": "ACPS"}
# other conifer genera (the generic conifer); any other genus is a broadleaf
_CONIFERS = ("cedrus", "chamaecyparis", "cupressus", "juniperus", "sequoia",
             "sequoiadendron", "thuja", "cryptomeria", "metasequoia", "taxodium")
# the first two letters of a 4-letter code (genus initials) -> the genus, where only one
# genus of the species table starts so; "PI" (Picea or Pinus) is the generic conifer
_CODE_GENUS = {"AB": "abies", "TS": "tsuga", "TA": "taxus", "LA": "larix",
               "PS": "pseudotsuga", "FA": "fagus", "QU": "quercus", "BE": "betula",
               "AC": "acer", "CE": "cedrus", "JU": "juniperus", "TH": "thuja", "CU": "cupressus"}


def species_fallback(name: str) -> tuple[Species, str | None]:
    """The species of a code or Latin name, and why when it is a stand-in.

    A name the table does not know falls back to the closest functional type: a species of
    the same genus (by its Latin genus, or a 4-letter code's first two letters), else the
    generic conifer (``GENC``) for a conifer genus or a ``PI..`` code (*Picea* or
    *Pinus*), else the generic broadleaf (``GENB``). The reason is None for a known name.

    >>> species_fallback("ABGR")[0].code, species_fallback("Pinus nigra")[0].code
    ('ABAL', 'PISY')
    >>> sp, why = species_fallback("TICO")
    >>> sp.code, why.split(": ")[1]
    ('GENB', 'grown as GENB (generic broadleaf), no genus known by its code')
    """
    key = str(name).strip()
    if key.upper() in SPECIES:
        return SPECIES[key.upper()], None
    low = " ".join(key.lower().split())
    for s in SPECIES.values():
        if s.latin.lower() == low:
            return s, None
    genus = low.split(" ")[0] if " " in low else _CODE_GENUS.get(key.upper()[:2], "")
    if genus in _GENERA:
        code, how = _GENERA[genus], f"genus {genus.capitalize()}"
    elif genus in _CONIFERS or (" " not in low and key.upper().startswith("PI")):
        code, how = "GENC", (f"conifer genus {genus.capitalize()}" if genus else
                             "a PI.. code: Picea or Pinus")
    else:
        code = "GENB"
        how = (f"genus {genus.capitalize()} taken as a broadleaf" if " " in low else
               "no genus known by its code")
    sp = SPECIES[code]
    return sp, f"unknown species {key!r}: grown as {code} ({sp.latin}), {how}"


def species_for(name: str) -> Species:
    """The species of a code (``PIAB``) or a Latin name (``Picea abies``), any case; an
    unknown name gets the closest functional type (:func:`species_fallback`).

    >>> species_for("picea abies").code, species_for("Tilia cordata").code
    ('PIAB', 'GENB')
    """
    return species_fallback(name)[0]


@dataclass
class TreeModel:
    """A grown tree, normalised: stem base at the origin, top at ``z = 1``.

    Attributes
    ----------
    vertices : (n, 3) float64
    triangles : (m, 3) int64
    parts : (m,) uint8
        Index into :data:`TREE_PARTS` per triangle.
    crown_radius : float
        Broadleaves: horizontal distance from the stem axis within which 90 % of the leaf
        vertices lie (height units). Conifers: the radius of the circle of the area of the
        convex hull of the shoots seen from above, as an inventory derived from a LiDAR
        segmentation measures a crown.
    stem_radius : float
        Stem radius at breast height for a tree 1 unit tall... as built (height units);
        :func:`place_tree` rescales the stem to the diameter asked for.
    form : str
    shoots : (k, 2, 3) float64 or None
        Conifers: the axes (stem and branches) as segments, normalised like ``vertices``;
        their needles are added in metres when the tree is placed (:func:`place_tree`),
        so the needle clusters keep their size whatever the tree's.
    shoot_parents : (k,) int64 or None
        The shoot each one continues along the same axis (-1 at an axis' base).
    species : str
        The species' code.
    whorls : int
        Conifers: the whorls of the crown (0 for broadleaves).
    """

    vertices: np.ndarray
    triangles: np.ndarray
    parts: np.ndarray
    crown_radius: float
    stem_radius: float
    form: str
    shoots: np.ndarray | None = None
    shoot_parents: np.ndarray | None = None
    species: str = ""
    whorls: int = 0


_LEAF = "[&(40)$^(30){{.+(35)f({s}).-(70)f({s}).-(110)f({s}).}}]"


def _conifer_grammar(sp: Species, rng: np.random.Generator, years: int,
                     crown_ratio: float) -> str:
    internode = 1.0
    k = sp.whorl + int(rng.integers(-1, 2))
    ang = sp.branch_angle + rng.uniform(-8, 8)
    b0 = 0.9 * rng.uniform(0.85, 1.15)
    gr = 0.93
    roll = 360.0 / k
    whorl = "".join(f"[&({ang + rng.uniform(-6, 6):.1f})'(1)!(0.06)B({b0:.3f})]/({roll:.1f})"
                    for _ in range(k))
    # interwhorl branches: shorter, two per year halfway up the year's shoot (Pseudotsuga,
    # Abies and Picea have them; pines few, but their long needles fill the same space)
    inter = "".join(f"[&({ang + rng.uniform(-6, 6):.1f})'(1)!(0.04)B({0.5 * b0:.3f})]/(180)"
                    for _ in range(2))
    # the crown is the last `years` whorls; the bole below it has shed its branches
    bole = years * internode * (1.0 - crown_ratio) / crown_ratio
    # the axes only: the needles are added in metres when the tree is placed
    return "\n".join([
        f"n: {years}",
        f"tropism: 0, 0, -1, {0.3 * sp.droop:.3f}",
        f"axiom: '(0)!(0.3)F({bole:.3f})A(0.25)",
        f"A(w) -> !(w)F({internode / 2})/(90)[{inter}]F({internode / 2})[{whorl}]/(137.5)"
        "A(w * 0.85)",
        f"B(l) -> !(0.04)F(l)B(l * {gr})",
    ])


def _broadleaf_grammar(sp: Species, rng: np.random.Generator, crown_ratio: float) -> str:
    depth = sp.whorl
    a = sp.branch_angle + rng.uniform(-5, 5)
    # the species' own ratio gives a bole of (1 - ratio) 12 units; another ratio scales the
    # bole to the crown by (1 - ratio) / ratio against the species'
    bole = 12.0 * sp.crown_ratio * (1.0 - crown_ratio) / crown_ratio
    leaf = _LEAF.format(s=1.2)
    cluster = "/(72)".join([leaf] * 5)
    fork2 = (f"[&({a:.1f})!(w * 0.7)F(l)X(l * 0.82, w * 0.7, d + 1)]/(180)"
             f"[&({a * 0.8:.1f})!(w * 0.7)F(l * 0.9)X(l * 0.8, w * 0.7, d + 1)]")
    fork3 = (f"[&({a:.1f})!(w * 0.65)F(l)X(l * 0.82, w * 0.65, d + 1)]/(120)"
             f"[&({a:.1f})!(w * 0.65)F(l * 0.9)X(l * 0.8, w * 0.65, d + 1)]/(120)"
             f"[&({a * 0.6:.1f})!(w * 0.65)F(l * 0.95)X(l * 0.82, w * 0.65, d + 1)]")
    return "\n".join([
        f"n: {depth + 1}",
        f"tropism: 0, 0, 1, {0.12 - sp.droop:.3f}",
        f"axiom: '(0)!(0.4)F({bole:.3f})'(1)X(3.2, 0.3, 0)",
        f"X(l, w, d) : d < 1 -(0.55)-> /(137.5){fork2}",
        f"X(l, w, d) : d < 1 -(0.45)-> /(137.5){fork3}",
        # the outer forks carry leaves along them too, not only at their tips
        f"X(l, w, d) : d >= 1 && d < {depth - 1} -(0.55)-> /(137.5){cluster}{fork2}",
        f"X(l, w, d) : d >= 1 && d < {depth - 1} -(0.45)-> /(137.5){cluster}{fork3}",
        f"X(l, w, d) : d >= {depth - 1} -> {cluster}F(l * 0.5){cluster}",
    ])


def grow_tree(species: str | Species, *, rng: np.random.Generator,
              years: int = 14, crown_ratio: float | None = None) -> TreeModel:
    """Grow one tree of a species and normalise it (top at z = 1).

    Parameters
    ----------
    species : str or Species
        A code or Latin name (see :func:`species_for`).
    rng : numpy.random.Generator
        Whorl counts and angles of this individual, and the stochastic forks.
    years : int
        Conifers: whorls laid down (the crown's depth in internodes).
    crown_ratio : float, optional
        Crown length / tree height (default: the species', for conifers +/- 10 % by
        ``rng``).

    Returns
    -------
    TreeModel
    """
    from procgen.lsystem import derive, interpret, parse_grammar, polygon_arrays, tube_arrays

    check_rng(rng)
    sp = species if isinstance(species, Species) else species_for(species)
    if sp.form == "conifer":
        cr = (sp.crown_ratio * rng.uniform(0.9, 1.1) if crown_ratio is None
              else float(crown_ratio))
        text = _conifer_grammar(sp, rng, int(years), min(max(cr, 0.05), 0.98))
    else:
        cr = sp.crown_ratio if crown_ratio is None else float(crown_ratio)
        text = _broadleaf_grammar(sp, rng, min(max(cr, 0.05), 0.98))
    g = parse_grammar(text, source=f"<{sp.code}>")
    res = interpret(derive(g, rng=rng), g)
    model = _normalise(res, sp, polygon_arrays, tube_arrays)
    if sp.form == "conifer":
        model.whorls = int(years)
    return model


def _normalise(res, sp: Species, polygon_arrays, tube_arrays) -> TreeModel:
    from procgen.lsystem import TurtleResult

    parts_v, parts_f, parts_l = [], [], []
    count = 0
    # conifers carry hundreds of thin branches: triangular tubes without caps suffice
    thin = (3, False) if sp.form == "conifer" else (4, True)
    for label, mask, sides, caps in ((0, res.colors == 0, 6, True),
                                     (1, res.colors != 0, *thin)):
        idx = np.flatnonzero(mask)
        if len(idx) == 0:
            continue
        remap = np.full(len(res.starts), -1, np.int64)
        remap[idx] = np.arange(len(idx))
        par = res.parents[idx]
        par = np.where(par >= 0, remap[np.maximum(par, 0)], -1)
        sub = TurtleResult(res.starts[idx], res.ends[idx], res.frames[idx], res.widths[idx],
                           res.colors[idx], par, np.empty((0, 3)), np.empty(0, np.int64))
        v, f = tube_arrays(sub, sides=sides, caps=caps)
        parts_v.append(v)
        parts_f.append(f.astype(np.int64) + count)
        parts_l.append(np.full(len(f), label, np.uint8))
        count += len(v)
    v, f = polygon_arrays(res)
    if len(f):
        parts_v.append(v)
        parts_f.append(f.astype(np.int64) + count)
        parts_l.append(np.full(len(f), 2, np.uint8))
    V = np.vstack(parts_v)
    F = np.vstack(parts_f)
    P = np.concatenate(parts_l)
    top = float(V[:, 2].max())
    V = V / top
    stem_w = res.widths[res.colors == 0]
    if sp.form == "conifer":
        shoots = np.stack([res.starts, res.ends], 1) / top
        par = np.asarray(res.parents, np.int64).copy()
        # an axis continues its parent only within the same kind (a branch's base hangs
        # on the stem, a new axis)
        same = (par >= 0) & (res.colors[np.maximum(par, 0)] == res.colors)
        par[~same] = -1
        ends = shoots[res.colors != 0, 1, :2]
        return TreeModel(V, F, P, hull_radius(ends), float(stem_w.max()) / 2 / top, sp.form,
                         shoots=shoots, shoot_parents=par, species=sp.code)
    leafy = V[F[P == 2].ravel()] if np.any(P == 2) else V
    # the crown's radius as an inventory measures it (the edge of the foliage, not the
    # tip of the longest shoot): 90 % of the leaf vertices lie within it
    crown = float(np.percentile(np.hypot(leafy[:, 0], leafy[:, 1]), 90))
    return TreeModel(V, F, P, crown, float(stem_w.max()) / 2 / top, sp.form, species=sp.code)


def hull_radius(xy: np.ndarray) -> float:
    """sqrt(area / pi) of the convex hull of points ``(n, 2)``."""
    from scipy.spatial import ConvexHull, QhullError

    try:
        area = ConvexHull(xy).volume if len(xy) >= 3 else 0.0
    except QhullError:
        area = 0.0
    return float(np.sqrt(area / np.pi)) if area > 0 else float(np.abs(xy).max(initial=1e-3))


LEAF_AREA_INDEX = 6.0
"""One-sided leaf area per unit of crown projection of a broadleaf crown, m²/m²: closed
mature European beech stands hold 5.6-9.5 (mean 7.4, 23 stands by litter traps:
Leuschner et al. 2006, *Variation in leaf area index and stand leaf mass of European
beech across gradients of soil acidity and precipitation*, Plant Ecology 182: 247-258,
doi:10.1007/s11258-005-9030-9), managed ones 4.5-5.1 (Cerny et al. 2020, J. For. Res.
31: 827-836, doi:10.1007/s11676-018-0850-z); sycamore maple 4.0 (the same)."""


def _outward_hull(p: np.ndarray):
    """The convex hull of ``p (n, 3)`` as ``(vertices (k, 3), triangles (m, 3) int64 with
    outward faces, volume)``."""
    from scipy.spatial import ConvexHull

    hull = ConvexHull(p)
    used = np.unique(hull.simplices)
    remap = np.zeros(len(p), np.int64)
    remap[used] = np.arange(len(used))
    V = p[used]
    F = remap[hull.simplices]
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    flip = np.einsum("ij,ij->i", n, hull.equations[:, :3]) < 0
    F[flip] = F[flip][:, ::-1]
    return V, F, float(hull.volume)


def crown_envelope(points: np.ndarray, leaf_area_index: float = LEAF_AREA_INDEX):
    """A broadleaf crown as a turbid medium: the convex hull of its foliage ``points
    (n, 3)`` (its leaf clusters' corners), faces outward, and the leaf area density that
    puts ``leaf_area_index`` m² of leaves over each m² of its projection.

    Returns ``(vertices (k, 3), triangles (m, 3) int64, leaf_area_density m²/m³)``.

    >>> g = np.array([[x, y, z] for x in (0, 2) for y in (0, 3) for z in (0, 4)], float)
    >>> v, f, lad = crown_envelope(g, 6.0)     # a 2 x 3 x 4 m box: 36 m² over 24 m³
    >>> len(f), lad
    (12, 1.5)
    """
    from scipy.spatial import ConvexHull

    p = check_array(points, "points", shape=(None, 3))
    lai = check_positive(leaf_area_index, "leaf_area_index")
    V, F, volume = _outward_hull(p)
    return V, F, float(lai * ConvexHull(p[:, :2]).volume / volume)


SUN_CROWN_DEPTH = 1.0 / 3.0
"""The sun crown's share of a broadleaf crown's length, from its top: the upper third,
where a closed beech canopy's sun leaves are (the crown's outer, lit layer)."""

SUN_CROWN_RATIO = 3.0
"""Leaf area density of a broadleaf's sun crown over that of its shade crown below. In
adult European beech the leaf area density peaks in the uppermost, peripheral sun-leaf
layer (Hagemeier and Leuschner 2019, *Functional crown architecture of five temperate
broadleaf tree species*, Forests 10: 265, doi:10.3390/f10030265), as Horn's monolayer
crowns of shade-tolerant trees put their leaves in the crown's outer shell (Horn 1971,
*The Adaptive Geometry of Trees*, Princeton). A crown uniform in leaf area density puts a
quarter of its leaves in its upper third (a sphere's cap of two thirds of its radius);
three times the density there puts half of them: the order of the sun/shade contrast
those harvests report (an assumption of this model, not a fitted figure)."""

_CAP_INSET = 0.01  # metres: the sun crown is shrunk this far inside the crown's envelope


def _cap(V: np.ndarray, F: np.ndarray, zc: float) -> np.ndarray:
    """The corners of the convex polyhedron ``(V, F)`` cut at height ``zc``, its part
    above: the vertices above and the points where its edges cross ``zc``."""
    e = np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    e = np.unique(np.sort(e, axis=1), axis=0)
    a, b = V[e[:, 0]], V[e[:, 1]]
    cross = (a[:, 2] - zc) * (b[:, 2] - zc) < 0
    t = (zc - a[cross, 2]) / (b[cross, 2] - a[cross, 2])
    cut = a[cross] + t[:, None] * (b[cross] - a[cross])
    return np.vstack([V[V[:, 2] >= zc], cut])


def crown_media(points: np.ndarray, leaf_area_index: float = LEAF_AREA_INDEX, *,
                sun_ratio: float = SUN_CROWN_RATIO, sun_depth: float = SUN_CROWN_DEPTH):
    """A broadleaf crown as nested turbid media whose leaf area densities add: the convex
    hull of its foliage ``points (n, 3)`` and, inside it, its sun crown (the hull's part
    above ``1 - sun_depth`` of its height, shrunk :data:`_CAP_INSET` inside), so that the
    density there is ``sun_ratio`` times the density below, and the crown holds
    ``leaf_area_index`` m² of leaves over each m² of its projection in all.

    Returns a list of ``(vertices (k, 3), triangles (m, 3) int64 outward, leaf area
    density m²/m³)``: the hull first, then the sun crown's extra density (absent when
    ``sun_ratio`` is 1). With ``sun_ratio = 1`` this is :func:`crown_envelope`.

    >>> g = np.array([[x, y, z] for x in (0, 2) for y in (0, 3) for z in (0, 3)], float)
    >>> [(len(f), round(lad, 4)) for _, f, lad in crown_media(g, 6.0, sun_ratio=1.0)]
    [(12, 2.0)]
    >>> (_, _, shade), (v, _, extra) = crown_media(g, 6.0, sun_ratio=3.0)
    >>> float(v[:, 2].min().round(3)), round(shade + extra, 4) == round(3 * shade, 4)
    (2.01, True)
    """
    from scipy.spatial import ConvexHull, QhullError

    p = check_array(points, "points", shape=(None, 3))
    lai = check_positive(leaf_area_index, "leaf_area_index")
    ratio = check_positive(sun_ratio, "sun_ratio")
    if not 0 < sun_depth < 1:
        raise ValueError(f"sun_depth: expected in (0, 1), got {sun_depth}")
    V, F, volume = _outward_hull(p)
    leaf_area = lai * ConvexHull(p[:, :2]).volume
    lo, hi = float(V[:, 2].min()), float(V[:, 2].max())
    cap = _cap(V, F, hi - sun_depth * (hi - lo))
    if ratio == 1.0 or len(cap) < 4:
        return [(V, F, float(leaf_area / volume))]
    try:
        cv, cf, _ = _outward_hull(cap)
    except QhullError:                     # a flat cap (coplanar corners): no sun crown
        return [(V, F, float(leaf_area / volume))]
    c = cv.mean(axis=0)                    # inside the cap: a mean of its corners
    shrink = max(0.0, 1.0 - 2.0 * _CAP_INSET / max(float(np.ptp(cv, axis=0).min()), 1e-9))
    cv = c + (cv - c) * shrink
    cvol = float(ConvexHull(cv).volume)
    shade = leaf_area / (volume + (ratio - 1.0) * cvol)
    return [(V, F, float(shade)), (cv, cf, float((ratio - 1.0) * shade))]


LEADER_GROWTH = 0.45
"""Metres a conifer's leader grows a year: a crown of length ``L`` holds ``L / 0.45``
whorls (:func:`crown_years`)."""


def crown_years(height: float, crown_ratio: float) -> int:
    """Whorls in the crown of a conifer ``height`` metres tall (6-24: the number of
    branches, and so of triangles, stays bounded).

    >>> crown_years(12.0, 0.6)
    16
    """
    return int(np.clip(round(height * crown_ratio / LEADER_GROWTH), 6, 24))


NEEDLE_CLUSTER = 0.2
"""Side of a needle cluster's triangle, metres: a shoot's tuft of needles."""

NEEDLE_DENSITY = 50.0
"""Needle clusters per square metre of a branch's needled spray."""

FAN = 0.5
"""A branch's spray widens by this much per metre back from its tip: its side shoots, a
year older with every year's shoot of the axis, are longer the farther from the tip."""

WHORL_AREA = 1.23
"""Square metres of crown projection that a whorl's branches fill with sprays of their
species' width: that of the crowns the needle density was set on (21 m tall, 3 m radius:
pi 3^2 over 23 whorls for *Pinus ponderosa*, 24 for the firs). A crown with more area per
whorl widens its sprays in proportion (:func:`spray_scale`)."""


def spray_scale(crown_radius: float, whorls: int, *, whorl_area: float = WHORL_AREA) -> float:
    """How much wider than its species' a conifer's sprays grow: the crown's projected area
    per whorl, ``pi R^2 / whorls``, over ``whorl_area`` (at least 1).

    A whorl lays down a fixed number of branches, but the ring of crown projection its
    foliage must close grows with the crown's area and shrinks with its whorls: as a tree
    and its crown grow, its branches ramify, their side shoots spread and keep the crown's
    shell closed. With sprays of a fixed width a large crown would open between its
    branches (a 24 m *Pinus ponderosa* with a 4.2 m crown stopped 64 % of nadir rays
    between 0.4 and 0.8 of its radius, one 21 m tall with a 3 m crown 85 %).

    >>> spray_scale(3.0, 23), round(spray_scale(4.2, 24), 2)
    (1.0, 1.88)
    """
    r = check_positive(crown_radius, "crown_radius")
    a = check_positive(whorl_area, "whorl_area")
    if whorls <= 0:
        return 1.0
    return float(max(1.0, np.pi * r * r / (whorls * a)))


def place_tree(model: TreeModel, *, position, height: float, crown_radius: float | None = None,
               dbh: float | None = None, azimuth: float = 0.0,
               rng: np.random.Generator | None = None,
               needle_cluster: float = NEEDLE_CLUSTER, needle_density: float = NEEDLE_DENSITY,
               crown_offset=(0.0, 0.0), whorl_area: float = WHORL_AREA,
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Scale a normalised tree to its size and stand it at ``position``.

    Parameters
    ----------
    model : TreeModel
    position : (3,) float
        Stem base (on the ground), metres.
    height : float
        Tree height, metres: the top ends exactly at ``position[2] + height``.
    crown_radius : float, optional
        Metres (default: the model's own proportion times ``height``).
    dbh : float, optional
        Stem diameter at 1.3 m, metres (default: the model's own proportion).
    azimuth : float
        Rotation about the stem, radians.
    rng : numpy.random.Generator, optional
        Conifers: where the needle clusters go (default: seed 0).
    needle_cluster : float
        Conifers: side of a needle cluster's triangle, metres.
    needle_density : float
        Conifers: needle clusters per square metre of a branch's needled spray.
    crown_offset : (2,) float
        Metres from the stem to the centre of the crown's projection (a crown grown towards
        the open side, as crowns between neighbours do: Seidel et al. 2011). The crown
        reaches ``1 + a cos(t)`` of its radius at azimuth ``t`` from the offset's direction,
        ``a = |offset| / crown radius`` (at most 0.6), which moves a round crown's centre by
        ``a`` radii; the stem and the top stay where they are.
    whorl_area : float
        Conifers: square metres of crown projection a whorl fills with sprays of the
        species' width; a crown with more per whorl widens them (:func:`spray_scale`).

    Returns
    -------
    vertices : (n, 3) float64
    triangles : (m, 3) int64
    parts : (m,) uint8
    """
    p = check_array(position, "position", shape=(3,))
    h = check_positive(height, "height")
    kxy = h if crown_radius is None else check_positive(crown_radius, "crown_radius") / \
        model.crown_radius
    sp = species_for(model.species) if model.shoots is not None else None
    widen = 1.0
    if sp is not None:
        widen = spray_scale(model.crown_radius * kxy, model.whorls, whorl_area=whorl_area)
    if sp is not None and crown_radius is not None:
        # the needles' spray reaches half its width beyond the branch tips
        kxy = max(crown_radius - 0.5 * widen * sp.spray, 0.5 * crown_radius) / \
            model.crown_radius
    V = model.vertices * np.array([kxy, kxy, h])
    if dbh is not None or kxy != h:
        # the stem keeps its own proportion (or the diameter asked for), not the crown's
        r_want = (0.5 * check_positive(dbh, "dbh") if dbh is not None
                  else model.stem_radius * h)
        stem_v = np.unique(model.triangles[model.parts == 0])
        r_now = model.stem_radius * kxy
        V[stem_v, :2] *= r_want / max(r_now, 1e-12)
    F, P = model.triangles, model.parts
    if sp is not None:
        shoots = model.shoots * np.array([kxy, kxy, h])
        nv, nf = needle_clusters(shoots, model.shoot_parents, sp,
                                 rng if rng is not None else np.random.default_rng(0),
                                 size=needle_cluster, density=needle_density, widen=widen)
        nv[:, 2] = np.minimum(nv[:, 2], h)  # the leader's tip stays the top
        F = np.vstack([F, nf + len(V)])
        P = np.concatenate([P, np.full(len(nf), 2, np.uint8)])
        V = np.vstack([V, nv])
    c, s = np.cos(azimuth), np.sin(azimuth)
    V = V @ np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    d = np.asarray(crown_offset, np.float64).reshape(2)
    if np.any(d != 0):
        r = crown_radius if crown_radius is not None else model.crown_radius * kxy
        a = min(float(np.hypot(*d)) / max(r, 1e-9), 0.6)
        u = d / np.hypot(*d)
        rho = np.hypot(V[:, 0], V[:, 1])
        cos_t = np.divide(V[:, :2] @ u, rho, out=np.zeros(len(V)), where=rho > 1e-12)
        k = 1.0 + a * cos_t
        k[np.unique(model.triangles[model.parts == 0])] = 1.0  # the stem stays round
        V[:, :2] *= k[:, None]
    return V + p, F, P


def needle_clusters(shoots: np.ndarray, parents: np.ndarray, species: Species,
                    rng: np.random.Generator, *, size: float = NEEDLE_CLUSTER,
                    density: float = NEEDLE_DENSITY,
                    widen: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Needle clusters along a conifer's axes, in metres.

    Each shoot (segment ``(k, 2, 3)``) carries needles on the last
    ``species.needle_reach`` metres of its axis back from the axis' tip (older needles
    have fallen, and the inner crown is shaded). There the branch is a flat spray of side
    shoots, ``species.spray + FAN x`` either side at ``x`` metres from the tip and a
    quarter of that above and below; ``density`` clusters per square metre of it, each a
    triangle of side ``size`` turned at random. ``widen`` multiplies the spray's width
    (``species.spray`` and the fan): the side shoots of a large crown's branches
    (:func:`spray_scale`).

    Returns
    -------
    vertices : (3 n, 3) float64
    triangles : (n, 3) int64
    """
    k = len(shoots)
    a, b = shoots[:, 0], shoots[:, 1]
    length = np.linalg.norm(b - a, axis=1)
    # distance from each shoot's end to the farthest tip of its axis
    beyond = np.zeros(k)
    for i in range(k - 1, -1, -1):
        q = parents[i]
        if q >= 0:
            beyond[q] = max(beyond[q], beyond[i] + length[i])
    reach = species.needle_reach
    # the needled stretch of each shoot, as distances from its axis' tip: [x0, x1]
    x0 = beyond
    x1 = np.minimum(beyond + length, reach)
    x1 = np.maximum(x1, x0)
    c, f = species.spray * widen, FAN * widen
    area = 2 * (c * (x1 - x0) + 0.5 * f * (x1 ** 2 - x0 ** 2))  # of the spray, m^2
    n = rng.poisson(density * area)
    seg = np.repeat(np.arange(k), n)
    m = len(seg)
    if m == 0:
        return np.empty((0, 3)), np.empty((0, 3), np.int64)
    # distance from the tip, drawn with the spray's width (c + f x): inverse of its CDF
    s0, s1 = x0[seg], x1[seg]
    cdf = rng.uniform(0.0, 1.0, m) * (c * (s1 - s0) + 0.5 * f * (s1 ** 2 - s0 ** 2))
    x = (-c + np.sqrt(c * c + 2 * f * (cdf + c * s0 + 0.5 * f * s0 ** 2))) / f
    t = 1.0 - (x - beyond[seg]) / np.maximum(length[seg], 1e-12)
    d = (b - a)[seg] / np.maximum(length[seg], 1e-12)[:, None]
    centre = a[seg] + t[:, None] * (b - a)[seg]
    # the spray's frame: across the shoot horizontally, and its normal
    side = np.cross(d, [0.0, 0.0, 1.0])
    ns = np.linalg.norm(side, axis=1)
    side = np.where(ns[:, None] > 1e-6, side / np.maximum(ns, 1e-12)[:, None], [1.0, 0, 0])
    up = np.cross(side, d)
    width = c + f * x
    centre += (side * (width * rng.uniform(-1, 1, m))[:, None]
               + up * (width / 4 * rng.uniform(-1, 1, m))[:, None])
    # an equilateral triangle in a random plane
    u = rng.normal(size=(m, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    w = np.cross(u, rng.normal(size=(m, 3)))
    w /= np.maximum(np.linalg.norm(w, axis=1, keepdims=True), 1e-12)
    v = np.cross(w, u)
    r = size / np.sqrt(3.0)
    h3 = np.sqrt(3.0) / 2
    corners = [u, -0.5 * u + h3 * v, -0.5 * u - h3 * v]
    V = np.stack([centre + r * c for c in corners], 1).reshape(-1, 3)
    return V, np.arange(3 * m, dtype=np.int64).reshape(m, 3)
