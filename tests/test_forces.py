import math

import numba as nb
import numpy as np
import pytest

from procgen.noise import noise3_grad
from procgen.noise.perlin import noise3, perm_table
from simulate.forces import (
    Attractor,
    Damping,
    ForceSet,
    Gravity,
    Pairwise,
    Springs,
    Turbulence,
    Vortex,
    Wind,
    curl_potentials,
    pairwise_accel,
    pairwise_accel_reference,
)
from simulate.integrators import integrate
from simulate.particles import advance_local


@nb.njit(cache=True)
def _grad_many(p, pts):
    out = np.empty((len(pts), 5))
    for i in range(len(pts)):
        n, gx, gy, gz = noise3_grad(p, pts[i, 0], pts[i, 1], pts[i, 2])
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = n, gx, gy, gz
        out[i, 4] = noise3(p, pts[i, 0], pts[i, 1], pts[i, 2])
    return out


def test_noise_gradient_matches_value_and_finite_differences(rng):
    p = perm_table(7)
    pts = rng.uniform(-4, 4, (400, 3))
    o = _grad_many(p, pts)
    np.testing.assert_allclose(o[:, 0], o[:, 4], atol=1e-14)
    e = 1e-6
    for k in range(3):
        d = np.zeros(3)
        d[k] = e
        fd = (_grad_many(p, pts + d)[:, 4] - _grad_many(p, pts - d)[:, 4]) / (2 * e)
        np.testing.assert_allclose(o[:, 1 + k], fd, atol=1e-7)


@nb.njit(cache=True)
def _potentials_many(p, pts):
    out = np.empty((len(pts), 8))
    for i in range(len(pts)):
        r = curl_potentials(p, pts[i, 0], pts[i, 1], pts[i, 2])
        for k in range(8):
            out[i, k] = r[k]
    return out


def test_curl_potentials_one_walk_gives_perlin_and_a_second_noise(rng):
    p = perm_table(3)
    pts = rng.uniform(-5, 5, (400, 3))
    o = _potentials_many(p, pts)
    # the first potential is Perlin's noise and gradient exactly
    ref = _grad_many(p, pts)
    np.testing.assert_allclose(o[:, :4], ref[:, :4], atol=1e-14)
    # the second is a different noise whose gradient matches its finite differences
    assert np.corrcoef(o[:, 0], o[:, 4])[0, 1] < 0.3
    assert np.std(o[:, 4]) > 0.5 * np.std(o[:, 0])
    e = 1e-6
    for k in range(3):
        d = np.zeros(3)
        d[k] = e
        fd = (_potentials_many(p, pts + d)[:, 4] - _potentials_many(p, pts - d)[:, 4]) / (2 * e)
        np.testing.assert_allclose(o[:, 5 + k], fd, atol=1e-7)


def _divergence(fs, x, e=1e-5):
    v = np.zeros_like(x)
    div = 0.0
    for k in range(3):
        d = np.zeros(3)
        d[k] = e
        div = div + (fs.accel(0, x + d, v, 1.0)[:, k] - fs.accel(0, x - d, v, 1.0)[:, k]) / (2 * e)
    return div


def test_curl_noise_is_divergence_free_and_perlin_is_not(rng):
    x = rng.uniform(-2, 2, (300, 3))
    curl = ForceSet([Turbulence(amplitude=2.0, scale=0.7, kind="curl", seed=1)])
    perl = ForceSet([Turbulence(amplitude=2.0, scale=0.7, kind="perlin", seed=1)])
    mag = np.abs(curl.accel(0, x, np.zeros_like(x), 1.0)).mean()
    assert mag > 0.1
    assert np.abs(_divergence(curl, x)).max() < 1e-5 * mag / 0.7
    assert np.abs(_divergence(perl, x)).max() > 0.1


def test_pairwise_grid_equals_reference(rng):
    pw = Pairwise(attraction=0.5, repulsion=2.0, radius=0.3)
    x = rng.uniform(0, 2, (1500, 3))
    m = rng.uniform(0.5, 2, 1500)
    np.testing.assert_allclose(pairwise_accel(x, m, pw), pairwise_accel_reference(x, m, pw),
                               atol=1e-12)
    # momentum: with equal masses the pair forces cancel
    a = pairwise_accel(x, 1.0, pw)
    assert np.abs(a.sum(axis=0)).max() < 1e-9


def test_wind_drag_relaxes_to_wind_velocity():
    fs = ForceSet([Wind(velocity=(3.0, 0, 0), drag=0.5)])
    x, v = np.zeros((1, 3)), np.zeros((1, 3))
    advance_local(fs, 0, x, v, 2.0, 0.01, substeps=100)  # rate = drag / m = 0.25
    assert v[0, 0] == pytest.approx(3.0 * (1 - math.exp(-0.25)), rel=1e-9)


def test_fused_kernel_matches_generic_integrator(rng):
    fs = ForceSet([Gravity(), Wind((1, 0.5, 0), 0.3), Damping(0.1),
                   Turbulence(1.5, 0.6, kind="curl", speed=0.2), Turbulence(1.0, 0.9, "perlin"),
                   Attractor((0, 0, 1), 0.5), Vortex((0, 0, 0), (0, 0, 1), 2.0, 0.3)])
    x0 = rng.uniform(-1, 1, (50, 3))
    v0 = rng.normal(size=(50, 3))
    m = rng.uniform(0.5, 2.0, 50)
    for method in ("euler", "symplectic_euler", "midpoint", "heun", "rk4"):
        x, v = x0.copy(), v0.copy()
        advance_local(fs, 0.3, x, v, m, 0.01, method=method, substeps=5)
        y = integrate(lambda t, y: np.stack([y[1], fs.accel(t, y[0], y[1], m)]), 0.3,
                      np.stack([x0, v0]), 0.35, method=method, substeps=5)
        np.testing.assert_allclose(x, y[0], atol=1e-12)
        np.testing.assert_allclose(v, y[1], atol=1e-12)


def test_single_spring_oscillates_at_sqrt_k_over_m():
    k, m = 40.0, 0.5
    # particle 0 is a very heavy anchor: the reduced mass is m
    springs = Springs(pairs=[[0, 1]], stiffness=k, rest=1.0)
    fs = ForceSet([springs])
    mass = np.array([1e12, m])
    y = np.stack([np.array([[0, 0, 0], [0, 0, 1.2]], float), np.zeros((2, 3))])
    f = lambda t, y: np.stack([y[1], fs.accel(t, y[0], y[1], mass)])  # noqa: E731
    h, zs = 1e-3, []
    for _ in range(3000):
        y = integrate(f, 0, y, h, method="rk4", substeps=1)
        zs.append(y[0, 1, 2] - 1.0)
    zs = np.array(zs)
    crossings = np.nonzero((zs[:-1] > 0) & (zs[1:] <= 0))[0]
    # sub-step interpolation of the downward zero crossings
    tc = (crossings + zs[crossings] / (zs[crossings] - zs[crossings + 1]) + 1) * h
    period = np.diff(tc).mean()
    assert 2 * math.pi / period == pytest.approx(math.sqrt(k / m), rel=1e-5)
    rate, omega = fs.stiffness(mass)
    assert omega >= math.sqrt(k / m)  # a conservative bound for the step-size check


def test_bad_force_parameters():
    with pytest.raises(ValueError, match="kind"):
        ForceSet([Turbulence(kind="simplex")])
    with pytest.raises(ValueError, match="axis"):
        ForceSet([Vortex(axis=(0, 0, 0))])
    with pytest.raises(ValueError, match="radius"):
        Pairwise(radius=0)


def test_attractor_vortex_damping_closed_forms():
    x = np.array([[2.0, 0, 0], [0, 3.0, 1.0]])
    v = np.array([[0.0, 1.0, 0], [1.0, 0, 0]])
    att = ForceSet([Attractor((0, 0, 0), strength=2.0, softening=1e-9)]).accel(0, x, v, 1.0)
    r = np.linalg.norm(x, axis=1)
    np.testing.assert_allclose(att, -2.0 * x / r[:, None] ** 3, rtol=1e-12)  # inverse square
    vor = ForceSet([Vortex((0, 0, 5.0), (0, 0, 2.0), strength=3.0, radius=0.5)]).accel(0, x, v,
                                                                                      1.0)
    # counter-clockwise about +z: at (2, 0) along +y, at (0, 3) along -x; 3 / (r^2 + 0.25)
    np.testing.assert_allclose(vor[0], [0, 3.0 * 2 / (4 + 0.25), 0], atol=1e-12)
    np.testing.assert_allclose(vor[1], [-3.0 * 3 / (9 + 0.25), 0, 0], atol=1e-12)
    damp = ForceSet([Damping(0.7)]).accel(0, x, v, 2.0)
    np.testing.assert_allclose(damp, -0.7 * v, atol=0)
