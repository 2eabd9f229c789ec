"""``scanamp amplify``: run an amplification recipe on a (reconstructed) mesh.

A recipe (TOML, see ``docs/amplify.md``) is an ordered list of steps — ``displace``,
``refine-terrain``, ``scatter``, ``sweep``, ``hypertexture``, ``animate`` — applied to
the mesh in turn. The shape-changing steps (displace, refine-terrain, hypertexture)
replace the *surface*; scatter and sweep add *parts* (plants, vines) planted on the
current surface; animate runs a particle, cloth or boids recipe with surface + parts as
the collider.

Output folder (written atomically): ``mesh.ply`` (the final mesh: surface and parts
merged, every vertex with ``red green blue`` and an integer ``label``; ``labels.json``
names the labels, :mod:`scanamp.amplify.labels`), ``mesh.gltf`` (the same with its
colours), ``surface.ply`` and one PLY per added part, ``before.png`` / ``after.png``,
``animation/`` (one folder per animate step, as ``scanamp simulate`` writes it) and
``report.json`` (steps with their validated parameters, counts before and after,
timings, seed).

>>> from scanamp.amplify import recipe_names
>>> "displace" in recipe_names()
True
"""

from __future__ import annotations

import logging
import os
import time
from pathlib import Path

import numpy as np

from core.files import atomic_dir, write_json
from core.io.image import write_image
from core.io.mesh import read_mesh, write_mesh
from core.meshes import mesh_arrays
from core.progress import track
from core.validate import InputError
from scanamp.amplify.recipe import KINDS, Recipe, Step, load_recipe, parse_recipe, recipe_names
from scanamp.amplify.steps import EXECUTORS, State

log = logging.getLogger(__name__)

__all__ = ["run", "run_variants", "amplify", "load_recipe", "parse_recipe", "recipe_names",
           "KINDS", "Recipe", "Step", "State"]


def _counts(mesh) -> dict:
    return {"vertices": len(mesh.vertices), "triangles": len(mesh.triangles)}


def amplify(mesh, recipe, *, seed: int = 0, out_dir: str | os.PathLike | None = None
            ) -> tuple[State, list[dict]]:
    """Apply ``recipe`` to ``mesh`` in memory; returns the final state and step reports.

    ``out_dir`` receives what animate steps write (required when the recipe animates).
    """
    rec = load_recipe(recipe)
    state = State(surface=mesh)
    rngs = np.random.default_rng(seed).spawn(len(rec.steps))
    reports = []
    for step, rng in track(list(zip(rec.steps, rngs, strict=True)), "amplifying",
                           total=len(rec.steps)):
        before = state.counts()
        t0 = time.perf_counter()
        info = EXECUTORS[step.kind](state, step, rng, recipe=rec, out_dir=out_dir)
        reports.append({"index": step.index, "kind": step.kind, "params": step.params,
                        "before": before, "after": state.counts(),
                        "seconds": time.perf_counter() - t0, **info})
        log.info("step %d %s: %s -> %s", step.index, step.kind, before, state.counts())
    return state, reports


def run(mesh_path: str | os.PathLike, recipe, out_dir: str | os.PathLike, *,
        seed: int | None = 0, up=None, turntable: int = 0) -> Path:
    """Amplify the mesh file ``mesh_path`` with ``recipe`` into ``out_dir``.

    Parameters
    ----------
    mesh_path : path
        A mesh file with triangles (PLY, OBJ, ...).
    recipe : str, path, dict or Recipe
        A shipped recipe name (:func:`recipe_names`), a TOML file, or a parsed table.
    out_dir : path
        Replaced atomically.
    seed : int, optional
        Seeds every step (each step draws from its own spawned generator). ``None``: the
        recipe's ``seed`` field, else 0. Same seed, same mesh bytes.
    up : (3,) float, optional
        Up in the mesh's frame. None: estimated (:func:`reconstruct.surface.up.estimate_up`) from
        a camera model beside the mesh, else from the mesh. The steps run with up along
        +z (plants stand along up, snow falls against it, terrain is a heightfield over
        it) and the results are written back in the mesh's own frame; ``report.json``
        says which up was used and where it came from.
    turntable : int
        Frames of a turntable animation of the result (``turntable.mp4``; 0: none).

    Returns
    -------
    Path
        ``out_dir``, holding ``mesh.ply`` (the final mesh) and ``report.json``.

    Raises
    ------
    core.validate.InputError
        A bad recipe (naming the file and field) or an unreadable mesh.
    """
    t_start = time.perf_counter()
    rec = load_recipe(recipe)
    mesh = read_mesh(mesh_path)
    if len(mesh.triangles) == 0:
        raise InputError("expected a mesh with triangles, got 0 triangles", path=mesh_path)
    if seed is None:
        seed = rec.seed if rec.seed is not None else 0
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed: expected an integer >= 0, got {seed!r}")
    v, f = mesh_arrays(mesh)
    from core.frames import rigid, rotation_between
    from core.meshes import make_mesh, transform_mesh
    from reconstruct.surface.up import estimate_up, find_camera_model, orient_winding

    cameras = find_camera_model(mesh_path) if up is None else None
    up_est = estimate_up(v, f, up=up, cameras=cameras)
    f, reversed_winding = orient_winding(v, f, up_est.up)  # steps read normals: ground up
    if reversed_winding:
        log.info("the mesh's triangles face down at its ground: their winding is reversed")
    to_upright = rotation_between(up_est.up, [0.0, 0.0, 1.0])  # the smallest turn
    log.info("up %s from %s (%s)", np.round(up_est.up, 3).tolist(), up_est.source,
             up_est.detail)
    mesh = make_mesh(v @ to_upright.T, f)
    out_dir = Path(out_dir)
    r = rec.render
    view = dict(width=r["width"], height=r["height"], elevation_deg=r["elevation_deg"],
                azimuth_deg=r["azimuth_deg"], fov_deg=r["fov_deg"])
    import open3d as o3d

    from core.io.mesh import write_labeled_mesh
    from scanamp.amplify.labels import LABELS, labelled_arrays, part_material, surface_parts
    from scanamp.amplify.scene_export import write_scene
    from scanamp.amplify.views import render_parts

    with atomic_dir(out_dir) as tmp:
        write_image(tmp / "before.png", render_parts(surface_parts(mesh)[1], **view))
        state, steps = amplify(mesh, rec, seed=int(seed), out_dir=tmp)
        back = to_upright.T  # +z -> the mesh's own up
        fv, ff, colors, labels = labelled_arrays(state.surface, state.parts)
        final = make_mesh(fv @ back.T, ff)
        write_labeled_mesh(tmp / "mesh.ply", fv @ back.T, ff, colors=colors, labels=labels,
                           names=LABELS)
        final.vertex_colors = o3d.utility.Vector3dVector(colors)
        write_mesh(tmp / "mesh.gltf", final)
        files = ["mesh.ply", "labels.json", "mesh.gltf"]
        if state.parts or state.parts_unmerged:
            write_mesh(tmp / "surface.ply", transform_mesh(state.surface, rigid(back)))
            files.append("surface.ply")
            used = set()
            for name, m, _ in state.parts + state.parts_unmerged:
                base, k = name, 2
                while name in used:
                    name, k = f"{base}_{k}", k + 1
                used.add(name)
                write_mesh(tmp / f"{name}.ply", transform_mesh(m, rigid(back)))
                files.append(f"{name}.ply")
        after = surface_parts(state.surface)[1] + [(m, c, part_material(n)) for n, m, c in
                                                   state.parts + state.parts_unmerged]
        write_image(tmp / "after.png", render_parts(after, **view))
        files += ["before.png", "after.png", "scene.toml", "parts"]
        scene_from_upright = write_scene(tmp, fv, ff, colors, labels, LABELS)
        if turntable > 0:
            from scanamp.amplify.views import turntable as spin

            spin(after, tmp / "turntable.mp4", frames=int(turntable),
                 elevation_deg=r["elevation_deg"], fov_deg=r["fov_deg"])
            files.append("turntable.mp4")
        files += [s["animation"] for s in steps if s.get("animation")]
        report = {
            "format": "scanamp.amplify/1",
            "recipe": rec.name,
            "recipe_path": None if rec.path is None else str(rec.path),
            "mesh": str(mesh_path),
            "seed": int(seed),
            "up": up_est.to_dict(),
            "winding_reversed": bool(reversed_winding),
            "upright_from_mesh": to_upright.tolist(),
            "scene_from_mesh": (scene_from_upright @ rigid(to_upright)).tolist(),
            "input": _counts(mesh),
            "output": _counts(final),
            "surface": _counts(state.surface),
            "parts": {name: _counts(m) for name, m, _ in state.parts},
            "steps": steps,
            "files": files + ["report.json"],
            "total_seconds": time.perf_counter() - t_start,
        }
        write_json(tmp / "report.json", report)
    log.info("amplified %s with %s -> %s", mesh_path, rec.name, out_dir)
    return out_dir


def run_variants(mesh_path: str | os.PathLike, recipe, out_dir: str | os.PathLike, *,
                 seeds, up=None, turntable: int = 0) -> Path:
    """One amplified result per seed in ``out_dir/seed_N/`` (each as :func:`run` writes
    it) and ``contact_sheet.png``: every result's after view, labelled by its seed."""
    from scanamp.amplify.views import contact_sheet

    seeds = [int(s) for s in seeds]
    if not seeds or len(set(seeds)) != len(seeds):
        raise ValueError(f"seeds: expected distinct seeds, got {seeds}")
    with atomic_dir(out_dir) as tmp:
        for s in track(seeds, "variants", total=len(seeds)):
            run(mesh_path, recipe, tmp / f"seed_{s}", seed=s, up=up, turntable=turntable)
        sheet = contact_sheet([tmp / f"seed_{s}" / "after.png" for s in seeds],
                              [f"seed {s}" for s in seeds])
        write_image(tmp / "contact_sheet.png", sheet)
    log.info("%d variants of %s -> %s", len(seeds), mesh_path, out_dir)
    return Path(out_dir)
