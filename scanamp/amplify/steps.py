"""The step executors of an amplification recipe (one function per step kind).

Each takes the :class:`State`, the validated :class:`~scanamp.amplify.recipe.Step`, a
generator, and returns a dict of facts for the report.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from procgen.amplify._surface import bbox_diagonal, edge_lengths
from procgen.meshes import mesh_arrays

__all__ = ["State", "EXECUTORS"]


@dataclass
class State:
    """The mesh being amplified: the surface and the parts planted on it.

    Attributes
    ----------
    surface : open3d.geometry.TriangleMesh
    parts : list of (name, mesh, rgb)
        Added geometry (plants, vines), kept apart so renders can colour it.
    """

    surface: object
    parts: list = field(default_factory=list)

    def counts(self) -> dict:
        out = {"vertices": len(self.surface.vertices), "triangles": len(self.surface.triangles)}
        for _, m, _ in self.parts:
            out["vertices"] += len(m.vertices)
            out["triangles"] += len(m.triangles)
        return out

    def merged(self):
        from procgen.meshes import merge_meshes

        if not self.parts:
            return self.surface
        return merge_meshes([self.surface] + [m for _, m, _ in self.parts])

    def add_part(self, base: str, mesh, color) -> str:
        names = {n for n, _, _ in self.parts}
        name, k = base, 2
        while name in names:
            name, k = f"{base}_{k}", k + 1
        self.parts.append((name, mesh, tuple(color)))
        return name


def _displace(state: State, step, rng, **_):
    from procgen.amplify import displace

    p = step.params
    v, f = mesh_arrays(state.surface)
    mean_edge = float(edge_lengths(v, f).mean())
    res = displace(state.surface, rng=rng, target_edge=p["edge"] * mean_edge,
                   noise=p["noise"], amplitude=p["amplitude"], scale=p["scale"],
                   wavelength=p["wavelength"], octaves=p["octaves"], mask=p["mask"],
                   mask_range=tuple(p["mask_range"]), invert_mask=p["invert_mask"],
                   max_triangles=p["max_triangles"])
    state.surface = res.mesh
    return {"input_mean_edge": mean_edge, "target_edge": p["edge"] * mean_edge,
            "subdivision_levels": res.levels, "max_edge": res.max_edge,
            "rms_offset_relative": res.rms_relative,
            "masked_fraction": float(np.mean(res.mask < 1e-12))}


def _not_yet(state, step, rng, **_):
    raise NotImplementedError(f"step kind {step.kind!r} is not implemented yet")


EXECUTORS = {
    "displace": _displace,
    "refine-terrain": _not_yet,
    "scatter": _not_yet,
    "sweep": _not_yet,
    "hypertexture": _not_yet,
    "animate": _not_yet,
}

_ = bbox_diagonal
