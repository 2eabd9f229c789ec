"""The pulsed scanner's physics on hand-built worlds: footprint, multiple returns,
intensity (radar equation), range noise (the SNR law), a gap between two leaves."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from acquire.lidar.beam import pack_rays, subray_directions, subray_pattern
from acquire.lidar.labels import PARTS
from acquire.lidar.presets import get_preset
from acquire.lidar.simulate import LidarWorld, Scanner, fire
from acquire.render import Material, RenderScene, SceneObject
from core.meshes import make_mesh
from core.validate import InputError

RHO = 0.4
NM = 1550.0


def _quad(name, corners, oid, part, rho=RHO):
    V = np.asarray(corners, float)
    F = np.array([[0, 1, 2], [0, 2, 3]])
    mat = Material(albedo=(0.5, 0.5, 0.5), lidar_reflectance=(rho, rho, rho))
    return SceneObject(name, make_mesh(V, F), mat, object_id=oid,
                       part_labels=np.full(2, PARTS.index(part), np.uint8))


def _ground(half=500.0, z=0.0, rho=RHO):
    return _quad("ground", [[-half, -half, z], [half, -half, z], [half, half, z],
                            [-half, half, z]], 1, "ground", rho)


def _world(*objs):
    return LidarWorld(RenderScene(list(objs)), NM)


def _scanner(**kw):
    return Scanner.from_preset(get_preset("riegl-lms-q560"), **kw)


def _beam(n, theta_deg, R):
    """Pulses toward the ground's origin at incidence theta from range R (in x-z)."""
    t = np.radians(theta_deg)
    d = np.array([np.sin(t), 0.0, -np.cos(t)])
    return np.tile(-d * R, (n, 1)), np.tile(d, (n, 1))


def test_packed_subrays_agree_with_the_numpy_cone():
    rng = np.random.default_rng(0)
    d = rng.normal(size=(50, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    offs, _ = subray_pattern(5)
    ref = subray_directions(d, 3e-3, offs).reshape(-1, 3)
    rays = pack_rays(np.zeros((50, 3)), d, 3e-3, offs)
    np.testing.assert_allclose(rays[:, 3:], ref, atol=1e-6)
    ang = np.arccos(np.clip(np.einsum("ij,ij->i", ref, np.repeat(d, 25, 0)), -1, 1))
    assert ang.max() == pytest.approx(1.5e-3, rel=1e-6)      # outer ring on the cone


@pytest.mark.parametrize("R", [50.0, 400.0])
def test_footprint_is_divergence_times_range_and_stretches_when_oblique(R):
    w = _world(_ground())
    gamma = 2e-3
    offs, _ = subray_pattern(7)
    for theta in (0.0, 50.0):
        o, d = _beam(1, theta, R)
        rays = pack_rays(o, d, gamma, offs)
        (rr, _), _, _ = w.cast_energy(rays, np.ones(len(offs)), 0.0)
        hits = o[0] + rays[:, 3:].astype(float) * rr[:, None]
        across = hits[:, 1].max() - hits[:, 1].min()
        along = hits[:, 0].max() - hits[:, 0].min()
        assert across == pytest.approx(gamma * R, rel=0.02)
        # an ellipse: stretched by 1 / cos(theta) along the plane of incidence
        assert along == pytest.approx(gamma * R / np.cos(np.radians(theta)), rel=0.02)


def _canopy(rng, n=400, size=0.25, z=10.0, half=15.0):
    objs = [_ground(rho=0.3)]
    for i, (x, y) in enumerate(rng.uniform(-half, half, (n, 2))):
        s = size / 2
        objs.append(_quad(f"leaf{i}", [[x - s, y - s, z], [x + s, y - s, z], [x + s, y + s, z],
                                       [x - s, y + s, z]], 100 + i, "leaf", 0.5))
    return objs


def test_multiple_return_share_rises_with_divergence():
    rng = np.random.default_rng(1)
    w = _world(*_canopy(rng))
    xy = rng.uniform(-12, 12, (3000, 2))
    o = np.column_stack([xy, np.full(len(xy), 100.0)])
    d = np.tile([0.0, 0.0, -1.0], (len(xy), 1))
    shares = []
    for div in (0.1, 1.0, 3.0, 6.0):
        e = fire(w, _scanner(divergence_mrad=div), o, d, rng=np.random.default_rng(0))
        first = e["return_number"] == 1
        shares.append(float(np.mean(e["number_of_returns"][first] > 1)))
    assert all(b > a for a, b in zip(shares, shares[1:], strict=False)), shares
    assert shares[0] < 0.02 and shares[-1] > 0.15, shares


@pytest.mark.parametrize("R", [40.0, 120.0, 300.0])
@pytest.mark.parametrize("theta", [0.0, 30.0, 60.0])
def test_intensity_follows_reflectance_cos_over_range_squared(R, theta):
    w = _world(_ground())
    e = fire(w, _scanner(), *_beam(1, theta, R), rng=np.random.default_rng(0))
    assert len(e["energy"]) == 1
    want = RHO * np.cos(np.radians(theta)) / R ** 2
    assert e["energy"][0] == pytest.approx(want, rel=0.03)


@pytest.mark.parametrize("R,theta", [(60.0, 0.0), (200.0, 0.0), (500.0, 0.0),
                                     (200.0, 45.0), (200.0, 70.0)])
def test_range_noise_follows_the_snr_law(R, theta):
    """sigma_R = sigma_pulse / sqrt(SNR), SNR = (rho cos theta / R^2) / E_noise: from the
    closed form of the echo's energy, not the simulator's own SNR."""
    w = _world(_ground())
    sc = _scanner()
    n = 3000
    e = fire(w, sc, *_beam(n, theta, R), rng=np.random.default_rng(7))
    assert len(e["range"]) == n
    snr = RHO * np.cos(np.radians(theta)) / R ** 2 / sc.receiver.noise_energy
    want = sc.receiver.sigma_m / np.sqrt(snr)
    # 3000 samples: the sample sigma is within ~3 % (two sigma) of the true one
    assert np.std(e["range"] - e["range_true"]) == pytest.approx(want, rel=0.10)
    assert np.std(e["range"]) == pytest.approx(want, rel=0.10)   # all pulses alike


@pytest.mark.parametrize("gap,returns", [(0.10, 2), (0.40, 1)])
def test_a_pulse_through_a_gap_between_two_leaves(gap, returns):
    """Footprint 2 mrad x 90 m = 18 cm at the leaves (10 m above the ground)."""
    z, L = 10.0, 1.0
    g = gap / 2
    left = _quad("left", [[-L, -L, z], [-g, -L, z], [-g, L, z], [-L, L, z]], 2, "leaf", 0.5)
    right = _quad("right", [[g, -L, z], [L, -L, z], [L, L, z], [g, L, z]], 3, "leaf", 0.5)
    w = _world(_ground(), left, right)
    e = fire(w, _scanner(divergence_mrad=2.0), np.array([[0.0, 0.0, 100.0]]),
             np.array([[0.0, 0.0, -1.0]]), rng=np.random.default_rng(0))
    assert len(e["range"]) == returns
    assert e["number_of_returns"].tolist() == [returns] * returns
    assert e["part"][-1] == PARTS.index("ground")
    if returns == 2:
        assert e["part"][0] == PARTS.index("leaf")
        assert e["range_true"][0] == pytest.approx(90.0, abs=0.05)
    assert e["range_true"][-1] == pytest.approx(100.0, abs=0.05)


def test_a_window_returns_its_own_echo_and_the_room_behind_it():
    """Glass (part 'glass', reflectance 0.05) 5 m in front of a wall: two echoes, the
    wall's energy reduced by the two passes through the pane, (1 - 0.05)^2."""
    pane = _quad("pane", [[-2, -2, 15.0], [2, -2, 15.0], [2, 2, 15.0], [-2, 2, 15.0]], 5,
                 "glass", 0.05)
    w = _world(_ground(), pane)
    e = fire(w, _scanner(), np.array([[0.0, 0.0, 100.0]]), np.array([[0.0, 0.0, -1.0]]),
             rng=np.random.default_rng(0))
    assert e["part"].tolist() == [PARTS.index("glass"), PARTS.index("ground")]
    assert e["range_true"] == pytest.approx([85.0, 100.0], abs=0.01)
    assert e["energy"][0] == pytest.approx(0.05 / 85.0 ** 2, rel=0.03)
    assert e["energy"][1] == pytest.approx(RHO * 0.95 ** 2 / 100.0 ** 2, rel=0.03)
    assert e["true_z"] == pytest.approx([15.0, 0.0], abs=0.01)
    # without the glass part the same pane is opaque: one echo
    opaque = _quad("pane", [[-2, -2, 15.0], [2, -2, 15.0], [2, 2, 15.0], [-2, 2, 15.0]], 5,
                   "building", 0.05)
    e = fire(_world(_ground(), opaque), _scanner(), np.array([[0.0, 0.0, 100.0]]),
             np.array([[0.0, 0.0, -1.0]]), rng=np.random.default_rng(0))
    assert e["part"].tolist() == [PARTS.index("building")]


@pytest.mark.parametrize("detection,kept", [("waveform", 102.0), ("discrete", 100.0)])
def test_two_echoes_within_the_minimum_separation(detection, kept):
    """A weak echo 2 m before a strong one, 3 m minimum separation: a waveform receiver
    keeps the stronger, a discrete one the earlier (its detector is then blind); 4 m apart
    both keep both."""
    from acquire.lidar.waveform import detect_echoes

    rx = dataclasses.replace(_scanner(min_separation_m=3.0).receiver, detection=detection)
    e = detect_echoes(np.array([[100.0, 102.0]]), np.array([[1e-5, 4e-5]]), rx)
    assert e["range"] == pytest.approx([kept], abs=0.01)
    assert e["number_of_returns"].tolist() == [1]
    e = detect_echoes(np.array([[100.0, 104.0]]), np.array([[1e-5, 4e-5]]), rx)
    assert e["range"] == pytest.approx([100.0, 104.0], abs=0.01)
    assert e["return_number"].tolist() == [1, 2]


def test_the_discrete_preset_and_override():
    s = Scanner.from_preset(get_preset("leica-als50-ii"))
    assert (s.receiver.detection, s.receiver.min_separation_m, s.receiver.max_returns) == (
        "discrete", 2.7, 4)
    s = _scanner(detection="discrete", max_returns=4)
    assert s.receiver.detection == "discrete"
    assert s.receiver.min_separation_m == pytest.approx(0.6, abs=0.01)   # 4 ns in range
    with pytest.raises(InputError):
        _scanner(detection="analogue")
