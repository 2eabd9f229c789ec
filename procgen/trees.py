"""Trees with species-like architecture, grown by parametric L-systems.

Two architectures, after Prusinkiewicz and Lindenmayer, *The Algorithmic Beauty of Plants*
(1990), chapter 2 (monopodial and sympodial branching):

- **conifer** (monopodial): a single leader that lays down one whorl of branches a year
  (the apex rolls by the golden angle between whorls); every branch elongates each year
  and carries needle clusters along it, so the lower (older) branches are the longest and
  the crown is a cone. Branches droop by tropism toward -Z.
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
>>> sorted(set(m.parts.tolist())) == [0, 1, 2]  # trunk, branch, leaf triangles
True
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.validate import check_array, check_positive, check_rng

__all__ = ["TREE_PARTS", "SPECIES", "Species", "TreeModel", "species_for", "grow_tree",
           "place_tree"]

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
    """

    code: str
    latin: str
    form: str
    crown_ratio: float
    crown_width: float
    branch_angle: float
    droop: float
    whorl: int


SPECIES = {s.code: s for s in (
    Species("PIAB", "Picea abies", "conifer", 0.75, 0.12, 80, 0.25, 5),
    Species("ABAL", "Abies alba", "conifer", 0.65, 0.12, 85, 0.10, 5),
    Species("PISY", "Pinus sylvestris", "conifer", 0.35, 0.14, 60, 0.05, 4),
    Species("PSME", "Pseudotsuga menziesii", "conifer", 0.60, 0.13, 75, 0.15, 5),
    Species("LADE", "Larix decidua", "conifer", 0.55, 0.12, 70, 0.15, 5),
    Species("PIPO", "Pinus ponderosa", "conifer", 0.45, 0.14, 65, 0.05, 4),
    Species("FASY", "Fagus sylvatica", "broadleaf", 0.60, 0.20, 35, 0.0, 6),
    Species("QURO", "Quercus robur", "broadleaf", 0.55, 0.24, 45, 0.0, 6),
    Species("BEPE", "Betula pendula", "broadleaf", 0.60, 0.16, 30, 0.1, 6),
    Species("ACPS", "Acer pseudoplatanus", "broadleaf", 0.55, 0.20, 40, 0.0, 6),
    Species("GENB", "generic broadleaf", "broadleaf", 0.55, 0.20, 40, 0.0, 6),
    Species("GENC", "generic conifer", "conifer", 0.60, 0.13, 75, 0.10, 5),
)}
"""The species known by code; :func:`species_for` also takes the Latin names."""


def species_for(name: str) -> Species:
    """The species of a code (``PIAB``) or a Latin name (``Picea abies``), any case.

    Unknown names get the generic broadleaf (``GENB``).

    >>> species_for("picea abies").code, species_for("Tilia cordata").code
    ('PIAB', 'GENB')
    """
    key = str(name).strip()
    if key.upper() in SPECIES:
        return SPECIES[key.upper()]
    low = " ".join(key.lower().split())
    for s in SPECIES.values():
        if s.latin.lower() == low:
            return s
    return SPECIES["GENB"]


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
        Horizontal distance from the stem axis within which 90 % of the leaf vertices lie
        (height units): where the foliage ends, as an inventory's crown radius says.
    stem_radius : float
        Stem radius at breast height for a tree 1 unit tall... as built (height units);
        :func:`place_tree` rescales the stem to the diameter asked for.
    form : str
    """

    vertices: np.ndarray
    triangles: np.ndarray
    parts: np.ndarray
    crown_radius: float
    stem_radius: float
    form: str


_NEEDLE = "[&(50){{.+(25)f({s}).-(50)f({s}).-(130)f({s}).}}]"
_LEAF = "[&(40)$^(30){{.+(35)f({s}).-(70)f({s}).-(110)f({s}).}}]"


def _conifer_grammar(sp: Species, rng: np.random.Generator, years: int) -> str:
    internode = 1.0
    k = sp.whorl + int(rng.integers(-1, 2))
    ang = sp.branch_angle + rng.uniform(-8, 8)
    b0 = 0.9 * rng.uniform(0.85, 1.15)
    gr = 0.93
    roll = 360.0 / k
    whorl = "".join(f"[&({ang + rng.uniform(-6, 6):.1f})'(1)!(0.06)B({b0:.3f})]/({roll:.1f})"
                    for _ in range(k))
    # the crown is the last `years` whorls; the bole below it has shed its branches
    bole = years * internode * (1.0 - sp.crown_ratio) / sp.crown_ratio
    # needle clusters: two pairs on the sides of each year's shoot and one ahead, large
    # enough that a crown is as opaque to a laser as a real one (several layers deep)
    s = 0.5
    needle = _NEEDLE.format(s=s)
    return "\n".join([
        f"n: {years}",
        f"tropism: 0, 0, -1, {0.3 * sp.droop:.3f}",
        f"axiom: '(0)!(0.3)F({bole:.3f})A(0.25)",
        f"A(w) -> !(w)F({internode})[{whorl}]/(137.5)A(w * 0.85)",
        f"B(l) -> !(0.04)F(l)[-(55)${needle}][+(55)${needle}]/(90)[-(40)${needle}]"
        f"[+(40)${needle}]{needle}B(l * {gr})",
    ])


def _broadleaf_grammar(sp: Species, rng: np.random.Generator) -> str:
    depth = sp.whorl
    a = sp.branch_angle + rng.uniform(-5, 5)
    bole = (1.0 - sp.crown_ratio) * 12.0
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
              years: int = 14) -> TreeModel:
    """Grow one tree of a species and normalise it (top at z = 1).

    Parameters
    ----------
    species : str or Species
        A code or Latin name (see :func:`species_for`).
    rng : numpy.random.Generator
        Whorl counts and angles of this individual, and the stochastic forks.
    years : int
        Conifers: whorls laid down (the crown's depth in internodes).

    Returns
    -------
    TreeModel
    """
    from procgen.lsystem import derive, interpret, parse_grammar, polygon_arrays, tube_arrays

    check_rng(rng)
    sp = species if isinstance(species, Species) else species_for(species)
    text = (_conifer_grammar(sp, rng, int(years)) if sp.form == "conifer"
            else _broadleaf_grammar(sp, rng))
    g = parse_grammar(text, source=f"<{sp.code}>")
    res = interpret(derive(g, rng=rng), g)
    return _normalise(res, sp, polygon_arrays, tube_arrays)


def _normalise(res, sp: Species, polygon_arrays, tube_arrays) -> TreeModel:
    from procgen.lsystem import TurtleResult

    parts_v, parts_f, parts_l = [], [], []
    count = 0
    for label, mask, sides in ((0, res.colors == 0, 6), (1, res.colors != 0, 4)):
        idx = np.flatnonzero(mask)
        if len(idx) == 0:
            continue
        remap = np.full(len(res.starts), -1, np.int64)
        remap[idx] = np.arange(len(idx))
        par = res.parents[idx]
        par = np.where(par >= 0, remap[np.maximum(par, 0)], -1)
        sub = TurtleResult(res.starts[idx], res.ends[idx], res.frames[idx], res.widths[idx],
                           res.colors[idx], par, np.empty((0, 3)), np.empty(0, np.int64))
        v, f = tube_arrays(sub, sides=sides, caps=True)
        parts_v.append(v)
        parts_f.append(f.astype(np.int64) + count)
        parts_l.append(np.full(len(f), label, np.uint8))
        count += len(v)
    v, f = polygon_arrays(res)
    parts_v.append(v)
    parts_f.append(f.astype(np.int64) + count)
    parts_l.append(np.full(len(f), 2, np.uint8))
    V = np.vstack(parts_v)
    F = np.vstack(parts_f)
    P = np.concatenate(parts_l)
    top = float(V[:, 2].max())
    V = V / top
    leafy = V[F[P == 2].ravel()] if np.any(P == 2) else V
    # the crown's radius as an inventory measures it (the edge of the foliage, not the
    # tip of the longest shoot): 90 % of the leaf vertices lie within it
    crown = float(np.percentile(np.hypot(leafy[:, 0], leafy[:, 1]), 90))
    stem_w = res.widths[res.colors == 0]
    return TreeModel(V, F, P, crown, float(stem_w.max()) / 2 / top, sp.form)


def place_tree(model: TreeModel, *, position, height: float, crown_radius: float | None = None,
               dbh: float | None = None, azimuth: float = 0.0
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
    V = model.vertices * np.array([kxy, kxy, h])
    if dbh is not None or kxy != h:
        # the stem keeps its own proportion (or the diameter asked for), not the crown's
        r_want = (0.5 * check_positive(dbh, "dbh") if dbh is not None
                  else model.stem_radius * h)
        stem_v = np.unique(model.triangles[model.parts == 0])
        r_now = model.stem_radius * kxy
        V[stem_v, :2] *= r_want / max(r_now, 1e-12)
    c, s = np.cos(azimuth), np.sin(azimuth)
    V = V @ np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]]) + p
    return V, model.triangles, model.parts
