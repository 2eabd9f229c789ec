"""What the renderer sees: objects (mesh + material + pose) and lights.

A :class:`RenderScene` is built by data_synth from a scene spec, or by hand. The
Embree acceleration structure is built once per scene and cached; moving an
object (:meth:`RenderScene.with_pose`) gives a new scene that rebuilds it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from acquire.render.materials import Material
from core.frames import transform_points
from core.meshes import mesh_arrays
from core.validate import check_array

__all__ = ["SceneObject", "RenderScene"]


@dataclass(eq=False)
class SceneObject:
    """One object of a render scene.

    Parameters
    ----------
    name : str
    mesh : open3d.geometry.TriangleMesh
        In the object frame (metres); vertex normals give smooth shading.
    material : Material
    world_from_object : (4, 4) float64
    object_id : int
        Written to the ground-truth id image (>= 0).
    vertex_uvs : (n, 2) float64, optional
        Texture coordinates for 'image' materials.
    analytic : dict, optional
        An exact shape the mesh approximates, in the object frame: ``{"type": "sphere",
        "center": (3,), "radius": r}`` or ``{"type": "plane", "point": (3,), "normal": (3,)}``.
        Hits are refined onto it, so depth is exact rather than faceted.
    part_labels : (m,) uint8, optional
        Per-triangle part codes into :data:`acquire.lidar.labels.PARTS` (ground, trunk,
        leaf, building...), the truth a LiDAR survey's points inherit. The camera
        renderer ignores them.
    leaf_area_density : float, optional
        m² of leaves per m³: the closed mesh is the envelope of foliage too fine to mesh (a
        turbid medium), which the LiDAR simulator traces by Beer-Lambert
        (:mod:`acquire.lidar.medium`); the camera renderer sees the envelope.
    """

    name: str
    mesh: object
    material: Material = field(default_factory=Material)
    world_from_object: np.ndarray = field(default_factory=lambda: np.eye(4))
    object_id: int = 0
    vertex_uvs: np.ndarray | None = None
    analytic: dict | None = None
    part_labels: np.ndarray | None = None
    leaf_area_density: float | None = None

    def __post_init__(self):
        self.world_from_object = check_array(self.world_from_object, "world_from_object",
                                             shape=(4, 4))
        v, f = mesh_arrays(self.mesh)
        if len(f) == 0:
            raise ValueError(f"mesh: object {self.name!r} has no triangles")
        if self.vertex_uvs is not None:
            self.vertex_uvs = check_array(self.vertex_uvs, "vertex_uvs", shape=(len(v), 2))
        if self.part_labels is not None:
            self.part_labels = check_array(self.part_labels, "part_labels", shape=(len(f),),
                                           dtype=np.uint8)
        if self.leaf_area_density is not None and not self.leaf_area_density > 0:
            raise ValueError(f"leaf_area_density: expected > 0, got {self.leaf_area_density}")
        if not self.mesh.has_vertex_normals():
            self.mesh.compute_vertex_normals()

    def world_arrays(self):
        """World-frame ``vertices (n, 3)``, ``triangles (m, 3)``, ``vertex normals (n, 3)``."""
        v, f = mesh_arrays(self.mesh)
        T = self.world_from_object
        n = np.array(self.mesh.vertex_normals, dtype=np.float64)  # a copy, normalised below
        if not np.array_equal(T, np.eye(4)):  # (a forest's thousands of objects are placed)
            v = transform_points(T, v)
            n = n @ T[:3, :3].T
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
        return v, f, n


@dataclass(eq=False)
class RenderScene:
    """Objects and lights to render.

    Parameters
    ----------
    objects : list of SceneObject
    lights : list of lights (see :mod:`acquire.render.lights`)
    ambient : float
        Ambient irradiance added everywhere (no shadows).
    background : (3,) float
        Radiance of rays that hit nothing.
    """

    objects: list
    lights: list = field(default_factory=list)
    ambient: float = 0.1
    background: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self):
        if not self.objects:
            raise ValueError("objects: expected at least one object, got none")
        names = [o.name for o in self.objects]
        if len(set(names)) != len(names):
            raise ValueError(f"objects: expected unique names, got {names}")
        self.background = check_array(self.background, "background", shape=(3,))
        self._cache = None
        self._flat = None

    def object(self, name: str) -> SceneObject:
        for o in self.objects:
            if o.name == name:
                return o
        raise ValueError(f"name: expected one of {[o.name for o in self.objects]}, got {name!r}")

    def with_pose(self, name: str, world_from_object: np.ndarray) -> RenderScene:
        """A new scene with object ``name`` moved (geometry is shared, not copied)."""
        self.object(name)
        objs = [dataclasses.replace(o, world_from_object=world_from_object) if o.name == name
                else o for o in self.objects]
        return RenderScene(objs, list(self.lights), self.ambient, self.background)

    def with_lights(self, lights, *, ambient: float | None = None) -> RenderScene:
        """A new scene with other lights, sharing the cached ray-casting structure."""
        out = RenderScene(self.objects, list(lights),
                          self.ambient if ambient is None else ambient, self.background)
        out._cache, out._flat = self._cache, self._flat
        return out

    def raycasting(self):
        """The cached Embree scene and world-frame arrays: ``(scene, parts, geom_to_obj)``."""
        if self._cache is None:
            import open3d as o3d

            rs = o3d.t.geometry.RaycastingScene()
            parts = []
            geom_to_obj = {}
            for i, obj in enumerate(self.objects):
                vw, f, n = obj.world_arrays()
                tm = o3d.t.geometry.TriangleMesh()
                tm.vertex.positions = o3d.core.Tensor(vw.astype(np.float32))
                tm.triangle.indices = o3d.core.Tensor(f.astype(np.int32))
                gid = rs.add_triangles(tm)
                geom_to_obj[int(gid)] = i
                parts.append((vw, f, n))
            lut = np.full(max(geom_to_obj) + 1, -1, np.int64)
            for g, i in geom_to_obj.items():
                lut[g] = i
            self._cache = (rs, parts, lut)
        return self._cache

    def flat_arrays(self):
        """All objects' world-frame meshes in one set of arrays (cached), for kernels that
        index any object's triangles: ``(vertices (V, 3), faces (F, 3) int64 into them,
        vertex_normals (V, 3), face_offset (k + 1,) int64)``; object ``i``'s triangle
        ``j`` is face ``face_offset[i] + j``."""
        if self._flat is None:
            _, parts, _ = self.raycasting()
            vo = np.cumsum([0] + [len(p[0]) for p in parts])
            fo = np.cumsum([0] + [len(p[1]) for p in parts]).astype(np.int64)
            V = np.ascontiguousarray(np.vstack([p[0] for p in parts]), np.float64)
            F = np.ascontiguousarray(np.vstack([p[1].astype(np.int64) + vo[i]
                                                for i, p in enumerate(parts)]))
            N = np.ascontiguousarray(np.vstack([p[2] for p in parts]), np.float64)
            self._flat = (V, F, N, fo)
        return self._flat

    def bounds(self) -> np.ndarray:
        """World bounding box ``(2, 3)`` of all objects."""
        _, parts, _ = self.raycasting()
        return np.stack([np.min([p[0].min(0) for p in parts], axis=0),
                         np.max([p[0].max(0) for p in parts], axis=0)])
