"""The pulsed time-of-flight scanner (LiDAR): presets, scan patterns, platforms and
survey planning, the beam's footprint, the waveform and its echoes, and part labels.

>>> from acquire.lidar import get_preset, Scanner
>>> Scanner.from_preset(get_preset("velodyne-vlp16")).pattern.kind
'spinning'
"""

from acquire.lidar.beam import pack_rays, subray_directions, subray_pattern
from acquire.lidar.capture import LidarCaptureConfig, plan_survey
from acquire.lidar.labels import PARTS, VEGETATION_PARTS, asprs_class, part_code
from acquire.lidar.patterns import PATTERNS, ScanPattern
from acquire.lidar.planning import SurveyPlan, plan_path, plan_stations, plan_strips
from acquire.lidar.platforms import PLATFORMS, Leg, mount_for
from acquire.lidar.presets import PRESETS, ScannerPreset, get_preset
from acquire.lidar.simulate import LidarWorld, Scanner, fire, scan_leg
from acquire.lidar.waveform import Receiver, detect_echoes

__all__ = ["PARTS", "VEGETATION_PARTS", "asprs_class", "part_code", "PRESETS",
           "ScannerPreset", "get_preset", "PATTERNS", "ScanPattern", "PLATFORMS", "Leg",
           "mount_for", "SurveyPlan", "plan_strips", "plan_path", "plan_stations",
           "subray_pattern", "subray_directions", "pack_rays", "Receiver", "detect_echoes",
           "Scanner", "LidarWorld", "fire", "scan_leg", "LidarCaptureConfig", "plan_survey"]
