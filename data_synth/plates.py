"""A flat plate under a laser sheet, and a concave groove: the benches of material and
inter-reflection effects on triangulation.

The plate lies on z = 0; the sheet comes in at ``incidence_deg`` from the normal in the
xz plane and draws its stripe along y at x = 0; the camera looks down at the stripe from
the other side at ``view_deg``, its image rows along y, so every row crosses the stripe
once. Everything a measurement needs is returned: the scene, the camera, the laser and
the camera pose (:class:`LaserPlate`); :meth:`LaserPlate.triangulate` intersects the
camera rays through detected stripe columns with the sheet's plane, as a scanner does.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acquire.camera import Camera
from acquire.laser.sheet import LaserSheet
from acquire.render.materials import Material
from acquire.render.scene import RenderScene, SceneObject
from core.meshes import make_mesh
from core.validate import check_range

__all__ = ["LaserPlate", "laser_plate", "v_groove"]


@dataclass
class LaserPlate:
    scene: RenderScene
    camera: Camera
    laser: LaserSheet

    def triangulate(self, cols: np.ndarray) -> np.ndarray:
        """World points ``(h, 3)`` where the camera rays through ``(row, cols[row])``
        meet the sheet's plane (NaN rows stay NaN)."""
        rows = np.arange(len(cols), dtype=np.float64)
        px = np.stack([np.asarray(cols, np.float64), rows], 1)
        o, d = self.camera.rays(np.nan_to_num(px))
        n, dd = self.laser.plane
        t = (dd - o @ n) / (d @ n)
        pts = o + t[:, None] * d
        pts[~np.isfinite(cols)] = np.nan
        return pts


def laser_plate(material: Material, *, incidence_deg: float = 30.0, view_deg: float = 30.0,
                distance: float = 0.3, width: int = 320, height: int = 96,
                fov_deg: float = 12.0, thickness: float = 0.3e-3,
                power: float = 0.35) -> LaserPlate:
    """The plate of ``material`` under a sheet at ``incidence_deg`` seen from ``view_deg``
    (both from the normal, on opposite sides) at ``distance`` metres."""
    inc = np.radians(check_range(incidence_deg, "incidence_deg", 0.0, 80.0))
    view = np.radians(check_range(view_deg, "view_deg", 0.0, 80.0))
    half = 0.2
    plate = make_mesh(np.array([[-half, -half, 0], [half, -half, 0], [half, half, 0],
                                [-half, half, 0.0]]), np.array([[0, 1, 2], [0, 2, 3]]))
    obj = SceneObject("plate", plate, material=material, object_id=0,
                      analytic={"type": "plane", "point": (0, 0, 0), "normal": (0, 0, 1)})
    scene = RenderScene([obj], lights=[], ambient=0.0)
    d = np.array([np.sin(inc), 0.0, -np.cos(inc)])            # toward the stripe
    laser = LaserSheet(origin=-distance * d, normal=np.cross(d, [0.0, 1.0, 0.0]),
                       direction=d, fan_angle=np.radians(40.0), thickness=thickness,
                       power=power, color=np.array([1.0, 0.0, 0.0]))
    eye = distance * np.array([np.sin(view), 0.0, np.cos(view)])
    cam = Camera.look_at(eye, [0.0, 0.0, 0.0], up=(0.0, 1.0, 0.0), width=width,
                         height=height, fov_deg=fov_deg)
    return LaserPlate(scene, cam, laser)


def v_groove(material: Material, *, opening_deg: float = 50.0, crease_y: float = 0.12,
             face: float = 0.18, height: float = 0.25) -> RenderScene:
    """A concave V-groove of two flat faces of ``material`` meeting at a vertical crease
    (x = 0, y = ``crease_y``), opening by ``opening_deg`` toward -y, where the scanners'
    rigs stand: each face lights the other (inter-reflections)."""
    a = np.radians(0.5 * check_range(opening_deg, "opening_deg", 10.0, 170.0))
    crease = np.array([0.0, crease_y, -0.05])
    objs = []
    for k, side in enumerate((-1.0, 1.0)):
        d = np.array([side * np.sin(a), -np.cos(a), 0.0])
        V = np.array([crease, crease + face * d, crease + face * d + [0, 0, height],
                      crease + [0, 0, height]])
        F = np.array([[0, 1, 2], [0, 2, 3]]) if side < 0 else np.array([[0, 2, 1], [0, 3, 2]])
        objs.append(SceneObject(f"face{k}", make_mesh(V, F), material=material, object_id=k))
    return RenderScene(objs, lights=[], ambient=0.0)
