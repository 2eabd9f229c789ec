"""The built scene that every scene kind returns: its spec, the render scene and the
ground-truth meshes. A module of its own so that the scene kinds (:mod:`data_synth.scenes`
and :mod:`data_synth.forest`, which subclasses it) both stand on it without importing
each other."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from acquire.render.scene import RenderScene
from core.meshes import merge_meshes

__all__ = ["SceneBundle"]


@dataclass
class SceneBundle:
    """A built scene: its spec, the render scene, and ground-truth world meshes.

    ``origin`` (3,) float64: the scene's geometry is in a local frame, ``world = local +
    origin`` (a survey's projected coordinates, millions of metres, stay exact);
    ``crs_wkt``: the coordinate system of ``world`` when known.
    """

    spec: dict
    render_scene: RenderScene
    meshes: dict  # name -> world-frame open3d mesh
    base_dir: Path | None = None
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))
    crs_wkt: str | None = None

    @property
    def name(self) -> str:
        return self.spec.get("scene", {}).get("name", "scene")

    @property
    def seed(self) -> int:
        return int(self.spec.get("scene", {}).get("seed", 0))

    def gt_mesh(self):
        """All objects merged, world frame (what mesh.ply holds)."""
        return merge_meshes(self.meshes.values())

    def object_mesh(self, name: str):
        if name not in self.meshes:
            raise ValueError(f"name: expected one of {sorted(self.meshes)}, got {name!r}")
        return self.meshes[name]

    def bounds(self) -> np.ndarray:
        return self.render_scene.bounds()
