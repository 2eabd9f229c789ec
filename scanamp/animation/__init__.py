"""The animation room: procedural animations run into a folder and rendered to video.

``simulation`` (``scanamp simulate particles|cloth``: a recipe stepped, its frames and
metrics written), ``boids`` (``scanamp simulate boids``: a flock, its metrics and plots),
``render`` (splats over a mesh background, frames to MP4/GIF), shared by both.
"""

from core.lazy import lazy_exports

_EXPORTS = {
    "run_simulation": "simulation",
    "run_boids": "boids", "render_flock": "boids", "plot_metrics": "boids",
    "render_animation": "render", "write_frames": "render", "draw_splats": "render",
    "mesh_background": "render",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
