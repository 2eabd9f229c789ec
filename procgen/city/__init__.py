"""procgen.city: cities as Parish and Mueller and CGA build them.

Roads grown with global goals by street pattern and local constraints (``roads``), blocks
cut into lots that front a street (``lots``), buildings from a split grammar whose rule
files are data (``cga``, ``rules/*.toml``), the city put together (``generate``), Boeing's
street statistics (``streets``), street and park trees of Weber & Penn species (``trees``),
GeoJSON and CityJSON output (``io``) and the solids of
constructive solid geometry (``csg``).

Every name below is importable from the room (``from procgen.city import NAME``), loaded on
first use.
"""

from core.lazy import lazy_exports

_EXPORTS = {
    "LABELS": "cga",
    "SHAPE_OPERATIONS": "cga",
    "build": "cga",
    "load_grammar": "cga",
    "parse_grammar": "cga",
    "shipped_rules": "cga",
    "Box": "csg",
    "Cylinder": "csg",
    "Difference": "csg",
    "Union": "csg",
    "csg_mesh": "csg",
    "ELEMENTS": "generate",
    "HIGHWAY_HALF_WIDTH": "generate",
    "STREET_HALF_WIDTH": "generate",
    "Building": "generate",
    "City": "generate",
    "CityConfig": "generate",
    "generate_city": "generate",
    "overlaps": "generate",
    "check_cityjson": "io",
    "city_cityjson": "io",
    "city_geojson": "io",
    "city_paths": "io",
    "write_city_files": "io",
    "Lot": "lots",
    "PATTERNS": "roads",
    "CityMaps": "roads",
    "city_maps": "roads",
    "grow_roads": "roads",
    "segments_cross": "roads",
    "street_statistics": "streets",
    "CityTrees": "trees",
    "city_trees": "trees",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
