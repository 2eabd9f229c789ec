"""A stand of Weber & Penn trees by instancing: a few grown individuals a species, each
placed many times turned about its stem and scaled to the height asked.

A forest of hundreds of trees then holds only its templates (leaf cards by default) and
one 4x4 ``world_from_tree`` a tree; :meth:`Stand.mesh` builds the whole stand's mesh when
a caller needs the triangles.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from core.validate import check_array, check_rng
from procgen.weber_penn.appearance import TreeMesh, tree_mesh
from procgen.weber_penn.growth import grow
from procgen.weber_penn.params import load_species

__all__ = ["Stand", "grow_stand"]


@dataclass
class Stand:
    """``templates`` (TreeMesh, grown at ``template_height`` m), ``template`` (n,) which one
    each tree uses, ``world_from_tree`` (n, 4, 4)."""

    templates: list
    template_height: np.ndarray
    template: np.ndarray
    world_from_tree: np.ndarray

    def nbytes(self) -> int:
        """Memory held by the stand's arrays (bytes)."""
        t = sum(m.vertices.nbytes + m.triangles.nbytes + m.colors.nbytes + m.labels.nbytes
                for m in self.templates)
        return t + self.template.nbytes + self.world_from_tree.nbytes

    def mesh(self) -> TreeMesh:
        """Every tree of the stand as one mesh (filled in place: no per-tree copies)."""
        nv = np.array([len(m.vertices) for m in self.templates])[self.template]
        nt = np.array([len(m.triangles) for m in self.templates])[self.template]
        v0 = np.concatenate([[0], np.cumsum(nv)])
        t0 = np.concatenate([[0], np.cumsum(nt)])
        V = np.empty((v0[-1], 3))
        T = np.empty((t0[-1], 3), np.int64)
        C = np.empty((v0[-1], 3))
        L = np.empty(v0[-1], np.int64)
        for i, (k, M) in enumerate(zip(self.template, self.world_from_tree, strict=True)):
            m = self.templates[k]
            vs, ts = slice(v0[i], v0[i + 1]), slice(t0[i], t0[i + 1])
            x = m.vertices  # x R^T + t, column by column (a 3x3 matmul is slower)
            V[vs] = x[:, :1] * M[:3, 0] + x[:, 1:2] * M[:3, 1] + x[:, 2:3] * M[:3, 2] + M[:3, 3]
            np.add(m.triangles, v0[i], out=T[ts])
            C[vs] = m.colors
            L[vs] = m.labels
        return TreeMesh(V, T, C, L)


def grow_stand(species, positions, heights, *, rng: np.random.Generator, variants: int = 4,
               lod: str = "cards", season: str = "summer") -> Stand:
    """Trees of ``species`` (a name a tree, or one for all) at ``positions`` (n, 3) with
    ``heights`` (n,) metres, from ``variants`` individuals a species."""
    rng = check_rng(rng)
    pos = check_array(positions, "positions", shape=(None, 3), finite=True)
    h = check_array(heights, "heights", shape=(len(pos),), finite=True)
    if np.any(h <= 0):
        raise ValueError("heights: expected positive heights in metres")
    names = [species] * len(pos) if isinstance(species, str) else list(species)
    if len(names) != len(pos):
        raise ValueError(f"species: expected {len(pos)} names, got {len(names)}")
    kinds = sorted(set(names))
    templates, theights, index = [], [], {}
    for name in kinds:
        params = load_species(name)
        sel = np.array([nm == name for nm in names])
        ref = float(np.median(h[sel]))
        for v in range(variants):
            t = grow(params, height=ref, rng=rng)
            index[(name, v)] = len(templates)
            templates.append(tree_mesh(t, rng=rng, season=season, lod=lod))
            theights.append(ref)
    which = np.array([index[(nm, int(rng.integers(variants)))] for nm in names])
    s = h / np.array(theights)[which]
    yaw = rng.uniform(0, 2 * np.pi, len(pos))
    M = np.zeros((len(pos), 4, 4))
    c, sn = np.cos(yaw) * s, np.sin(yaw) * s
    M[:, 0, 0], M[:, 0, 1], M[:, 1, 0], M[:, 1, 1] = c, -sn, sn, c
    M[:, 2, 2] = s
    M[:, :3, 3] = pos
    M[:, 3, 3] = 1
    return Stand(templates, np.array(theights), which, M)
