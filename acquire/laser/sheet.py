"""The laser sheet and its frame renderer, served here for the laser room's users: they live
in the shared render room (:mod:`acquire.render.laser_sheet`) since the range-scanning head
of :mod:`acquire.scans` renders with them too (a method room never imports another)."""

from acquire.render.laser_sheet import (
                                        LaserFrame,
                                        LaserRenderer,
                                        LaserSheet,
                                        camera_directions,
                                        plane_of,
                                        subsurface_reach,
)

__all__ = ["LaserSheet", "LaserFrame", "LaserRenderer", "camera_directions", "plane_of",
           "subsurface_reach"]
