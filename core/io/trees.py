"""Tree tables as CSV: forest inventories in, detected and true trees out.

One row per tree, a header naming the columns. Numeric columns (``x``, ``y``, ``height``,
``dbh``, ``crown_radius``, ``crown_area``, ...) are metres (m² for areas); ``species`` is
text. Coordinates are kept exactly as written (projected coordinates of millions of
metres stay float64 and are written with millimetre digits).

:func:`read_tree_table` checks what every tree table must hold: the required columns,
numbers where numbers belong, finite coordinates, heights that are positive numbers, and
no tree listed twice (identical ``x``, ``y`` and ``height``; stems a few decimetres apart are
normal: coppice and multi-stem trees). Each failure is an
:class:`core.validate.InputError` naming the file, the column and the row.

>>> import tempfile, pathlib
>>> p = pathlib.Path(tempfile.mkdtemp()) / "t.csv"
>>> _ = write_tree_table(p, {"x": [512000.25], "y": [5403000.5], "height": [21.0]})
>>> t = read_tree_table(p)
>>> float(t["x"][0]), float(t["height"][0])
(512000.25, 21.0)
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from core.files import atomic_file, read_text
from core.validate import InputError

__all__ = ["read_tree_table", "write_tree_table", "TEXT_COLUMNS"]

#: Columns read as text (every other column is a number).
TEXT_COLUMNS = ("species", "name")


def _number(text: str, *, path, column: str, row: int) -> float:
    t = text.strip()
    if t == "" or t.lower() in ("na", "nan", "null"):
        return math.nan
    try:
        return float(t)
    except ValueError:
        raise InputError(f"row {row}: expected a number, got {text!r}", path=path,
                         field=column) from None


def read_tree_table(path: str | os.PathLike, *,
                    required: Sequence[str] = ("x", "y", "height"),
                    optional: Sequence[str] = (), allow_empty: bool = False
                    ) -> dict[str, np.ndarray]:
    """Read a tree table: ``dict column -> (n,) array`` (float64, text columns as str).

    Parameters
    ----------
    path : path to a ``.csv`` file (comma, semicolon or tab separated)
    required : sequence of str
        Columns that must be present (matched without regard to case and spaces).
    optional : sequence of str
        Columns read when present; every other column is read too.
    allow_empty : bool
        A header without rows is a table of no trees (a detection that found none), not
        an error.

    Raises
    ------
    InputError
        Missing column, a number that is not one, NaN or non-finite ``x``/``y``, a
        ``height`` that is missing, NaN or not positive, a ``dbh``/``crown_radius`` below 0,
        or the same tree twice.
    """
    path = Path(path)
    text = read_text(path)
    try:
        dialect = csv.Sniffer().sniff(text.split("\n", 1)[0], delimiters=",;\t")
    except csv.Error:
        dialect = csv.excel
    rows = list(csv.reader(io.StringIO(text), dialect))
    rows = [r for r in rows if any(c.strip() for c in r)]
    if not rows:
        raise InputError("empty file: expected a header row", path=path, field="header")
    header = [h.strip().lower().replace(" ", "_") for h in rows[0]]
    for col in required:
        if col not in header:
            raise InputError(f"missing column; the file has {', '.join(header)}", path=path,
                             field=col)
    if len(rows) == 1 and not allow_empty:
        raise InputError("no trees: the file has only its header", path=path, field="rows")
    out: dict[str, list] = {h: [] for h in header}
    for k, r in enumerate(rows[1:], start=2):
        if len(r) != len(header):
            raise InputError(f"row {k}: expected {len(header)} values, got {len(r)}", path=path,
                             field="rows")
        for h, v in zip(header, r, strict=True):
            out[h].append(v.strip() if h in TEXT_COLUMNS else
                          _number(v, path=path, column=h, row=k))
    table = {h: (np.array(v, dtype=str) if h in TEXT_COLUMNS else np.array(v, np.float64))
             for h, v in out.items()}
    _check_table(table, path)
    return table


def _check_table(t: dict, path: Path) -> None:
    for col in ("x", "y"):
        if col in t:
            bad = np.flatnonzero(~np.isfinite(t[col]))
            if len(bad):
                raise InputError(f"row {bad[0] + 2}: expected a finite number, got "
                                 f"{t[col][bad[0]]}", path=path, field=col)
    if "height" in t:
        h = t["height"]
        bad = np.flatnonzero(~(h > 0))
        if len(bad):
            raise InputError(f"row {bad[0] + 2}: expected a positive height (metres), got "
                             f"{h[bad[0]]}", path=path, field="height")
    for col in ("dbh", "crown_radius", "crown_area"):
        if col in t:
            bad = np.flatnonzero(t[col] < 0)
            if len(bad):
                raise InputError(f"row {bad[0] + 2}: expected a number >= 0, got "
                                 f"{t[col][bad[0]]}", path=path, field=col)
    if all(c in t for c in ("x", "y", "height")):
        key = np.stack([t["x"], t["y"], t["height"]], 1)
        _, first, counts = np.unique(key, axis=0, return_index=True, return_counts=True)
        if np.any(counts > 1):
            dup = key[first[counts > 1][0]]
            rows = np.flatnonzero(np.all(key == dup, axis=1)) + 2
            raise InputError(f"rows {rows[0]} and {rows[1]}: the same tree twice (x {dup[0]}, "
                             f"y {dup[1]}, height {dup[2]})", path=path, field="x, y, height")


def write_tree_table(path: str | os.PathLike, columns: Mapping[str, Sequence]) -> Path:
    """Write a tree table atomically; numbers with millimetre digits (``%.3f``).

    Parameters
    ----------
    path : path
    columns : mapping name -> (n,) array
        Columns of equal length, written in the mapping's order.
    """
    names = list(columns)
    cols = [np.asarray(columns[n]) for n in names]
    n = {len(c) for c in cols}
    if len(n) > 1:
        lengths = dict(zip(names, map(len, cols), strict=True))
        raise ValueError(f"columns: expected equal lengths, got {lengths}")
    with atomic_file(path) as tmp, open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(names)
        for row in zip(*cols, strict=True):
            w.writerow([v if isinstance(v, str) else
                        (str(int(v)) if np.issubdtype(type(v), np.integer) else f"{float(v):.3f}")
                        for v in row])
    return Path(path)
