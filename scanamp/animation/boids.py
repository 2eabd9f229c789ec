"""``scanamp simulate boids``: run a boids recipe around a mesh and write its outputs.

The output folder holds ``frames/*.vtp`` + ``series.pvd`` (positions with velocity,
heading, speed and id), ``metrics.csv`` (one row a step: polarization, milling,
mean nearest-neighbour distance, groups), ``metrics.png`` (polarization and milling
over time), ``animation.mp4`` (oriented glyphs over the rendered mesh) and
``report.json``. Written atomically.
"""

from __future__ import annotations

import csv
import logging
import os
import time
from pathlib import Path

import numpy as np

from core.files import atomic_dir, write_json
from core.progress import track
from simulate.boids import FlockState, Recipe, init_flock, step
from simulate.boids.metrics import METRIC_NAMES, flock_metrics
from simulate.colliders import MeshCollider
from simulate.series_io import SeriesWriter

log = logging.getLogger(__name__)

__all__ = ["run_boids", "render_flock", "plot_metrics"]


def _place_outside(state: FlockState, collider: MeshCollider, rng, recipe: Recipe) -> int:
    """Move boids that start inside (or within a probe of) the mesh to free spots."""
    margin = max(recipe.params.skin * 10, 0.05 * recipe.params.separation_radius)
    moved = 0
    for _ in range(200):
        x = state.positions
        bad = collider.distance(x) < margin
        if collider.closed:
            bad |= collider.inside(x)
        idx = np.nonzero(bad)[0]
        if len(idx) == 0:
            return moved
        moved += len(idx)
        d = rng.standard_normal((len(idx), 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        rad = recipe.init_radius * rng.uniform(0, 1, len(idx)) ** (1 / 3)
        state.positions[idx] = np.asarray(recipe.init_centre) + d * rad[:, None]
    raise ValueError("run.init_centre, run.init_radius: the start ball lies inside the mesh; "
                     "move it into free space")


def run_boids(recipe: Recipe, out_dir: str | os.PathLike, *, mesh=None, render: bool = True,
              animation: str = "animation.mp4", width: int = 640, height: int = 480,
              fps: float = 24) -> Path:
    """Simulate ``recipe`` (around ``mesh`` if given) and write the output folder.

    Parameters
    ----------
    recipe : simulate.boids.Recipe
    out_dir : path
    mesh : open3d.geometry.TriangleMesh, optional
        Collider (must have faces).
    render : bool
        Write the animation (and ``metrics.png``).
    animation : str
        File name ending in ``.mp4`` or ``.gif``.
    """
    p = recipe.params
    collider = MeshCollider(mesh) if mesh is not None else None
    rng = np.random.default_rng(recipe.seed)
    state = init_flock(recipe.n, p, rng=rng, centre=recipe.init_centre,
                       radius=recipe.init_radius)
    moved = _place_outside(state, collider, rng, recipe) if collider is not None else 0
    rows = []
    frames = []
    ids = np.arange(recipe.n)
    t0 = time.perf_counter()
    sim_time = 0.0
    with atomic_dir(out_dir) as tmp:
        writer = SeriesWriter(tmp)

        def record(k):
            m = flock_metrics(state.positions, state.velocities,
                              group_radius=recipe.group_radius)
            rows.append([k, state.time] + [m[name] for name in METRIC_NAMES])
            if k % recipe.frame_every == 0 or k == recipe.steps:
                v = state.velocities
                sp = np.linalg.norm(v, axis=1)
                heading = np.divide(v, sp[:, None], out=np.zeros_like(v), where=sp[:, None] > 0)
                writer.add(state.time, state.positions, point_data={
                    "id": ids, "velocity": v, "heading": heading, "speed": sp})
                frames.append((state.positions.copy(), heading))

        record(0)
        for k in track(range(1, recipe.steps + 1), "boids", total=recipe.steps):
            s = time.perf_counter()
            step(state, p, rng=rng, collider=collider)
            sim_time += time.perf_counter() - s
            record(k)
        writer.close()
        with open(tmp / "metrics.csv", "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["step", "time", *METRIC_NAMES])
            for r in rows:
                w.writerow([r[0], f"{r[1]:.6f}", *(f"{x:.9g}" for x in r[2:5]), r[5]])
        arr = np.array([r[2:] for r in rows], float)
        tail = arr[len(arr) * 2 // 3:]
        report = {
            "format": "scanamp.boids/1",
            "recipe": recipe.name,
            "model": p.model,
            "n": recipe.n, "steps": recipe.steps, "seed": recipe.seed,
            "params": {k: getattr(p, k) for k in p.__dataclass_fields__},
            "mesh": None if collider is None else {
                "vertices": len(collider.vertices), "triangles": len(collider.triangles),
                "closed": collider.closed},
            "boids_moved_out_of_mesh_at_start": int(moved),
            "swept_segment_stops": int(state.collisions),
            "final": dict(zip(METRIC_NAMES, arr[-1].tolist(), strict=True)),
            "mean_last_third": dict(zip(METRIC_NAMES, tail.mean(axis=0).tolist(), strict=True)),
            "frames": len(frames),
            "step_seconds": sim_time,
            "boid_updates_per_second": recipe.n * recipe.steps / max(sim_time, 1e-12),
        }
        if render:
            plot_metrics(tmp / "metrics.csv", tmp / "metrics.png", title=recipe.name)
            render_flock(frames, tmp / animation, mesh=mesh, width=width, height=height,
                         fps=fps, size=_glyph_size(recipe))
            report["animation"] = animation
        report["total_seconds"] = time.perf_counter() - t0
        write_json(tmp / "report.json", report)
    log.info("boids %s: %d boids x %d steps, polarization %.3f, milling %.3f -> %s",
             recipe.name, recipe.n, recipe.steps, arr[-1, 0], arr[-1, 1], out_dir)
    return Path(out_dir)


def _glyph_size(recipe: Recipe) -> float:
    p = recipe.params
    return 0.8 * (p.zor if p.model == "couzin" else p.separation_radius)


def render_flock(frames, out_path: str | os.PathLike, *, mesh=None, width: int = 640,
                 height: int = 480, fps: float = 24, size: float = 0.3) -> Path:
    """Render ``frames`` (a list of ``(positions (n, 3), headings (n, 3))``) as oriented
    glyphs over the shaded mesh, to MP4 or GIF."""
    from acquire.camera import frame_camera
    from acquire.render.glyphs import render_glyphs
    from core.meshes import mesh_arrays
    from scanamp.animation.render import mesh_background, render_animation

    out_path = Path(out_path)
    suffix = out_path.suffix.lower()
    if suffix not in (".mp4", ".gif"):
        raise ValueError(f"animation: expected a .mp4 or .gif file, got {out_path.name!r}")
    pts = [f[0] for f in frames[:: max(1, len(frames) // 20)]] + [frames[-1][0]]
    # Frame the mesh and the flock's middle 95 % (a few strays must not shrink the view).
    allp = np.concatenate(pts)
    lo, hi = np.percentile(allp, 2.5, axis=0), np.percentile(allp, 97.5, axis=0)
    box = [lo, hi]
    if mesh is not None:
        v, _ = mesh_arrays(mesh)
        box += [v.min(0), v.max(0)]
    cam = frame_camera(np.array(box), width=width, height=height, elevation_deg=35,
                       azimuth_deg=-70, margin=1.0)
    if mesh is not None:
        bg, depth = mesh_background(mesh, cam)
    else:
        bg, depth = np.zeros((height, width, 3)) + [0.08, 0.09, 0.12], None

    def glyphs(frame, camera, background, background_depth):
        x, heading = frame
        return render_glyphs(x, heading, camera, size=size, background=background,
                             background_depth=background_depth)

    return render_animation(frames, cam, out_path, background=bg, background_depth=depth,
                            fps=fps, total=len(frames), draw=glyphs)


def plot_metrics(csv_paths, out_png: str | os.PathLike, *, title: str = "",
                 labels=None) -> Path:
    """Plot polarization and milling over time from one or more ``metrics.csv`` files."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure  # no pyplot: the caller's backend stays untouched

    from core.files import atomic_file

    paths = [csv_paths] if isinstance(csv_paths, (str, os.PathLike)) else list(csv_paths)
    labels = labels or [Path(p).parent.name for p in paths]
    fig = Figure(figsize=(4.2 * len(paths), 3.2))
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(paths), squeeze=False, sharey=True)
    for ax, path, label in zip(axes[0], paths, labels, strict=True):
        data = np.genfromtxt(path, delimiter=",", names=True)
        ax.plot(data["time"], data["polarization"], label="polarization P")
        ax.plot(data["time"], data["milling"], label="milling M")
        ax.set_ylim(0, 1.02)
        ax.set_xlabel("time (s)")
        ax.set_title(title if len(paths) == 1 and title else label)
        ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="center right")
    fig.tight_layout()
    with atomic_file(out_png) as tmp:
        fig.savefig(tmp, dpi=110)
    return Path(out_png)
