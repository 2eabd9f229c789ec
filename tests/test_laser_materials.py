"""The laser frame renderer shades by the material (issue 17): a polished metal plate
sends the stripe back only near the mirror direction (saturation there, dropout
elsewhere), where a matte plate looks the same from every side."""

import numpy as np

from acquire.laser import LaserRenderer
from acquire.materials import Material
from data_synth.plates import laser_plate


def _peak(material, inc, view):
    lp = laser_plate(material, incidence_deg=inc, view_deg=view)
    fr = LaserRenderer(lp.scene, lp.camera).frame(lp.camera.cam_from_world, lp.laser)
    return float(fr.radiance.max())


def test_metal_plate_shines_at_the_mirror_angle_and_drops_out_elsewhere():
    white = np.ones(3)
    metal = Material(albedo=white, brdf="conductor", roughness=0.15)
    matte = Material(albedo=white)
    mirror, off = _peak(metal, 30.0, 30.0), _peak(metal, 30.0, 5.0)
    assert mirror > 20 * _peak(matte, 30.0, 30.0)        # a highlight: saturates a sensor
    assert off < 0.2 * _peak(matte, 30.0, 5.0)           # away from it: dropout
    # matte: the same peak radiance whatever the view (Lambert), to within the pixel
    # footprint's sampling of the thin stripe
    a, b = _peak(matte, 30.0, 30.0), _peak(matte, 30.0, 5.0)
    assert abs(a - b) < 0.15 * a
