"""Boids: flocks under Reynolds' steering rules or Couzin's zones, around meshes.

- :mod:`simulate.boids.flock` the model: parameters, state, one step (grid or all pairs);
- :mod:`simulate.boids._kernels` its compiled kernels (private to this room);
- :mod:`simulate.boids.recipes` named simulations from the shipped ``recipes/*.toml`` or a
  user's TOML file;
- :mod:`simulate.boids.metrics` measures of a flock: polarization, milling, nearest
  neighbours, groups.

>>> from simulate.boids import BoidParams, load_recipe
>>> load_recipe("torus").params.model
'couzin'
"""

from core.lazy import lazy_exports

_EXPORTS = {
    **dict.fromkeys(["BoidParams", "FlockState", "init_flock", "step", "perception_radius",
                     "MODELS", "METHODS"], "flock"),
    **dict.fromkeys(["Recipe", "load_recipe", "recipe_names"], "recipes"),
    **dict.fromkeys(["polarization", "milling", "nearest_neighbour_distances", "groups",
                     "flock_metrics", "METRIC_NAMES"], "metrics"),
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
