"""Fractals: random midpoint displacement and diamond-square (with constrained
refinement of a control surface), deterministic fractals (Koch, Sierpinski, IFS by the
chaos game, Mandelbrot and Julia sets) and fractal dimension estimators."""

from procgen.fractals.deterministic import (
    BARNSLEY_FERN,
    barnsley_fern,
    chaos_game,
    colorize_escape,
    julia,
    koch_curve,
    koch_snowflake,
    mandelbrot,
    sierpinski_triangle,
)
from procgen.fractals.dimension import box_counting_dimension, box_counts, similarity_dimension
from procgen.fractals.displacement import diamond_square, midpoint_displacement, refine_heightfield

__all__ = [
    "midpoint_displacement", "diamond_square", "refine_heightfield",
    "koch_curve", "koch_snowflake", "sierpinski_triangle", "chaos_game", "barnsley_fern",
    "BARNSLEY_FERN", "mandelbrot", "julia", "colorize_escape",
    "similarity_dimension", "box_counting_dimension", "box_counts",
]
