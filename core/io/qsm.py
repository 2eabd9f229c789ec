"""Quantitative structure models (QSM): a tree's woody skeleton as cylinders, and its CSV.

A QSM lists cylinders the way TreeQSM (Raumonen et al. 2013) does: each has an ``id``, the
``parent`` it grows from (0 for the root), its ``extension`` (the next cylinder of the same
branch, 0 at a branch's tip), the ``branch`` it belongs to, the ``branch_order`` (0 the
stem), its ``start`` point, unit ``axis``, ``length`` and ``radius`` (metres). The CSV has
one row a cylinder under the header :data:`QSM_COLUMNS` (ids from 1, as TreeQSM's tables).

:func:`read_qsm_csv` also reads the cylinder tables that TreeQSM exports with
``ID, parentID, startX ... endZ, radius, length, ..., branchOrder, branchID`` columns
(ids from 0, the root's parent -1). Either way the parents must form one tree: a single
root, every parent an existing cylinder, no cycle (:func:`check_qsm`).

>>> import numpy as np, tempfile, pathlib
>>> q = QSM(id=np.array([1, 2, 3]), parent=np.array([0, 1, 1]), extension=np.array([2, 0, 0]),
...         branch=np.array([1, 1, 2]), branch_order=np.array([0, 0, 1]),
...         start=np.array([[0, 0, 0], [0, 0, 1], [0, 0, 1.0]]),
...         axis=np.array([[0, 0, 1], [0, 0, 1], [1, 0, 0.0]]),
...         length=np.array([1.0, 1.0, 0.5]), radius=np.array([0.1, 0.08, 0.05]))
>>> p = pathlib.Path(tempfile.mkdtemp()) / "tree.qsm.csv"
>>> read_qsm_csv(write_qsm_csv(p, q)).parent.tolist()
[0, 1, 1]
"""

from __future__ import annotations

import csv
import io
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from core.files import atomic_file
from core.validate import InputError

__all__ = ["QSM_COLUMNS", "QSM", "check_qsm", "read_qsm_csv", "write_qsm_csv"]

QSM_COLUMNS = ("id", "parent", "extension", "branch", "branch_order", "start_x", "start_y",
               "start_z", "axis_x", "axis_y", "axis_z", "length", "radius")
_TREEQSM_EXPORT = ("ID", "parentID", "startX", "startY", "startZ", "endX", "endY", "endZ",
                   "radius", "length")


@dataclass
class QSM:
    """Cylinders of a tree (see the module docstring); arrays of length n, ``start`` and
    ``axis`` (n, 3)."""

    id: np.ndarray
    parent: np.ndarray
    extension: np.ndarray
    branch: np.ndarray
    branch_order: np.ndarray
    start: np.ndarray
    axis: np.ndarray
    length: np.ndarray
    radius: np.ndarray

    def __len__(self) -> int:
        return len(self.id)

    @property
    def end(self) -> np.ndarray:
        """(n, 3) the cylinders' end points."""
        return self.start + self.axis * self.length[:, None]

    def parent_index(self) -> np.ndarray:
        """(n,) the row of each cylinder's parent (-1 for the root)."""
        order = np.argsort(self.id)
        pos = np.searchsorted(self.id[order], self.parent)
        pos = np.clip(pos, 0, len(self.id) - 1)
        found = self.id[order][pos] == self.parent
        return np.where(found, order[pos], -1)


def check_qsm(qsm: QSM, *, path: str | os.PathLike | None = None) -> QSM:
    """Check that the cylinders' parents form one tree; InputError naming ``parent`` if not."""
    n = len(qsm)
    if n == 0:
        raise InputError("no cylinders", path=path, field="id")
    if len(np.unique(qsm.id)) != n or np.any(qsm.id <= 0):
        raise InputError("ids must be distinct positive integers", path=path, field="id")
    pidx = qsm.parent_index()
    roots = np.flatnonzero(qsm.parent == 0)
    if len(roots) != 1:
        raise InputError(f"expected one root cylinder (parent 0), found {len(roots)}",
                         path=path, field="parent")
    dangling = np.flatnonzero((pidx < 0) & (qsm.parent != 0))
    if len(dangling):
        i = dangling[0]
        raise InputError(f"cylinder {qsm.id[i]} names parent {qsm.parent[i]}, which is no "
                         "cylinder", path=path, field="parent")
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import breadth_first_order

    has = pidx >= 0
    graph = coo_matrix((np.ones(int(has.sum())), (pidx[has], np.flatnonzero(has))),
                       shape=(n, n)).tocsr()
    reach = np.zeros(n, bool)
    reach[breadth_first_order(graph, int(roots[0]), directed=True,
                              return_predecessors=False)] = True
    if not reach.all():
        i = np.flatnonzero(~reach)[0]
        raise InputError(f"cylinder {qsm.id[i]} does not lead to the root (its parents form "
                         "a cycle)", path=path, field="parent")
    return qsm


def write_qsm_csv(path: str | os.PathLike, qsm: QSM) -> Path:
    """Write ``qsm`` as CSV with the header :data:`QSM_COLUMNS` (atomically)."""
    check_qsm(qsm)
    buf = io.StringIO()
    buf.write(",".join(QSM_COLUMNS) + "\n")
    ints = np.stack([qsm.id, qsm.parent, qsm.extension, qsm.branch, qsm.branch_order], 1)
    floats = np.column_stack([qsm.start, qsm.axis, qsm.length, qsm.radius])
    for i_row, f_row in zip(ints.tolist(), floats.tolist(), strict=False):
        buf.write(",".join(str(int(v)) for v in i_row) + ","
                  + ",".join(repr(float(v)) for v in f_row) + "\n")
    with atomic_file(path) as tmp:
        tmp.write_text(buf.getvalue())
    return Path(path)


def _column(rows, header, name, path, kind):
    j = header.index(name)
    try:
        return np.array([kind(r[j]) for r in rows])
    except (ValueError, IndexError) as exc:
        raise InputError(f"expected numbers ({exc})", path=path, field=name) from None


def read_qsm_csv(path: str | os.PathLike) -> QSM:
    """Read a QSM CSV (this module's columns or a TreeQSM cylinder export) and check it."""
    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", path=path)
    with open(path, newline="") as fh:
        rows = [r for r in csv.reader(fh) if r]
    if not rows:
        raise InputError("empty file", path=path)
    header = [h.strip() for h in rows[0]]
    body = rows[1:]
    if all(c in header for c in QSM_COLUMNS):
        def col(name, kind=float):
            return _column(body, header, name, path, kind)
        qsm = QSM(col("id", int), col("parent", int), col("extension", int), col("branch", int),
                  col("branch_order", int),
                  np.stack([col("start_x"), col("start_y"), col("start_z")], 1),
                  np.stack([col("axis_x"), col("axis_y"), col("axis_z")], 1),
                  col("length"), col("radius"))
    elif all(c in header for c in _TREEQSM_EXPORT):
        def col(name, kind=float):
            return _column(body, header, name, path, kind)
        start = np.stack([col("startX"), col("startY"), col("startZ")], 1)
        end = np.stack([col("endX"), col("endY"), col("endZ")], 1)
        d = end - start
        length = np.linalg.norm(d, axis=1)
        ids = col("ID", int) + 1
        parent = col("parentID", int) + 1
        order = col("branchOrder", int) if "branchOrder" in header else np.zeros(len(ids), int)
        branch = col("branchID", int) + 1 if "branchID" in header else np.ones(len(ids), int)
        ext = np.zeros(len(ids), int)
        same = {}
        for i, (pa, br) in enumerate(zip(parent, branch, strict=False)):
            same[(pa, br)] = ids[i]
        for i, (me, br) in enumerate(zip(ids, branch, strict=False)):
            ext[i] = same.get((me, br), 0)
        qsm = QSM(ids, parent, ext, branch, order, start,
                  d / np.maximum(length, 1e-12)[:, None], length, col("radius"))
    else:
        raise InputError(f"expected the columns {', '.join(QSM_COLUMNS)} (or a TreeQSM "
                         f"export's ID, parentID, startX ...), got {', '.join(header)}",
                         path=path, field="header")
    for name, arr in (("start_x", qsm.start), ("axis_x", qsm.axis), ("length", qsm.length),
                      ("radius", qsm.radius)):
        if not np.all(np.isfinite(arr)):
            raise InputError("not finite", path=path, field=name)
    if np.any(qsm.length < 0) or np.any(qsm.radius < 0):
        raise InputError("negative length or radius", path=path,
                         field="radius" if np.any(qsm.radius < 0) else "length")
    return check_qsm(qsm, path=path)
