"""The 3-D turtle: interpreting a derived string as segments and polygons.

Conventions (ABOP chapter 1.5, written down here and tested):

- The turtle state is a position and a right-handed orthonormal frame: heading ``H``,
  left ``L`` and up ``U`` with ``H x L = U``. It starts at the origin with
  ``H = +Z`` (world up), ``L = -X`` and ``U = -Y``, so a 2-D grammar draws in the XZ
  plane as seen from the front (from -Y, X to the right): ``+`` turns toward -X.
- ``+ & \\`` are right-handed rotations by ``+angle`` about ``U``, ``L`` and ``H``
  (ABOP's R_U(d), R_L(d), R_H(d)); ``- ^ /`` rotate by ``-angle``. So ``+`` turns left,
  ``&`` pitches down, ``\\`` rolls left, ``|`` turns around (R_U(180)).
- ``F`` moves forward by ``step`` and draws a segment; ``f`` moves without drawing;
  ``G`` moves without drawing or recording a polygon vertex. ``F(l)``, ``f(l)``, ``G(l)``
  move by ``l``; ``+(a)`` etc. turn by ``a`` degrees.
- ``[`` pushes the state, ``]`` pops it. ``!`` multiplies the width by ``width_factor``,
  ``!(w)`` sets it; ``'`` increments the colour index, ``'(c)`` sets it.
- ``{`` starts a polygon, ``.`` records the position as a vertex, ``}`` closes it; inside
  a polygon ``F`` and ``f`` record the position they reach instead of drawing.
- ``$`` rolls the turtle about ``H`` so that ``L`` is horizontal (ABOP: L = V x H / |V x H|).
- Tropism: after every ``F`` the frame turns about ``H x T`` by ``e |H x T|``.

Every segment remembers its parent (the segment that ended where it starts on the same
branch), so tubes can share rings at joints (:func:`procgen.sweeps.segment_tubes`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from procgen.lsystem.derive import LString
from procgen.lsystem.grammar import Grammar

__all__ = ["TurtleResult", "interpret", "OPS", "INITIAL_FRAME"]

(_NOP, _DRAW, _MOVE, _MOVE_NOREC, _TURN, _TURN_NEG, _PITCH, _PITCH_NEG, _ROLL, _ROLL_NEG,
 _AROUND, _PUSH, _POP, _WIDTH, _COLOR, _POLY_BEGIN, _POLY_END, _VERTEX, _LEVEL) = range(19)

OPS = {"F": _DRAW, "f": _MOVE, "G": _MOVE_NOREC, "+": _TURN, "-": _TURN_NEG, "&": _PITCH,
       "^": _PITCH_NEG, "\\": _ROLL, "/": _ROLL_NEG, "|": _AROUND, "[": _PUSH, "]": _POP,
       "!": _WIDTH, "'": _COLOR, "{": _POLY_BEGIN, "}": _POLY_END, ".": _VERTEX, "$": _LEVEL}
"""Symbol -> turtle operation code."""

INITIAL_FRAME = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
"""Rows H, L, U of the turtle's starting frame."""


@dataclass
class TurtleResult:
    """What the turtle drew.

    Attributes
    ----------
    starts, ends : (m, 3) float64
        Segment end points, in drawing order.
    frames : (m, 3, 3) float64
        Rows H, L, U of the turtle frame while drawing each segment.
    widths : (m,) float64
    colors : (m,) int32
    parents : (m,) int64
        Index of the segment this one continues (-1 at a branch base after a move).
    polygon_vertices : (p, 3) float64
    polygon_ids : (p,) int64
        Polygon of each vertex (vertices of one polygon are contiguous).
    """

    starts: np.ndarray
    ends: np.ndarray
    frames: np.ndarray
    widths: np.ndarray
    colors: np.ndarray
    parents: np.ndarray
    polygon_vertices: np.ndarray
    polygon_ids: np.ndarray

    def __len__(self) -> int:
        return len(self.starts)

    def polylines(self) -> list[np.ndarray]:
        """Chains of segments as ``(k, 3)`` point arrays (a 2-D curve is one polyline)."""
        m = len(self.starts)
        if m == 0:
            return []
        idx = np.arange(m)
        breaks = np.flatnonzero((self.parents != idx - 1) | (idx == 0))
        breaks = np.concatenate([breaks, [m]])
        return [np.vstack([self.starts[a:a + 1], self.ends[a:b]])
                for a, b in zip(breaks[:-1], breaks[1:], strict=True)]


@numba.njit(cache=True)
def _rotate_cs(a, b, c, s):
    """Rotate the pair (a, b) in their plane: a -> c a + s b, b -> -s a + c b."""
    for t in range(3):
        x = a[t]
        y = b[t]
        a[t] = c * x + s * y
        b[t] = -s * x + c * y


@numba.njit(cache=True)
def _rotate(a, b, ang):
    """Rotate the pair (a, b) in their plane by ``ang`` radians."""
    _rotate_cs(a, b, np.cos(ang), np.sin(ang))


@numba.njit(cache=True)
def _cross(a, b, out):
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@numba.njit(cache=True)
def _normalize(a):
    n = np.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
    if n > 0:
        for t in range(3):
            a[t] /= n


@numba.njit(cache=True, inline="always")
def _turn(a, b, has_arg, ang, ca, sa, sign):
    """One turtle rotation of the pair (a, b) by ``sign`` times the module's own angle
    ``ang`` (radians) when it has an argument, else by the grammar's default (cos ca, sin sa)."""
    if has_arg:
        _rotate(a, b, sign * ang)
    else:
        _rotate_cs(a, b, ca, sign * sa)


@numba.njit(cache=True)
def _orthonormalize(H, L, U):
    _normalize(H)
    _cross(U, H, L)  # L = U x H
    _normalize(L)
    _cross(H, L, U)  # U = H x L


@numba.njit(cache=True)
def _run(codes, ops, params, npar, has_params, step, angle, width, width_factor, tropism,
         use_tropism, depth, starts, ends, frames, widths, colors, parents, pv, pid):
    deg = np.pi / 180.0
    ca = np.cos(angle * deg)  # the default turn, computed once
    sa = np.sin(angle * deg)
    pos = np.zeros(3)
    H = np.array([0.0, 0.0, 1.0])
    L = np.array([-1.0, 0.0, 0.0])
    U = np.array([0.0, -1.0, 0.0])
    w = width
    color = 0
    last = -1
    stack_f = np.empty((depth + 1, 13))
    stack_i = np.empty((depth + 1, 2), np.int64)
    top = 0
    n_pv = len(pv)
    poly_stack = np.empty(depth + n_pv + 1, np.int64)
    ptop = 0
    cur_poly = -1
    n_poly = 0
    m = 0
    p = 0
    tmp = np.empty(3)
    T = tropism[:3].copy()
    _normalize(T)
    e = tropism[3]
    for i in range(len(codes)):
        op = ops[codes[i]]
        if op == _NOP:
            continue
        has = has_params and npar[i] > 0
        arg = params[i, 0] if has else 0.0
        if op == _DRAW or op == _MOVE or op == _MOVE_NOREC:
            d = arg if has else step
            if op == _DRAW and cur_poly < 0:
                starts[m] = pos
                for t in range(3):
                    pos[t] += d * H[t]
                ends[m] = pos
                frames[m, 0] = H
                frames[m, 1] = L
                frames[m, 2] = U
                widths[m] = w
                colors[m] = color
                parents[m] = last
                last = m
                m += 1
                if use_tropism:
                    _cross(H, T, tmp)
                    s = np.sqrt(tmp[0] ** 2 + tmp[1] ** 2 + tmp[2] ** 2)
                    if s > 1e-12:
                        alpha = e * s
                        # rotate the frame about axis k = tmp / s by alpha (Rodrigues)
                        for t in range(3):
                            tmp[t] /= s
                        c = np.cos(alpha)
                        sn = np.sin(alpha)
                        for vec in (H, L, U):
                            kd = tmp[0] * vec[0] + tmp[1] * vec[1] + tmp[2] * vec[2]
                            kx = tmp[1] * vec[2] - tmp[2] * vec[1]
                            ky = tmp[2] * vec[0] - tmp[0] * vec[2]
                            kz = tmp[0] * vec[1] - tmp[1] * vec[0]
                            vec[0] = vec[0] * c + kx * sn + tmp[0] * kd * (1 - c)
                            vec[1] = vec[1] * c + ky * sn + tmp[1] * kd * (1 - c)
                            vec[2] = vec[2] * c + kz * sn + tmp[2] * kd * (1 - c)
                        _orthonormalize(H, L, U)
            else:
                for t in range(3):
                    pos[t] += d * H[t]
                last = -1
                if cur_poly >= 0 and op != _MOVE_NOREC:
                    pv[p] = pos
                    pid[p] = cur_poly
                    p += 1
        elif op == _TURN or op == _TURN_NEG:
            _turn(H, L, has, arg * deg, ca, sa, 1.0 if op == _TURN else -1.0)
            _orthonormalize(H, L, U)
        elif op == _PITCH or op == _PITCH_NEG:
            # R_L(+a): H -> cos H - sin U, U -> sin H + cos U
            _turn(U, H, has, arg * deg, ca, sa, 1.0 if op == _PITCH else -1.0)
            _orthonormalize(H, L, U)
        elif op == _ROLL or op == _ROLL_NEG:
            # R_H(+a): L -> cos L + sin U
            _turn(L, U, has, arg * deg, ca, sa, 1.0 if op == _ROLL else -1.0)
            _orthonormalize(H, L, U)
        elif op == _AROUND:
            _rotate(H, L, np.pi)
            _orthonormalize(H, L, U)
        elif op == _PUSH:
            stack_f[top, 0:3] = pos
            stack_f[top, 3:6] = H
            stack_f[top, 6:9] = L
            stack_f[top, 9:12] = U
            stack_f[top, 12] = w
            stack_i[top, 0] = color
            stack_i[top, 1] = last
            top += 1
        elif op == _POP:
            if top > 0:
                top -= 1
                pos[:] = stack_f[top, 0:3]
                H[:] = stack_f[top, 3:6]
                L[:] = stack_f[top, 6:9]
                U[:] = stack_f[top, 9:12]
                w = stack_f[top, 12]
                color = stack_i[top, 0]
                last = stack_i[top, 1]
        elif op == _WIDTH:
            w = arg if has else w * width_factor
        elif op == _COLOR:
            color = int(arg) if has else color + 1
        elif op == _POLY_BEGIN:
            poly_stack[ptop] = cur_poly
            ptop += 1
            cur_poly = n_poly
            n_poly += 1
        elif op == _POLY_END:
            if ptop > 0:
                ptop -= 1
                cur_poly = poly_stack[ptop]
        elif op == _VERTEX:
            if cur_poly >= 0:
                pv[p] = pos
                pid[p] = cur_poly
                p += 1
        elif op == _LEVEL:
            # L = V x H / |V x H| with V = +Z; U = H x L
            tmp[0] = -H[1]
            tmp[1] = H[0]
            tmp[2] = 0.0
            s = np.sqrt(tmp[0] ** 2 + tmp[1] ** 2)
            if s > 1e-12:
                L[:] = tmp / s
                _cross(H, L, U)
    return m, p


@numba.njit(cache=True)
def _sizes(codes, ops):
    """Upper bounds for the turtle's outputs: segments, polygon vertices, stack depth."""
    n_seg = 0
    n_pv = 0
    depth = 0
    for i in range(len(codes)):
        op = ops[codes[i]]
        if op == _DRAW:
            n_seg += 1
            n_pv += 1
        elif op == _MOVE or op == _VERTEX:
            n_pv += 1
        elif op == _PUSH:
            depth += 1
    return n_seg, n_pv, depth


def op_table(grammar: Grammar | None = None) -> np.ndarray:
    """``(256,) int8`` symbol code -> turtle operation (the grammar's ``draw``/``move`` too)."""
    table = np.zeros(256, np.int8)
    for sym, op in OPS.items():
        table[ord(sym)] = op
    if grammar is not None:
        for sym in grammar.draw:
            table[ord(sym)] = _DRAW
        for sym in grammar.move:
            table[ord(sym)] = _MOVE
    return table


def interpret(string: LString, grammar: Grammar | None = None, *, step: float | None = None,
              angle: float | None = None, width: float | None = None,
              width_factor: float | None = None, tropism=None) -> TurtleResult:
    """Run the turtle over a derived string.

    Parameters
    ----------
    string : LString
    grammar : Grammar, optional
        Supplies ``step``, ``angle`` (degrees), ``width``, ``width_factor``, ``tropism``
        and the extra ``draw``/``move`` symbols; keyword arguments override it.
    tropism : (4,) float, optional
        ``(x, y, z, e)``.

    Returns
    -------
    TurtleResult
    """
    g = grammar
    step = float(step if step is not None else (g.step if g else 1.0))
    angle = float(angle if angle is not None else (g.angle if g else 90.0))
    width = float(width if width is not None else (g.width if g else 0.1))
    width_factor = float(width_factor if width_factor is not None else
                         (g.width_factor if g else 0.7))
    trop = tropism if tropism is not None else (g.tropism if g else None)
    use_trop = trop is not None
    trop_arr = np.asarray(trop if use_trop else (0.0, 0.0, -1.0, 0.0), np.float64)
    if trop_arr.shape != (4,) or not np.all(np.isfinite(trop_arr)):
        raise ValueError(f"tropism: expected 4 finite numbers (x, y, z, e), got {trop!r}")
    ops = op_table(g)
    codes = string.codes
    n_seg, n_pv, depth = _sizes(codes, ops)
    has = string.params is not None
    params = string.params if has else np.zeros((1, 1))
    npar = string.nparams if has else np.zeros(1, np.uint8)
    # outputs allocated by numpy (huge pages for big arrays: fewer first-touch page faults)
    starts, ends = np.empty((n_seg, 3)), np.empty((n_seg, 3))
    frames, widths = np.empty((n_seg, 3, 3)), np.empty(n_seg)
    colors, parents = np.empty(n_seg, np.int32), np.empty(n_seg, np.int64)
    pv, pid = np.empty((n_pv, 3)), np.empty(n_pv, np.int64)
    m, p = _run(codes, ops, params, npar, has, step, angle, width, width_factor, trop_arr,
                use_trop, depth, starts, ends, frames, widths, colors, parents, pv, pid)
    return TurtleResult(starts[:m], ends[:m], frames[:m], widths[:m], colors[:m], parents[:m],
                        pv[:p], pid[:p])
