"""Weber & Penn's trees: species parameter files, the generator, the QSM, the laws.

- :mod:`~procgen.weber_penn.params`: the parameter table and the species' TOML files
  (:func:`load_species`, :func:`species_names`);
- :mod:`~procgen.weber_penn.shapes`: crown shapes 0-8, pruning envelope, taper, flare;
- :mod:`~procgen.weber_penn.growth`: :func:`grow` a :class:`Tree` (skeleton and leaves);
- :mod:`~procgen.weber_penn.appearance`: :func:`tree_mesh` (bark, leaves, seasons, LOD);
- :mod:`~procgen.weber_penn.qsm`: :func:`tree_qsm`, the skeleton as TreeQSM cylinders;
- :mod:`~procgen.weber_penn.stand`: :func:`grow_stand`, forests by instancing;
- :mod:`~procgen.weber_penn.placement`: :class:`SpeciesTrees`, species trees placed in a
  scene (height, crown radius, dbh, parts), :func:`species_map` of forestry codes;
- :mod:`~procgen.weber_penn.laws`: Leonardo's rule, taper, angles, allometry, crown
  envelope, measured on any QSM.

>>> from procgen.weber_penn import load_species
>>> load_species("weeping_willow")["Shape"]
3
"""

from core.lazy import lazy_exports

_EXPORTS = {
    "TreeParams": "params", "load_species": "params", "species_names": "params",
    "parse_params": "params", "params_to_dict": "params", "write_species": "params",
    "shape_ratio": "shapes", "Tree": "growth", "Skeleton": "growth", "Leaves": "growth",
    "grow": "growth", "TreeMesh": "appearance", "tree_mesh": "appearance",
    "TREE_LABELS": "appearance", "bark_texture": "appearance", "tree_qsm": "qsm",
    "leonardo_exponents": "laws", "allometric_exponent": "laws", "crown_profile": "laws",
    "Stand": "stand", "grow_stand": "stand", "SpeciesTrees": "placement",
    "PlacedTree": "placement", "species_map": "placement", "FORESTRY_SPECIES": "placement",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
