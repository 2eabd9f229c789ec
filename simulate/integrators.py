"""Time integrators over one interface: a state-derivative function ``f(t, y) -> dy/dt``.

Methods (``METHODS``):

``euler``
    Explicit (forward) Euler, first order. On ``x' = -k x`` stable for ``h k <= 2``; on
    an oscillator it multiplies the energy by ``1 + (w h)^2`` every step.
``symplectic_euler``
    Semi-implicit Euler for second-order systems: the state is ``y = [x, v]`` stacked
    on the first axis (``y.shape[0] == 2``); ``v += h a(x, v); x += h v``. Keeps an
    oscillator's energy bounded for ``w h < 2``.
``midpoint``
    Explicit midpoint (RK2), second order; stable on ``x' = -k x`` for ``h k <= 2``.
``heun``
    Trapezoid rule in its explicit form (Heun), second order.
``rk4``
    Classical Runge-Kutta, fourth order; stable for ``h k <= 2.7853`` (decay) and
    ``w h <= 2 sqrt 2`` (oscillation).
``adaptive``
    Dormand-Prince 5(4) with embedded error estimate and step-size control
    (:func:`integrate_adaptive`); as a single :func:`step` it takes the 5th-order step.

>>> import numpy as np
>>> y = integrate(lambda t, y: -y, 0.0, np.array([1.0]), 1.0, method="rk4", h=0.01)
>>> bool(abs(y[0] - np.exp(-1)) < 1e-9)
True

References
----------
E. Hairer, S. P. Norsett, G. Wanner, "Solving Ordinary Differential Equations I",
Springer 1993 (stability regions, Dormand-Prince). doi:10.1007/978-3-540-78862-1
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from core.validate import check_choice, check_int, check_positive

log = logging.getLogger(__name__)

__all__ = ["METHODS", "step", "integrate", "integrate_adaptive", "AdaptiveStats",
           "stability_limit", "check_step", "RK4_REAL_LIMIT"]

METHODS = ("euler", "symplectic_euler", "midpoint", "heun", "rk4", "adaptive")

Derivative = Callable[[float, np.ndarray], np.ndarray]

#: Where RK4's stability polynomial crosses |R(z)| = 1 on the negative real axis.
RK4_REAL_LIMIT = 2.785293563405282

# Dormand-Prince 5(4) tableau.
_DP_C = (0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0)
_DP_A = (
    (),
    (1 / 5,),
    (3 / 40, 9 / 40),
    (44 / 45, -56 / 15, 32 / 9),
    (19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729),
    (9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656),
    (35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84),
)
_DP_B5 = (35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0.0)
_DP_B4 = (5179 / 57600, 0.0, 7571 / 16695, 393 / 640, -92097 / 339200, 187 / 2100, 1 / 40)


def _dp_stages(f: Derivative, t: float, y: np.ndarray, h: float, k1: np.ndarray | None = None):
    ks = [f(t, y) if k1 is None else k1]
    for i in range(1, 7):
        yi = y.copy()
        for a, k in zip(_DP_A[i], ks[:i], strict=True):
            if a:
                yi += (h * a) * k
        ks.append(f(t + _DP_C[i] * h, yi))
    y5 = y.copy()
    y4 = y.copy()
    for b5, b4, k in zip(_DP_B5, _DP_B4, ks, strict=True):
        if b5:
            y5 += (h * b5) * k
        if b4:
            y4 += (h * b4) * k
    return y5, y4, ks[-1]  # FSAL: the last stage is f(t + h, y5)


def step(f: Derivative, t: float, y: np.ndarray, h: float, *, method: str = "rk4") -> np.ndarray:
    """Advance ``y`` from ``t`` to ``t + h`` with one step of ``method``.

    Parameters
    ----------
    f : callable ``f(t, y) -> dydt``
        Returns an array shaped like ``y``; must not modify ``y``.
    t : float
    y : ndarray
        State (any shape; ``(2, ...)`` = positions, velocities for ``symplectic_euler``).
    h : float
        Step size (may be negative for backward integration).
    method : str
        One of :data:`METHODS`.

    Returns
    -------
    ndarray
        The new state (a new array).
    """
    check_choice(method, "method", METHODS)
    y = np.asarray(y, dtype=np.float64)
    if method == "euler":
        return y + h * f(t, y)
    if method == "symplectic_euler":
        if y.ndim == 0 or y.shape[0] != 2:
            raise ValueError("y: symplectic_euler expects a state stacked as [positions, "
                             f"velocities] along axis 0, got shape {y.shape}")
        a = f(t, y)[1]
        v = y[1] + h * a
        return np.stack([y[0] + h * v, v])
    if method == "midpoint":
        k1 = f(t, y)
        return y + h * f(t + 0.5 * h, y + (0.5 * h) * k1)
    if method == "heun":
        k1 = f(t, y)
        k2 = f(t + h, y + h * k1)
        return y + (0.5 * h) * (k1 + k2)
    if method == "rk4":
        k1 = f(t, y)
        k2 = f(t + 0.5 * h, y + (0.5 * h) * k1)
        k3 = f(t + 0.5 * h, y + (0.5 * h) * k2)
        k4 = f(t + h, y + h * k3)
        return y + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return _dp_stages(f, t, y, h)[0]


def integrate(f: Derivative, t0: float, y0: np.ndarray, t1: float, *, method: str = "rk4",
              h: float | None = None, substeps: int | None = None, rtol: float = 1e-6,
              atol: float = 1e-9) -> np.ndarray:
    """Integrate from ``t0`` to ``t1`` with equal steps (or adaptively).

    Give either ``h`` (the step is shrunk so that a whole number of steps fits) or
    ``substeps`` (the interval is cut into that many steps). ``method="adaptive"``
    ignores both and controls the step by ``rtol``/``atol``.

    Returns
    -------
    ndarray
        The state at ``t1``.
    """
    check_choice(method, "method", METHODS)
    if method == "adaptive":
        return integrate_adaptive(f, t0, y0, t1, rtol=rtol, atol=atol)[0]
    span = float(t1) - float(t0)
    if substeps is None:
        if h is None:
            raise ValueError("h: expected a step size or substeps, got neither")
        check_positive(h, "h")
        n = max(1, math.ceil(abs(span) / h - 1e-9))
    else:
        n = check_int(substeps, "substeps")
    dt = span / n
    y = np.asarray(y0, dtype=np.float64)
    for i in range(n):
        y = step(f, t0 + i * dt, y, dt, method=method)
    return y


@dataclass
class AdaptiveStats:
    """Counters of an adaptive run: accepted and rejected steps, derivative calls."""

    accepted: int = 0
    rejected: int = 0
    evaluations: int = 0
    last_h: float = 0.0


def integrate_adaptive(f: Derivative, t0: float, y0: np.ndarray, t1: float, *,
                       rtol: float = 1e-6, atol: float = 1e-9, h0: float | None = None,
                       h_min: float = 1e-12, max_steps: int = 1_000_000
                       ) -> tuple[np.ndarray, AdaptiveStats]:
    """Dormand-Prince 5(4) with error control (local extrapolation, FSAL).

    The error of a step is the RMS over components of ``(y5 - y4) / (atol + rtol
    max(|y|, |y_new|))``; a step is accepted when it is <= 1 and the next step is
    ``h * clip(0.9 err^(-1/5), 0.2, 5)``.

    Returns
    -------
    y : ndarray
        The state at ``t1``.
    stats : AdaptiveStats
    """
    check_positive(rtol, "rtol", allow_zero=True)
    check_positive(atol, "atol", allow_zero=True)
    if rtol == 0 and atol == 0:
        raise ValueError("rtol, atol: expected at least one positive tolerance, got 0 and 0")
    y = np.asarray(y0, dtype=np.float64).copy()
    t = float(t0)
    t1 = float(t1)
    span = t1 - t
    stats = AdaptiveStats()
    if span == 0:
        return y, stats
    sign = 1.0 if span > 0 else -1.0
    h = abs(span) / 100 if h0 is None else abs(float(h0))
    k1 = f(t, y)
    stats.evaluations += 1
    while sign * (t1 - t) > 0:
        if stats.accepted + stats.rejected >= max_steps:
            raise RuntimeError(f"integrate_adaptive: gave up after {max_steps} steps at t={t}")
        h = min(h, abs(t1 - t))
        y5, y4, k_last = _dp_stages(f, t, y, sign * h, k1)
        stats.evaluations += 6
        scale = atol + rtol * np.maximum(np.abs(y), np.abs(y5))
        err = float(np.sqrt(np.mean(((y5 - y4) / scale) ** 2))) if y.size else 0.0
        if not np.isfinite(err):
            err = np.inf
        if err <= 1.0:
            t = t1 if abs(t1 - t) <= h * (1 + 1e-12) else t + sign * h
            y = y5
            k1 = k_last
            stats.accepted += 1
            stats.last_h = h
        else:
            stats.rejected += 1
        factor = 5.0 if err == 0 else min(5.0, max(0.2, 0.9 * err ** -0.2))
        h *= factor
        if h < h_min and sign * (t1 - t) > 0:
            raise RuntimeError(f"integrate_adaptive: step size fell below {h_min} at t={t}")
    return y, stats


def stability_limit(method: str, *, rate: float = 0.0, omega: float = 0.0) -> float:
    """Largest stable step for a linear decay rate and/or oscillation frequency.

    Parameters
    ----------
    method : str
        One of :data:`METHODS`.
    rate : float
        Decay rate ``k`` of ``x' = -k x`` (e.g. drag / mass), 1/s.
    omega : float
        Angular frequency ``w`` of an undamped oscillator (e.g. sqrt(k / m)), rad/s.

    Returns
    -------
    float
        The step limit (``inf`` when nothing constrains it; ``0.0`` when the method
        is unstable at every step for an undamped oscillator: explicit Euler, midpoint
        and Heun amplify it by ``1 + (w h)^2`` resp. ``1 + (w h)^4 / 4`` per step).
    """
    check_choice(method, "method", METHODS)
    rate = check_positive(rate, "rate", allow_zero=True)
    omega = check_positive(omega, "omega", allow_zero=True)
    if method == "adaptive":
        return math.inf
    real = {"euler": 2.0, "symplectic_euler": 2.0, "midpoint": 2.0, "heun": 2.0,
            "rk4": RK4_REAL_LIMIT}[method]
    imag = {"euler": 0.0, "symplectic_euler": 2.0, "midpoint": 0.0, "heun": 0.0,
            "rk4": 2.0 * math.sqrt(2.0)}[method]
    limit = math.inf
    if rate > 0:
        limit = min(limit, real / rate)
    if omega > 0:
        limit = min(limit, imag / omega)
    return limit


def check_step(method: str, h: float, *, rate: float = 0.0, omega: float = 0.0,
               what: str = "h") -> bool:
    """Log a warning naming the limit when ``h`` exceeds :func:`stability_limit`.

    Returns True when the step is within the limit.
    """
    limit = stability_limit(method, rate=rate, omega=omega)
    if abs(h) <= limit:
        return True
    if limit == 0.0:
        log.warning("%s = %g: %s is unstable at any step for an undamped oscillation "
                    "(omega = %g rad/s); use symplectic_euler, rk4 or adaptive",
                    what, h, method, omega)
    else:
        log.warning("%s = %g exceeds the stability limit %.6g s of %s (decay rate %g 1/s, "
                    "omega %g rad/s); use more substeps", what, h, limit, method, rate, omega)
    return False
