"""``scanamp procgen sweep --out sweep.ply``: a profile swept along a path with
parallel-transport (or Frenet) frames, twist and taper (:func:`procgen.sweeps.sweep`)."""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from core.config import Config, option
from scanamp.cli._procgen_common import (
    MESH_OUT,
    add_output,
    check_out,
    preview_path,
    render_preview,
)

NAME = "sweep"
GROUP = "procgen"
OUTPUT = "file"
HELP = "sweep a profile (circle, square, star) along a path (helix, trefoil knot, circle)"

log = logging.getLogger(__name__)

COLOR = (0.55, 0.62, 0.78)


@dataclass
class SweepConfig(Config):
    """Options of ``scanamp procgen sweep``."""

    profile: str = option("star", choices=("circle", "square", "star"), help="cross-section")
    path: str = option("helix", choices=("helix", "trefoil", "circle"), help="spine curve")
    size: float = option(1.0, unit="m", range="(0, inf)", help="extent of the path")
    radius: float = option(0.08, range="(0, 1)", help="profile radius, fraction of size")
    twist: float = option(2.0, unit="turns", range="(-inf, inf)",
                          help="turns of the profile about the path, start to end")
    taper: float = option(0.0, range="[0, 1)", help="the profile shrinks by this at the end")
    frames: str = option("parallel", choices=("parallel", "frenet"),
                         help="moving frame (parallel transport does not flip)")
    samples: int = option(400, range="[8, 100000]", help="path samples")


CONFIG = SweepConfig


def companions(args, config=None):
    return [] if args.no_preview else [preview_path(args.out)]


def add_arguments(p):
    add_output(p, kind="mesh")


def _profile(kind: str, r: float) -> np.ndarray:
    if kind == "circle":
        t = np.linspace(0, 2 * np.pi, 24, endpoint=False)
        return r * np.c_[np.cos(t), np.sin(t)]
    if kind == "square":
        return r * np.array([[1, -1], [1, 1], [-1, 1], [-1, -1]], float)
    t = np.linspace(0, 2 * np.pi, 10, endpoint=False)  # a five-pointed star
    rad = np.where(np.arange(10) % 2 == 0, r, 0.45 * r)
    return np.c_[rad * np.cos(t), rad * np.sin(t)]


def _path(kind: str, n: int) -> tuple[np.ndarray, bool]:
    t = np.linspace(0, 2 * np.pi, n, endpoint=kind == "helix")
    if kind == "helix":
        return np.c_[0.5 * np.cos(3 * t), 0.5 * np.sin(3 * t), t / (2 * np.pi)], False
    if kind == "circle":
        return np.c_[0.5 * np.cos(t), 0.5 * np.sin(t), 0 * t], True
    x = np.sin(t) + 2 * np.sin(2 * t)                     # trefoil knot
    y = np.cos(t) - 2 * np.cos(2 * t)
    return np.c_[x, y, -np.sin(3 * t)] / 6.0, True


def run(args, config: SweepConfig) -> int:
    from core.io.mesh import write_mesh
    from core.meshes import make_mesh
    from procgen.sweeps import sweep

    out = check_out(args.out, MESH_OUT)
    path, closed = _path(config.path, config.samples)
    if closed and config.taper > 0:
        raise ValueError(f"--taper: a closed path ({config.path}) joins its ends, so it "
                         f"cannot taper; expected 0, got {config.taper}")
    path = path * (config.size / float(np.max(np.ptp(path, axis=0))))
    u = np.linspace(0.0, 1.0, len(path))
    v, f = sweep(_profile(config.profile, config.radius * config.size), path,
                 frames=config.frames, twist=2 * np.pi * config.twist * u,
                 scale=1.0 - config.taper * u, closed_path=closed, caps=not closed)
    mesh = make_mesh(v, f)
    write_mesh(out, mesh)
    log.info("wrote %s (%d triangles)", out, len(f))
    if not args.no_preview:
        log.info("wrote %s", render_preview([(mesh, COLOR)], preview_path(out)))
    return 0
