"""The step executors of an amplification recipe (one function per step kind).

Each takes the :class:`State`, the validated :class:`~scanamp.amplify.recipe.Step`, a
generator, and returns a dict of facts for the report.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from core.meshes import bbox_diagonal, edge_lengths, mesh_arrays, submesh

__all__ = ["State", "EXECUTORS"]


@dataclass
class State:
    """The mesh being amplified: the surface and the parts planted on it.

    Attributes
    ----------
    surface : open3d.geometry.TriangleMesh
    parts : list of (name, mesh, rgb)
        Added geometry (plants, vines), kept apart so renders can colour it; part of the
        final mesh and of animation colliders.
    parts_unmerged : list of (name, mesh, rgb)
        Added geometry written to its own file only (``merge = false``).
    """

    surface: object
    parts: list = field(default_factory=list)
    parts_unmerged: list = field(default_factory=list)

    def counts(self) -> dict:
        out = {"vertices": len(self.surface.vertices), "triangles": len(self.surface.triangles)}
        for _, m, _ in self.parts:
            out["vertices"] += len(m.vertices)
            out["triangles"] += len(m.triangles)
        return out

    def merged(self):
        from core.meshes import merge_meshes

        if not self.parts:
            return self.surface
        return merge_meshes([self.surface] + [m for _, m, _ in self.parts])

    def place(self, base: str, mesh, color, merge: bool) -> str | None:
        """Add ``mesh`` (None: nothing) as a part, merged into the final mesh or in its
        own file only; the part's name when merged."""
        if mesh is None:
            return None
        if merge:
            return self.add_part(base, mesh, color)
        self.parts_unmerged.append((base, mesh, tuple(color)))
        return None

    def add_part(self, base: str, mesh, color) -> str:
        names = {n for n, _, _ in self.parts}
        name, k = base, 2
        while name in names:
            name, k = f"{base}_{k}", k + 1
        self.parts.append((name, mesh, tuple(color)))
        return name


def _clean(state: State, step, rng, **_):
    from reconstruct.surface.clean import CleanOptions, clean_mesh

    state.surface, report = clean_mesh(state.surface, CleanOptions(**step.params))
    return report


def _displace(state: State, step, rng, **_):
    from procgen.amplify import displace

    p = step.params
    v, f = mesh_arrays(state.surface)
    mean_edge = float(edge_lengths(v, f).mean())
    target = p["edge"] * mean_edge if p["edge"] > 0 else None
    res = displace(state.surface, rng=rng, target_edge=target,
                   noise=p["noise"], amplitude=p["amplitude"], scale=p["scale"],
                   wavelength=p["wavelength"], octaves=p["octaves"], hurst=p["hurst"],
                   mask=p["mask"],
                   mask_range=tuple(p["mask_range"]), invert_mask=p["invert_mask"],
                   max_triangles=p["max_triangles"])
    state.surface = res.mesh
    return {"input_mean_edge": mean_edge, "target_edge_asked": target,
            "target_edge": res.target_edge,
            "subdivision_levels": res.levels, "max_edge": res.max_edge,
            "rms_offset_relative": res.rms_relative,
            "masked_fraction": float(np.mean(res.mask < 1e-12))}


def _refine_terrain(state: State, step, rng, **_):
    from core.meshes import merge_meshes
    from procgen.amplify import refine_terrain
    from reconstruct.surface.ground import ground_mask

    p = step.params
    v, f = mesh_arrays(state.surface)
    on_ground = ground_mask(v, f)[f].sum(axis=1) >= 2
    keep = p["objects"] == "keep" and on_ground.any() and not on_ground.all()
    ground = submesh(v, f[on_ground]) if keep else state.surface
    res = refine_terrain(ground, rng=rng, control_size=p["control_size"],
                         levels=p["levels"], hurst=p["hurst"], sigma=p["sigma"],
                         trim=p["trim"], erosion=p["erosion"])
    state.surface = merge_meshes([res.mesh, submesh(v, f[~on_ground])]) if keep else res.mesh
    return {"control_shape": list(res.control.shape), "fine_shape": list(res.heights.shape),
            "control_hit_fraction": float(res.valid.mean()), "fine_spacing": res.spacing,
            "object_triangles_kept": int((~on_ground).sum()) if keep else 0}


def _scatter(state: State, step, rng, *, recipe=None, **_):
    from procgen.amplify import scatter_plants
    from scanamp.amplify.recipe import species_list

    p = step.params
    v, _ = mesh_arrays(state.surface)
    diag = bbox_diagonal(v)
    grammar = p["grammar"] if recipe is None else recipe.resolve(p["grammar"])
    density = p["density"] / diag ** 2 if p["density_unit"] == "diagonal" else p["density"]
    species = [s if not s.endswith(".toml") or recipe is None else recipe.resolve(s)
               for s in species_list(p["species"])]
    res = scatter_plants(state.surface, rng=rng, grammar=grammar, density=density,
                         height=p["height"] * diag, height_jitter=p["height_jitter"],
                         slope_max_deg=p["slope_max_deg"],
                         altitude_range=tuple(p["altitude_range"]), variants=p["variants"],
                         steps=p["steps"], sides=p["sides"], max_plants=p["max_plants"],
                         upright=p["upright"], min_plants=p["min_plants"],
                         leaves=p["leaves"], leaf_size=p["leaf_size"], species=species)
    names = []
    if res.mesh is not None:   # bark and leaves as two parts, so each keeps its label
        v, f = mesh_arrays(res.mesh)
        on_leaf = res.leaf[f].all(axis=1)
        for kind, sel, color in (("bark", ~on_leaf, p["bark_color"]),
                                 ("leaf", on_leaf, p["color"])):
            if sel.any():
                names.append(state.place(kind, submesh(v, f[sel]), color, p["merge"]))
    return {"plants": len(res.positions), "candidates": res.candidates,
            "density_per_m2": density,
            "eligible_area": res.eligible_area, "truncated": res.truncated,
            "plant_height_mean": float(res.heights.mean()) if len(res.heights) else 0.0,
            "species": species,
            "parts": [n for n in names if n is not None]}


def _sweep(state: State, step, rng, **_):
    from procgen.amplify import grow_vines

    p = step.params
    v, _ = mesh_arrays(state.surface)
    diag = bbox_diagonal(v)
    length, stp = p["length"] * diag, p["step"] * diag
    leaf = p["leaf_size"] * diag
    res = grow_vines(state.surface, rng=rng, count=p["count"], length=length,
                     step=min(stp, length), radius=p["radius"] * diag,
                     wander_deg=p["wander_deg"], slope_max_deg=p["slope_max_deg"],
                     slope_min_deg=p["slope_min_deg"], climb=p["climb"],
                     sides=p["sides"], taper=p["taper"], branches=p["branches"] / diag,
                     leaf_size=leaf,
                     leaf_spacing=p["leaf_spacing"] * diag if p["leaf_spacing"] > 0 else None)
    facts = {"vines": len(res.paths) - res.shoots, "shoots": res.shoots, "length": length,
             "radius": p["radius"] * diag}
    if leaf > 0:   # stems and leaves as two parts, so each keeps its label
        vv, ff = mesh_arrays(res.mesh)
        on_leaf = res.leaf[ff].all(axis=1)
        facts["part"] = state.place("vines", submesh(vv, ff[~on_leaf]), p["color"], p["merge"])
        facts["leaf_part"] = state.place("leaf", submesh(vv, ff[on_leaf]), p["leaf_color"],
                                         p["merge"])
        facts["leaves"] = res.leaves
    else:
        facts["part"] = state.place("vines", res.mesh, p["color"], p["merge"])
    return facts


def _snow(state: State, step, rng, **_):
    from procgen.amplify.snow import snow_cover

    p = step.params
    v, _ = mesh_arrays(state.surface)
    depth = p["depth"] * bbox_diagonal(v)
    res = snow_cover(state.surface, rng=rng, depth=depth, slope_max_deg=p["slope_max_deg"],
                     drift=p["drift"])
    name = state.place("snow", res.mesh, p["color"], p["merge"])
    return {"depth_m": depth, "covered_fraction": res.covered_fraction,
            "sky_fraction": float(res.sky.mean()), "part": name}


def _hypertexture(state: State, step, rng, **_):
    from procgen.amplify import hypertexture_mesh

    p = step.params
    v, _ = mesh_arrays(state.surface)
    diag = bbox_diagonal(v)
    res = hypertexture_mesh(state.surface, rng=rng, noise=p["noise"],
                            amplitude=p["amplitude"] * diag, frequency=p["frequency"] / diag,
                            octaves=p["octaves"], resolution=p["resolution"], bias=p["bias"],
                            gain=p["gain"])
    state.surface = res.mesh
    return {"voxel": res.voxel, "amplitude_m": p["amplitude"] * diag, "inside": res.inside}


def _city(state: State, step, rng, **_):
    from procgen.amplify.city_layout import lay_city
    from procgen.city import CityConfig
    from reconstruct.surface.ground import ground_mask

    p = step.params
    v, f = mesh_arrays(state.surface)
    on_ground = ground_mask(v, f)[f].sum(axis=1) >= 2
    if not on_ground.any():
        raise ValueError("surface: no ground found to lay a city on")
    cfg = CityConfig(size=p["size"], centres=p["centres"], parks=p["parks"],
                     river_width=p["river_width"], max_segments=p["max_segments"])
    lay = lay_city(v, f[on_ground], rng=rng, config=cfg, object_v=v,
                   object_f=f[~on_ground], max_slope_deg=p["max_slope_deg"],
                   road_step=p["road_step"])
    parts = [state.place(kind, mesh, p[f"{kind}_color"], True)
             for kind, mesh in (("road", lay.roads), ("building", lay.walls),
                                ("roof", lay.roofs))]
    return {"road_segments": len(lay.city.edges), "road_segments_laid": lay.roads_kept,
            "buildings": len(lay.city.buildings), "buildings_laid": lay.buildings_kept,
            "units_per_city_metre": lay.scale, "road_lift": lay.lift,
            "parts": [n for n in parts if n is not None]}


def _fit(mesh, simulation: str, size: float):
    """Move and scale ``mesh`` into a simulation recipe's frame; returns (mesh, 4x4)."""
    import copy

    v, _ = mesh_arrays(mesh)
    lo, hi = v.min(axis=0), v.max(axis=0)
    T = np.eye(4)
    if simulation == "boids":   # centred on the origin, bounding half-diagonal = size
        c = 0.5 * (lo + hi)
        s = size / max(0.5 * float(np.linalg.norm(hi - lo)), 1e-12)
    else:                       # standing on z = 0, centred in x, y, half-width = size
        c = np.array([0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), lo[2]])
        s = size / max(0.5 * float(np.max(hi[:2] - lo[:2])), 1e-12)
    T[:3, :3] *= s
    T[:3, 3] = -s * c
    out = copy.deepcopy(mesh)
    out.transform(T)
    return out, T


def _animate(state: State, step, rng, *, recipe=None, out_dir=None, **_):
    import dataclasses
    from pathlib import Path

    from core.files import read_json, scratch_dir
    from core.io.mesh import write_mesh
    from procgen.implicit import watertight

    if out_dir is None:
        raise ValueError("out_dir: an animate step needs an output folder")
    p = step.params
    sim = p["simulation"]
    sub = p["recipe"] if recipe is None else recipe.resolve(p["recipe"])
    out_dir = Path(out_dir)
    name, k = "animation", 2
    while (out_dir / name).exists():
        name, k = f"animation_{k}", k + 1
    seed = int(rng.integers(0, 2 ** 31 - 1))
    mesh = state.merged()
    # the simulations need an inside: an open reconstruction collides as its thin shell
    solid, shell = watertight(mesh, resolution=p["collider_resolution"])
    if sim == "boids":
        from scanamp.animation.boids import run_boids
        from simulate.boids import load_recipe as load_boids

        r = load_boids(sub)
        changes = {"seed": seed}
        if p["frames"] is not None:
            changes["steps"] = p["frames"]
        if p["n"] is not None:
            changes["n"] = p["n"]
        r = dataclasses.replace(r, **changes)
        size = p["size"] if p["size"] is not None else r.obstacle_size
        collider, T = (_fit(solid, sim, size) if p["fit"] else (solid, np.eye(4)))
        run_boids(r, out_dir / name, mesh=collider, render=p["render"], width=p["width"],
                  height=p["height"])
    else:
        from scanamp.animation.simulation import run_simulation

        size = p["size"] if p["size"] is not None else 0.6
        collider, T = (_fit(solid, sim, size) if p["fit"] else (solid, np.eye(4)))
        with scratch_dir(out_dir) as td:
            mesh_path = write_mesh(td / "collider.ply", collider)
            run_simulation(sim, sub, out_dir / name, mesh_path=mesh_path,
                           frames=p["frames"], render=p["render"], width=p["width"],
                           height=p["height"], seed=seed)
    sub_report = read_json(out_dir / name / "report.json")
    keys = ("status", "frames", "n", "steps", "particles_born", "particles_alive", "escapes",
            "impacts", "final", "animation")
    shown = _last_frame(state, sim, out_dir / name, np.linalg.inv(T), mesh)
    return {"animation": name, "simulation": sim, "sub_recipe": str(sub), "seed": seed,
            "sim_from_mesh": T.tolist(), "last_frame_part": shown,
            "collider": {"closed_input": shell == 0.0, "shell_half_width": shell,
                         "triangles": len(solid.triangles)},
            "result": {key: sub_report[key] for key in keys if key in sub_report}}


def _last_frame(state: State, sim: str, folder, mesh_from_sim: np.ndarray, mesh):
    """What the animation ends with, as a part of the result in the mesh's frame: the
    draped cloth of the last frame (merged), or the boids of the frame that has the most
    of them about the mesh, as small tetrahedra (their own file and the after view).
    Particles leave no geometry. Returns the part's name."""
    import glob

    from core.meshes import make_mesh

    if sim == "cloth":
        plys = sorted(glob.glob(str(folder / "ply" / "frame_*.ply")))
        if not plys:
            return None
        from core.io.mesh import read_mesh

        cloth = read_mesh(plys[-1])
        cloth.transform(mesh_from_sim)
        return state.place("cloth", cloth, (0.75, 0.25, 0.22), True)
    if sim != "boids":
        return None
    vtps = sorted(glob.glob(str(folder / "frames" / "frame_*.vtp")))
    if not vtps:
        return None
    import pyvista as pv

    v, _ = mesh_arrays(mesh)
    lo, hi = v.min(0), v.max(0)
    pad = 0.5 * (hi - lo)
    best = (0, None, None)
    for path in vtps:  # the frame with the most boids about the mesh (the latest on ties)
        pts = (np.asarray(pv.read(path).points, float) @ mesh_from_sim[:3, :3].T
               + mesh_from_sim[:3, 3])
        near = np.all((pts >= lo - pad) & (pts <= hi + pad), axis=1)
        if near.sum() >= best[0]:
            best = (int(near.sum()), pts, near)
    count, pts, near = best
    if count == 0:
        return None
    size = 0.01 * bbox_diagonal(v)
    tet = size * np.array([[1, 0, 0], [-0.5, 0.8, 0], [-0.5, -0.8, 0], [0, 0, 1.2]])
    faces = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]])
    verts = (pts[near][:, None, :] + tet[None]).reshape(-1, 3)
    tris = (faces[None] + 4 * np.arange(int(near.sum()))[:, None, None]).reshape(-1, 3)
    state.place("boids", make_mesh(verts, tris), (0.15, 0.2, 0.3), False)
    return "boids"


EXECUTORS = {
    "clean": _clean,
    "displace": _displace,
    "refine-terrain": _refine_terrain,
    "scatter": _scatter,
    "sweep": _sweep,
    "snow": _snow,
    "hypertexture": _hypertexture,
    "city": _city,
    "animate": _animate,
}
