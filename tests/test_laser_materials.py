"""The laser frame renderer shades by the material (issue 17): a polished metal plate
sends the stripe back only near the mirror direction (saturation there, dropout
elsewhere), where a matte plate looks the same from every side."""

import numpy as np

from acquire.laser.sheet import LaserRenderer
from acquire.render.materials import Material
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


def test_a_shiny_groove_shows_a_ghost_stripe_with_the_bounce():
    """A polished metal V-groove: the camera, off the mirror direction, sees almost none
    of the direct stripe; with one bounce the stripe mirrored by the other face appears,
    brighter than the direct one and as extra peaks in the rows (the outliers a scanner
    must reject). Same seed, same bytes."""
    from acquire.camera import Camera
    from acquire.laser.sheet import LaserSheet
    from data_synth.plates import v_groove

    scene = v_groove(Material(albedo=np.full(3, 0.9), brdf="conductor", roughness=0.08),
                     opening_deg=90.0)
    cam = Camera.look_at([0.0, -0.35, 0.1], [0.0, 0.1, 0.07], width=160, height=120,
                         fov_deg=40)
    org, tgt = np.array([-0.25, -0.25, 0.08]), np.array([-0.05, 0.07, 0.08])
    d = (tgt - org) / np.linalg.norm(tgt - org)
    laser = LaserSheet(origin=org, normal=np.cross(d, [0.0, 0.0, 1.0]), direction=d,
                       fan_angle=np.radians(60.0), thickness=0.5e-3, power=0.35,
                       color=np.array([1.0, 0.0, 0.0]))

    def frame(bounces, seed=0):
        r = LaserRenderer(scene, cam, bounces=bounces)
        return r.frame(cam.cam_from_world, laser, rng=np.random.default_rng(seed)).radiance

    direct, ghost = frame(0), frame(1)
    assert ghost.max() > 20 * direct.max()
    rows = np.flatnonzero((direct.max(axis=1) > 0) & (ghost.max(axis=1) > 0.1 * ghost.max()))
    apart = np.abs(np.argmax(ghost[rows], axis=1) - np.argmax(direct[rows], axis=1))
    assert len(rows) > 10 and np.median(apart) > 10      # a second stripe, elsewhere
    assert frame(1).tobytes() == ghost.tobytes() and frame(1, 1).tobytes() != ghost.tobytes()

