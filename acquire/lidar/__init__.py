"""The pulsed time-of-flight scanner (LiDAR): part labels of the surveyed world.

Issue 31 fills this room: scan patterns, platforms, presets, the footprint, the
waveform and echo detection.
"""

from acquire.lidar.labels import PARTS, VEGETATION_PARTS, asprs_class, part_code

__all__ = ["PARTS", "VEGETATION_PARTS", "asprs_class", "part_code"]
