"""Run a particle or cloth recipe into an output folder (shared by ``scanamp simulate``).

``out_dir`` receives ``frames/*.vtp`` + ``series.pvd`` (ParaView), ``ply/*.ply`` (point
or cloth sequences), ``animation.mp4`` (splats over the rendered mesh) and
``report.json`` (counts, escapes, energy, status). The folder is written atomically;
a run stopped by a non-finite state still writes it, with ``status`` saying why.
"""

from __future__ import annotations

import logging
import os
import time
from pathlib import Path

import numpy as np

from core.files import atomic_dir, write_json
from core.io.mesh import read_mesh, write_mesh, write_points
from core.progress import track
from simulate.colliders import MeshCollider
from simulate.particles import NonFiniteStateError
from simulate.recipes import build_cloth, build_particles, load_recipe, procedural_scan
from simulate.series_io import SeriesWriter

log = logging.getLogger(__name__)

__all__ = ["run_simulation"]


def run_simulation(kind: str, recipe: str | os.PathLike, out_dir: str | os.PathLike, *,
                   mesh_path: str | os.PathLike | None = None, frames: int | None = None,
                   render: bool = True, width: int = 480, height: int = 360,
                   seed: int | None = None, animation: str = "animation.mp4") -> dict:
    """Simulate ``recipe`` (name or TOML) of ``kind`` (``particles``/``cloth``) into ``out_dir``.

    ``mesh_path`` is the collider and emitter mesh (default: a procedural scan); a mesh
    without faces is a warning and the run goes on without collisions. ``animation``
    names the video (``.mp4`` or ``.gif``). Returns the report (also ``report.json``).
    """
    if Path(animation).suffix.lower() not in (".mp4", ".gif") or Path(animation).name != animation:
        raise ValueError(f"animation: expected a file name ending in .mp4 or .gif, got "
                         f"{animation!r}")
    table, path = load_recipe(recipe)
    if table["kind"] != kind:
        raise ValueError(f"recipe: {path} is a {table['kind']} recipe, not {kind}; use "
                         f"`scanamp simulate {table['kind']}`")
    if seed is not None:
        table["seed"] = int(seed)
    mesh = read_mesh(mesh_path) if mesh_path is not None else procedural_scan()
    if len(mesh.triangles):
        collider = MeshCollider(mesh)
    else:
        collider = None
        log.warning("%s: the collider mesh has no faces; simulating without collisions",
                    mesh_path)
    n_frames = int(frames or table.get("frames", 96))
    fps = float(table.get("fps", 24))
    status, error = "ok", None
    per_frame = []
    render_frames = []
    t0 = time.perf_counter()
    out_dir = Path(out_dir)
    with atomic_dir(out_dir) as tmp:
        writer = SeriesWriter(tmp)
        (tmp / "ply").mkdir()
        if collider is not None:
            write_mesh(tmp / "collider.ply", mesh)
        if kind == "particles":
            system = build_particles(table, path, mesh=mesh, collider=collider)
            for k in track(range(n_frames), "simulating", total=n_frames):
                try:
                    st = system.step_frame()
                except NonFiniteStateError as exc:
                    status, error = "nonfinite", str(exc)
                    break
                fr = system.frame()
                writer.add(st.time, fr["points"], point_data={
                    "id": fr["ids"], "velocity": fr["velocity"], "age": fr["age"],
                    "temperature": fr["temperature"], "color": fr["colors"],
                    "size": fr["sizes"], "emitter": fr["emitter"]})
                write_points(tmp / "ply" / f"frame_{k:05d}.ply", fr["points"],
                             colors=fr["colors"])
                per_frame.append({"frame": st.frame, "time": st.time, "alive": st.alive,
                                  "born": st.born, "died": st.died, "impacts": st.impacts,
                                  "escapes": st.escapes, "kinetic": st.kinetic,
                                  "potential": st.potential})
                render_frames.append({k2: fr[k2] for k2 in ("points", "colors", "sizes",
                                                               "alphas")})
            totals = {"particles_born": int(sum(f["born"] for f in per_frame)),
                      "particles_alive": int(per_frame[-1]["alive"]) if per_frame else 0,
                      "dropped": system.dropped,
                      "escapes": int(sum(f["escapes"] for f in per_frame)),
                      "impacts": int(sum(f["impacts"] for f in per_frame))}
        else:
            cloth, substeps = build_cloth(table, path, mesh=mesh, collider=collider)
            dt = 1.0 / fps
            for k in track(range(n_frames), "simulating", total=n_frames):
                try:
                    st = cloth.advance(dt, substeps)
                except RuntimeError as exc:
                    status, error = "nonfinite", str(exc)
                    break
                e = cloth.energy()
                writer.add(cloth.t, cloth.x, triangles=cloth.triangles,
                           point_data={"id": np.arange(len(cloth.x)), "velocity": cloth.v})
                from core.meshes import make_mesh

                write_mesh(tmp / "ply" / f"frame_{k:05d}.ply", make_mesh(cloth.x,
                                                                          cloth.triangles))
                sd = (collider.signed_distance(cloth.x)
                      if collider is not None and collider.closed else None)
                per_frame.append({"frame": k + 1, "time": cloth.t, "impacts": st.impacts,
                                  "escapes": int(np.count_nonzero(sd < -1e-4))
                                  if sd is not None else 0,
                                  "max_stretch": float(cloth.stretch().max()), **e})
                render_frames.append({"points": cloth.x.copy(),
                                      "colors": np.tile([0.85, 0.25, 0.2], (len(cloth.x), 1)),
                                      "sizes": np.full(len(cloth.x), 0.6 * cloth.spec.spacing),
                                      "alphas": np.full(len(cloth.x), 0.9)})
            totals = {"vertices": len(cloth.x), "substeps": substeps,
                      "stable_step": cloth.stable_step(),
                      "escapes": int(sum(f["escapes"] for f in per_frame))}
        writer.close()
        sim_seconds = time.perf_counter() - t0
        if render and render_frames:
            from acquire.camera import frame_camera
            from scanamp.animation.render import mesh_background, render_animation

            pts = [f["points"] for f in render_frames if len(f["points"])]
            allp = np.concatenate(pts + [np.asarray(mesh.vertices)])
            lo, hi = np.percentile(allp, 1, axis=0), np.percentile(allp, 99, axis=0)
            cam_t = table.get("camera", {})
            cam = frame_camera(np.stack([lo, hi]), width=width, height=height,
                               elevation_deg=float(cam_t.get("elevation_deg", 20.0)),
                               azimuth_deg=float(cam_t.get("azimuth_deg", -90.0)))
            bg, depth = mesh_background(mesh, cam) if collider is not None else (None, None)
            render_animation(render_frames, cam, tmp / animation, background=bg,
                             background_depth=depth, fps=fps, total=len(render_frames))
        report = {"kind": kind, "recipe": str(path), "mesh": str(mesh_path) if mesh_path
                  else "procedural_scan", "seed": table.get("seed", 0), "status": status,
                  "error": error, "frames": len(per_frame), "fps": fps,
                  "collider_closed": None if collider is None else collider.closed,
                  "animation": animation if render and render_frames else None, **totals,
                  "energy_first": per_frame[0] if per_frame else None,
                  "energy_last": per_frame[-1] if per_frame else None,
                  "simulation_seconds": sim_seconds, "per_frame": per_frame}
        write_json(tmp / "report.json", report)
    return report
