"""``scanamp reconstruct scans``: range scans from free viewpoints, registered to each
other with no initial pose and merged into one surface.

Stages (:class:`core.runs.stages.Stages`, each skipped when its inputs and options are
unchanged): ``register`` (:func:`reconstruct.registration.register_scans`: features and a
seeded RANSAC per pair, verification on the lines of sight, a pose graph, multi-view
ICP), ``merge`` (:func:`reconstruct.surface.volumetric.merge_scans`, Curless and Levoy's
volumetric merging; ``merge = "poisson"`` for Open3D's screened Poisson instead).

Outputs in ``out_dir``: ``mesh.ply``; ``poses.json`` (every scan: ``file``,
``registered``, ``reason``, ``model_from_scan``, ``rms``, ``overlap``); ``poses.conf``
(scanalyze, the registered scans); ``report.json`` (per-scan figures, every pair tried,
pruned edges, wall-clock ``timings`` and ``cpu_timings`` per stage); ``scans_before.png``
and ``scans_after.png`` (the scans coloured by scan, as given and as registered);
``residuals.png``; ``config.toml``.
"""

from __future__ import annotations

import logging
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from core.config import Config, option
from core.files import atomic_dir, json_data, write_json
from core.frames import transform_points
from core.validate import InputError
from reconstruct.result import ReconstructionResult

log = logging.getLogger(__name__)

__all__ = ["ScansReconConfig", "STAGES", "run", "read_initial_poses"]

STAGES = ("register", "merge")
MERGE_METHODS = ("volumetric", "poisson")


@dataclass(frozen=True)
class ScansReconConfig(Config):
    """Options of ``scanamp reconstruct scans``."""

    voxel: float = option(0.0, unit="m", range="[0, inf)",
                          help="sample spacing of the features and the coarse matching "
                               "(0: 1/80 of the median scan's diagonal)")
    fine_voxel: float = option(0.0, unit="m", range="[0, inf)",
                               help="sample spacing of the fine multi-view alignment (0: a "
                                    "third of voxel, at least twice the scans' spacing)")
    seed: int = option(0, help="seed of the RANSAC (same seed, same bytes)")
    ransac_iterations: int = option(2500, range="[100, 10000000]",
                                    help="triples drawn per pair of scans")
    min_overlap: float = option(0.15, range="(0, 1)",
                                help="a pair must share at least this fraction of the smaller "
                                     "scan's samples")
    max_backfacing: float = option(0.1, range="[0, 1]",
                                   help="largest fraction of a pair's overlap seen from "
                                        "opposite sides")
    max_blocking: float = option(0.03, range="[0, 1]",
                                 help="largest fraction of one scan lying in space the other "
                                      "scanner saw through")
    merge: str = option("volumetric", choices=MERGE_METHODS,
                        help="how the registered scans become one surface")
    resolution: float = option(0.0, unit="m", range="[0, inf)",
                               help="voxel of the merge (0: the merge's default from the "
                                    "scans' sample spacing)")
    fill_holes: bool = option(False, help="close holes where the carved space allows (a "
                                          "watertight model)")
    renders: bool = option(True, help="write the before/after renders and the residual plot")


def read_initial_poses(path) -> dict[str, np.ndarray]:
    """``{file name: model_from_scan}`` from a ``.conf``, ``.aln`` or ``poses.json``."""
    from core.io.range import read_aln, read_conf, read_poses_json

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".conf":
        entries = read_conf(path)
    elif suffix == ".aln":
        entries = read_aln(path)
    elif suffix == ".json":
        entries = [(p.file, p.model_from_scan) for p in read_poses_json(path)
                   if p.registered and p.model_from_scan is not None]
    else:
        raise InputError(f"expected a .conf, .aln or .json file, got {suffix or 'no suffix'}",
                         path=path, field="--poses")
    return {Path(f).name: np.asarray(T, float) for f, T in entries}


def _register(scans, cfg: ScansReconConfig, initial):
    from reconstruct.registration import MultiwayOptions, register_scans

    opts = MultiwayOptions(voxel=cfg.voxel, fine_voxel=cfg.fine_voxel, seed=cfg.seed,
                           ransac_iterations=cfg.ransac_iterations,
                           min_overlap=cfg.min_overlap, max_backfacing=cfg.max_backfacing,
                           max_blocking=cfg.max_blocking)
    guess = None
    if initial:
        guess = [initial.get(s.name) if s.path is None else
                 initial.get(s.path.name, initial.get(s.name)) for s in scans]
    result = register_scans(scans, options=opts, initial=guess)
    if guess is not None:  # express the result in the guess's frame
        both = [k for k, s in enumerate(result.scans) if s.registered and guess[k] is not None]
        if both:
            k = both[0]
            g = guess[k] @ np.linalg.inv(result.scans[k].model_from_scan)
            from dataclasses import replace

            result.scans = [replace(s, model_from_scan=g @ s.model_from_scan)
                            if s.registered else s for s in result.scans]
    return result


def _merge(scans, poses, cfg: ScansReconConfig):
    """The merged mesh as arrays (vertices, triangles: the stage cache pickles them) and
    the merge's report."""
    from core.meshes import mesh_arrays

    mesh, rep = _merge_mesh(scans, poses, cfg)
    return mesh_arrays(mesh), rep


def _merge_mesh(scans, poses, cfg: ScansReconConfig):
    t, cpu = time.perf_counter(), time.process_time()
    if cfg.merge == "poisson":
        from reconstruct.surface.meshing import poisson_mesh

        pairs = list(zip(scans, poses, strict=True))
        pts = np.concatenate([transform_points(T, s.points) for s, T in pairs])
        nrm = np.concatenate([s.normals @ T[:3, :3].T for s, T in pairs])
        mesh, _ = poisson_mesh(pts, nrm, depth=9)
        return mesh, {"method": "poisson", "seconds": time.perf_counter() - t,
                      "cpu_seconds": time.process_time() - cpu}
    from reconstruct.surface.volumetric import MergeOptions, merge_scans

    opts = MergeOptions(voxel_size=cfg.resolution or None, fill_holes=cfg.fill_holes)
    mesh, rep = merge_scans(scans, poses, opts)
    return mesh, {"method": "volumetric", **rep, "cpu_seconds": time.process_time() - cpu}


def run(config: ScansReconConfig, inputs, out_dir, *, poses=None,
        from_stage: str | None = None) -> ReconstructionResult:
    """Register and merge the scans named by ``inputs`` (files, folders, E57, ``.conf``)
    into ``out_dir`` (module docstring); ``poses``: an optional initial guess file."""
    from core.meshes import make_mesh, sorted_mesh
    from core.runs.stages import Stages, files_key
    from reconstruct.scans.load import load_scans, scan_files

    cfg = config
    t0, cpu0 = time.perf_counter(), time.process_time()
    paths = [inputs] if isinstance(inputs, (str, Path)) else list(inputs)
    scans = load_scans(paths, min_scans=2)
    initial = read_initial_poses(poses) if poses is not None else None
    t_load, cpu_load = time.perf_counter() - t0, time.process_time() - cpu0
    out_dir = Path(out_dir)
    key = files_key(scan_files(paths)) + (files_key([poses]) if poses else [])
    reg_opts = {k: v for k, v in asdict(cfg).items() if k not in
                ("merge", "resolution", "fill_holes", "renders")}
    with atomic_dir(out_dir) as tmp:
        st = Stages(tmp, STAGES, from_stage=from_stage,
                    reuse=out_dir if out_dir.is_dir() else None)
        result = st.run("register", _register, scans, cfg, initial,
                        depends={"inputs": key, "options": reg_opts})
        placed = [k for k, s in enumerate(result.scans) if s.registered]
        if not placed:
            raise RuntimeError("no two scans could be registered to each other: "
                               + "; ".join(f"{s.name}: {s.reason}" for s in result.scans))
        (verts, tris), merge_rep = st.run(
            "merge", _merge, [scans[k] for k in placed],
            [result.scans[k].model_from_scan for k in placed], cfg,
            depends={"merge": cfg.merge, "resolution": cfg.resolution,
                     "fill_holes": cfg.fill_holes})
        mesh = sorted_mesh(make_mesh(verts, tris, compute_normals=False))  # canonical order
        report = _write_outputs(tmp, scans, result, mesh, merge_rep, cfg, (t_load, cpu_load),
                                time.perf_counter() - t0, st)
    return ReconstructionResult(out_dir, json_data(report))


def _up(sights: list[np.ndarray]) -> np.ndarray:
    """The model's likely up, for the renders: the mean line of sight when the scanners
    looked down from all around, else the axis the lines of sight turn about (a
    turntable's), +y of the model frame's side."""
    s = np.concatenate(sights)
    mean = s.mean(axis=0)
    if np.linalg.norm(mean) > 0.3:
        return mean / np.linalg.norm(mean)
    _, vec = np.linalg.eigh(s.T @ s)
    up = vec[:, 0]
    return up if up[1] >= 0 else -up


def _write_outputs(tmp: Path, scans, result, mesh, merge_rep, cfg, load, t_total, st) -> dict:
    """Write the mesh, poses, report and figures; the report. ``load``: the wall-clock and
    CPU seconds of reading the scans."""
    from core.io.image import write_image
    from core.io.mesh import write_mesh
    from core.io.range import ScanPose, write_conf, write_poses_json

    t_load, cpu_load = load

    write_mesh(tmp / "mesh.ply", mesh)
    poses = [ScanPose(s.name, s.model_from_scan if s.registered else None, s.registered,
                      s.reason, s.rms, s.overlap) for s in result.scans]
    write_poses_json(tmp / "poses.json", poses)
    write_conf(tmp / "poses.conf", [(s.name, s.model_from_scan) for s in result.scans
                                    if s.registered])
    for s in result.scans:
        if not s.registered:
            log.warning("%s not registered: %s", s.name, s.reason)
    report = {
        "counts": {"scans": len(scans), "registered": sum(s.registered for s in result.scans),
                   "pairs_tried": len(result.pairs),
                   "pairs_verified": sum(p["accepted"] for p in result.pairs),
                   "edges_pruned": len(result.pruned),
                   "mesh_vertices": len(mesh.vertices), "mesh_triangles": len(mesh.triangles)},
        "voxel_m": result.voxel, "fine_voxel_m": result.fine_voxel,
        "scans": [s.to_dict() for s in result.scans],
        "pairs": result.pairs, "pruned": result.pruned,
        "merge": {k: v for k, v in merge_rep.items() if k != "scans"},
        "timings": {"load_s": t_load, **{f"register_{k}_s": v for k, v in
                                          result.timings.items() if k != "fine_pairs"},
                    "merge_s": merge_rep.get("seconds"), "total_s": t_total},
        "cpu_timings": {"load_s": cpu_load, **{
            f"register_{k}_s": v for k, v in getattr(result, "cpu_timings", {}).items()},
            "merge_s": merge_rep.get("cpu_seconds")},
        "stages": {"ran": st.ran, "reused": st.skipped},
    }
    write_json(tmp / "report.json", report)
    if cfg.renders:
        from reconstruct.scans.figures import plot_residuals, render_scans

        sub = [np.arange(0, len(s.points), max(1, len(s.points) // 30000)) for s in scans]
        before = render_scans([s.points[i] for s, i in zip(scans, sub, strict=True)],
                              [s.normals[i] for s, i in zip(scans, sub, strict=True)])
        write_image(tmp / "scans_before.png", before)
        after_p, after_n, cols = [], [], []
        from reconstruct.scans.figures import scan_colors

        palette = scan_colors(len(scans))
        for k, (s, i) in enumerate(zip(scans, sub, strict=True)):
            if result.scans[k].registered:
                T = result.scans[k].model_from_scan
                after_p.append(transform_points(T, s.points[i]))
                after_n.append(s.normals[i] @ T[:3, :3].T)
                cols.append(palette[k])
        write_image(tmp / "scans_after.png", render_scans(after_p, after_n, up=_up(
            [scans[k].sight[::50] @ result.scans[k].model_from_scan[:3, :3].T
             for k in range(len(scans)) if result.scans[k].registered]),
            colors=np.array(cols)))
        write_image(tmp / "residuals.png", plot_residuals(
            [s.name for s in result.scans], [s.rms for s in result.scans],
            [s.overlap for s in result.scans], [s.registered for s in result.scans]))
    return report
