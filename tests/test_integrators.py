import logging
import math

import numpy as np
import pytest

from simulate.integrators import (
    RK4_REAL_LIMIT,
    check_step,
    integrate,
    integrate_adaptive,
    stability_limit,
    step,
)


def decay(k):
    return lambda t, y: -k * y


def oscillator(w):
    # y = [x, v]; x'' = -w^2 x
    return lambda t, y: np.stack([y[1], -w * w * y[0]])


@pytest.mark.parametrize("method", ["euler", "midpoint"])
def test_decay_stable_exactly_up_to_hk_2(method):
    k = 3.0
    amp = {}
    for hk in (2 * (1 - 1e-3), 2.0, 2 * (1 + 1e-3)):
        y = np.array([1.0])
        for _ in range(2000):
            y = step(decay(k), 0.0, y, hk / k, method=method)
        amp[hk] = abs(y[0])
    assert amp[2 * (1 - 1e-3)] < 1.0  # just inside: decays
    assert amp[2.0] == pytest.approx(1.0, rel=1e-9)  # on the boundary |R| = 1
    assert amp[2 * (1 + 1e-3)] > 1.0  # just outside: grows
    assert stability_limit(method, rate=k) == pytest.approx(2 / k)


def test_rk4_real_limit_is_where_the_polynomial_reaches_one():
    z = -RK4_REAL_LIMIT
    assert abs(1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24) == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("method,order", [("euler", 1), ("midpoint", 2), ("heun", 2),
                                          ("rk4", 4)])
def test_convergence_order(method, order):
    f = oscillator(2.0)
    y0 = np.array([1.0, 0.0])
    exact = np.array([math.cos(2.0), -2 * math.sin(2.0)])
    errs = [np.abs(integrate(f, 0, y0, 1.0, method=method, h=h) - exact).max()
            for h in (1 / 64, 1 / 128)]
    ratio = errs[0] / errs[1]
    # RK4: 16x +- 10 % (the target); the others at their own order with the same band.
    assert 0.9 * 2**order <= ratio <= 1.1 * 2**order


def test_symplectic_euler_bounded_and_euler_grows_exactly():
    w, h = 2 * math.pi, 0.01  # 100 steps per period
    f = oscillator(w)

    def energy(y):
        return 0.5 * y[1] ** 2 + 0.5 * w * w * y[0] ** 2

    y = np.array([1.0, 0.0])
    e0 = energy(y)
    for _ in range(20):
        y1 = step(f, 0, y, h, method="euler")
        assert energy(y1) / energy(y) == pytest.approx(1 + (w * h) ** 2, rel=1e-12)
        y = y1
    # Symplectic Euler over 10^4 periods (10^6 steps), vectorized over 1 state:
    # the modified energy is conserved, so the true energy stays within the
    # O(w h) band [1 - w h, 1 + w h] at every sampled step.
    x, v = 1.0, 0.0
    emin = emax = e0
    xs = np.empty(10_000)
    for period in range(10_000):
        for _ in range(100):
            v -= h * w * w * x
            x += h * v
        xs[period] = x
        e = 0.5 * v * v + 0.5 * w * w * x * x
        emin, emax = min(emin, e), max(emax, e)
    assert 1 - w * h <= emin / e0 and emax / e0 <= 1 + w * h
    # and the library step gives the same update
    y = step(f, 0, np.array([1.0, 0.0]), h, method="symplectic_euler")
    v1 = -h * w * w
    np.testing.assert_allclose(y, [1 + h * v1, v1], rtol=1e-15)


def test_symplectic_needs_stacked_state():
    with pytest.raises(ValueError, match="positions"):
        step(decay(1.0), 0, np.ones(3), 0.1, method="symplectic_euler")


def test_adaptive_meets_tolerance_with_fewer_evaluations():
    f = oscillator(3.0)
    y0 = np.array([1.0, 0.0])
    exact = np.array([math.cos(30.0), -3 * math.sin(30.0)])
    y, stats = integrate_adaptive(f, 0, y0, 10.0, rtol=1e-9, atol=1e-12)
    assert np.abs(y - exact).max() < 1e-6
    assert stats.accepted > 10 and stats.evaluations < 6 * 10_000
    # tighter tolerance, smaller error
    y2, _ = integrate_adaptive(f, 0, y0, 10.0, rtol=1e-11, atol=1e-14)
    assert np.abs(y2 - exact).max() < np.abs(y - exact).max()
    # the method name routes through integrate too
    np.testing.assert_allclose(integrate(f, 0, y0, 10.0, method="adaptive", rtol=1e-9,
                                         atol=1e-12), y)


def test_unknown_method_lists_choices():
    with pytest.raises(ValueError, match="'rk4'"):
        step(decay(1.0), 0, np.ones(1), 0.1, method="rk5")


def test_stability_warning_names_the_limit(caplog):
    with caplog.at_level(logging.WARNING, logger="simulate.integrators"):
        assert check_step("rk4", 0.1, rate=1.0)
        assert not check_step("euler", 0.5, rate=10.0)
    assert "stability limit 0.2" in caplog.text
    assert stability_limit("symplectic_euler", omega=4.0) == pytest.approx(0.5)
    assert stability_limit("rk4", omega=1.0) == pytest.approx(2 * math.sqrt(2))
    assert stability_limit("euler", omega=1.0) == 0.0
