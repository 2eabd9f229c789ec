"""Input validation shared by every package (procgen is the bottom layer).

One helper per kind of check, so that every public entry point raises the same
kind of message: the argument's name, what was expected, and what came.

>>> import numpy as np
>>> check_array(np.zeros((4, 3)), "points", shape=(None, 3)).shape
(4, 3)
>>> check_choice("rk4", "method", {"euler", "rk4"})
'rk4'
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

__all__ = [
    "InputError",
    "check_array",
    "check_choice",
    "check_int",
    "check_rng",
    "check_range",
    "check_positive",
    "check_finite",
    "check_unit_vector",
]


class InputError(ValueError):
    """Bad user input that can be pinned to a file and a field.

    The CLI prints ``error: <file>: <field>: <message>`` and exits with status 2.
    """

    def __init__(self, message: str, *, path: Any = None, field: str | None = None):
        self.path = None if path is None else str(path)
        self.field = field
        self.message = message
        parts = [p for p in (self.path, field) if p]
        super().__init__(": ".join([*parts, message]))


def _shape_str(shape: Sequence[int | None]) -> str:
    names = iter("nmkjl")
    return "(" + ", ".join(next(names) if s is None else str(s) for s in shape) + (
        ",)" if len(shape) == 1 else ")"
    )


def check_array(
    value: Any,
    name: str,
    *,
    shape: Sequence[int | None] | None = None,
    dtype: Any = np.float64,
    finite: bool = True,
    min_rows: int = 0,
) -> np.ndarray:
    """Return ``value`` as an array of ``dtype`` after checking its shape.

    Parameters
    ----------
    value : array_like
    name : str
        The argument's name, used in the error message.
    shape : sequence of int or None, optional
        Expected shape; ``None`` matches any length along that axis.
    dtype : numpy dtype, optional
        Converted to this dtype (``None`` keeps the input's).
    finite : bool
        Reject NaN and infinity (floating arrays only).
    min_rows : int
        Minimum length along the first axis.

    Raises
    ------
    ValueError
        ``points: expected shape (n, 3), got (5, 2)`` and the like.
    """
    try:
        arr = np.asarray(value, dtype=dtype)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: expected a numeric array, got {type(value).__name__}") from exc
    if shape is not None:
        ok = arr.ndim == len(shape) and all(
            s is None or s == a for s, a in zip(shape, arr.shape, strict=True)
        )
        if not ok:
            raise ValueError(f"{name}: expected shape {_shape_str(shape)}, got {arr.shape}")
    if min_rows and (arr.ndim == 0 or arr.shape[0] < min_rows):
        got = 0 if arr.ndim == 0 else arr.shape[0]
        raise ValueError(f"{name}: expected at least {min_rows} rows, got {got}")
    if finite and arr.dtype.kind in "fc" and not np.all(np.isfinite(arr)):
        bad = int(np.size(arr) - np.count_nonzero(np.isfinite(arr)))
        raise ValueError(f"{name}: expected finite values, got {bad} NaN or infinite")
    return arr


def check_choice(value: Any, name: str, allowed: Iterable[Any]) -> Any:
    """Return ``value`` if it is one of ``allowed``; else a ValueError listing them all."""
    allowed = list(allowed)
    if value not in allowed:
        listed = ", ".join(repr(a) for a in sorted(allowed, key=str))
        raise ValueError(f"{name}: expected one of {listed}, got {value!r}")
    return value


def check_finite(value: Any, name: str) -> float:
    """Return ``value`` as a finite float."""
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: expected a number, got {value!r}") from exc
    if not math.isfinite(v):
        raise ValueError(f"{name}: expected a finite number, got {value!r}")
    return v


def check_range(
    value: Any,
    name: str,
    lo: float | None = None,
    hi: float | None = None,
    *,
    lo_open: bool = False,
    hi_open: bool = False,
) -> float:
    """Return ``value`` as a float inside the interval, else a ValueError naming it.

    >>> check_range(0.5, "hurst", 0, 1, lo_open=True, hi_open=True)
    0.5
    """
    v = check_finite(value, name)
    low_bad = lo is not None and (v <= lo if lo_open else v < lo)
    high_bad = hi is not None and (v >= hi if hi_open else v > hi)
    if low_bad or high_bad:
        left = "(" if lo_open else "["
        right = ")" if hi_open else "]"
        lo_s = "-inf" if lo is None else f"{lo:g}"
        hi_s = "inf" if hi is None else f"{hi:g}"
        raise ValueError(f"{name}: expected a value in {left}{lo_s}, {hi_s}{right}, got {value!r}")
    return v


def check_int(value: Any, name: str, lo: int = 1, hi: int | None = None) -> int:
    """Return ``value`` as an int: an integral number (not a bool) in ``[lo, hi]``.

    ``3`` and ``3.0`` pass; ``2.5``, ``True``, ``"3"``, NaN and anything outside the
    range raise ValueError naming ``name``.

    >>> check_int(3.0, "octaves", 1, 64)
    3
    """
    try:
        ok = (isinstance(value, (int, float, np.integer, np.floating))
              and not isinstance(value, (bool, np.bool_))
              and float(value) == int(value) and int(value) >= lo
              and (hi is None or int(value) <= hi))
    except (ValueError, OverflowError):  # NaN, infinity
        ok = False
    if not ok:
        if hi is not None:
            what = f"an integer in [{lo}, {hi}]"
        else:
            what = "a positive integer" if lo == 1 else f"an integer >= {lo}"
        raise ValueError(f"{name}: expected {what}, got {value!r}")
    return int(value)


def check_rng(rng: Any, name: str = "rng") -> np.random.Generator:
    """Return ``rng`` if it is a ``numpy.random.Generator`` (no global RNG, no seeds here)."""
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"{name}: expected a numpy.random.Generator, got {type(rng).__name__}")
    return rng


def check_positive(value: Any, name: str, *, allow_zero: bool = False) -> float:
    """Return ``value`` as a float > 0 (or >= 0 with ``allow_zero``)."""
    return check_range(value, name, 0.0, None, lo_open=not allow_zero)


def check_unit_vector(value: Any, name: str) -> np.ndarray:
    """A finite, non-zero 3-vector scaled to unit length, else ValueError naming ``name``."""
    v = check_array(value, name, shape=(3,))
    n = float(np.linalg.norm(v))
    if not np.isfinite(n) or n == 0:
        raise ValueError(f"{name}: expected a non-zero vector, got {np.asarray(v).tolist()}")
    return v / n
