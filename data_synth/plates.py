"""A flat plate under a laser sheet: the bench of material effects on triangulation.

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
from acquire.laser import LaserSheet
from acquire.materials import Material
from acquire.scene import RenderScene, SceneObject
from core.meshes import make_mesh
from core.validate import check_range

__all__ = ["LaserPlate", "laser_plate"]


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
