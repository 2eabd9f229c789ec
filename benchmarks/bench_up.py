"""Up on any reconstruction, from the mesh alone, without trusting the winding: the
project's scenes (whole, and as a capture from above sees them), facades (whole, and as
a street-level capture sees them) and the real Stanford dragon (its 15 range scans,
triangulated on their grids and posed by the published .conf; up +y in the model frame),
each with its winding as written and reversed, under 5 random rotations.

Target: within 10 degrees on every one.
"""

import os
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from core.meshes import mesh_arrays
from data_synth.facades import facade_mesh
from data_synth.fixtures import ring_of_eyes, seen_triangles
from data_synth.scenes import build_scene, scene_names
from reconstruct.surface.up import up_from_mesh

# the real data beside the repository (``../shared/data/real``), or where SCANAMP_REAL_DATA says
REAL = Path(os.environ.get("SCANAMP_REAL_DATA",
                           Path(__file__).resolve().parents[2] / "shared" / "data" / "real"))
DRAGON = REAL / "dragon_stand" / "dragonStandRight.conf"
Z = np.array([0.0, 0.0, 1.0])


def _dragon():
    from core.io.range import conf_files, read_conf, read_range_grid
    from reconstruct.scans.scan import scan_from_grid

    entries = [(name, T) for name, T in read_conf(DRAGON)  # the .conf names one scan more
               if (DRAGON.parent / name).is_file()
               or (DRAGON.parent / f"{name}.ply").is_file()]
    vs, fs, n = [], [], 0
    for path, T in conf_files(DRAGON, entries):
        s = scan_from_grid(read_range_grid(path))
        vs.append(s.points @ T[:3, :3].T + T[:3, 3])
        fs.append(np.asarray(s.triangles, np.int64) + n)
        n += len(s.points)
    return np.vstack(vs), np.vstack(fs), np.array([0.0, 1.0, 0.0])


def _cases(only=None):
    if only == "dragon":
        yield "Stanford dragon, 15 real scans", *_dragon()
        return
    for name in scene_names():
        v, f = mesh_arrays(build_scene(name).gt_mesh())
        if len(f) < 1_000_000:
            yield name, v, f, Z
        eyes = ring_of_eyes(v, 16, (15.0, 50.0))
        yield f"{name} (seen from above)", v, seen_triangles(v, f, eyes), Z
    for seed in range(6):
        rng = np.random.default_rng(seed)
        v, f, up = facade_mesh(rng, width=rng.uniform(12, 30), height=rng.uniform(9, 15),
                               ground_depth=rng.uniform(3, 6),
                               floors=int(rng.integers(3, 5)), bays=int(rng.integers(4, 8)),
                               rotate=False)
        yield f"facade {seed}", v, f, up
        lo, hi = v.min(0), v.max(0)
        xs = np.linspace(lo[0], hi[0], 6)
        eyes = np.concatenate([np.stack([xs, np.full(6, lo[1] - 8.0), np.full(6, z)], 1)
                               for z in (1.7, 6.0)])
        yield (f"facade {seed} (from the street)", v,
               seen_triangles(v, f, eyes, target=0.5 * (lo + hi), fov_deg=90), up)
    if DRAGON.is_file():
        yield "Stanford dragon, 15 real scans", *_dragon()
    else:
        print(f"   {DRAGON} not present: the real dragon is skipped")
    yield from _own_meshes()


def _own_meshes():
    """This project's meshes of real photo sets, kept by bench_mvs (``.cache/bench/up``)
    with their true up; none until bench_mvs has run on the real sets."""
    import json

    from core.io.mesh import read_mesh

    keep = Path(__file__).resolve().parents[1] / ".cache" / "bench" / "up"
    found = sorted(keep.glob("*.json")) if keep.is_dir() else []
    if not found:
        print(f"   no mesh of a real photo set in {keep} (bench_mvs keeps them): skipped")
    for meta in found:
        m = read_mesh(meta.with_suffix(".ply"))
        info = json.loads(meta.read_text())
        yield (info["label"], np.asarray(m.vertices, np.float64),
               np.asarray(m.triangles, np.int64), np.asarray(info["up"], np.float64))


def main():
    import logging

    logging.getLogger("reconstruct.surface.up").setLevel(logging.ERROR)  # close calls
    worst_all, total, bad = 0.0, 0, 0
    import sys

    for name, v, f, up in _cases(sys.argv[1] if len(sys.argv) > 1 else None):
        errs, margins, t = [], [], time.perf_counter()
        for seed in range(5):
            R = Rotation.random(random_state=seed).as_matrix()
            for tris in (f, f[:, ::-1]):
                est = up_from_mesh(v @ R.T, tris)
                errs.append(np.degrees(np.arccos(np.clip(est.up @ (R @ up), -1, 1))))
                margins.append(est.decision["confidence"])
        dt = (time.perf_counter() - t) / len(errs)
        worst = max(errs)
        worst_all = max(worst_all, worst)
        total += len(errs)
        bad += sum(e > 10 for e in errs)
        print(f"   {name:<38} {len(f):>8} triangles: worst {worst:5.1f} deg, median "
              f"{np.median(errs):4.1f}, confidence {min(margins):.2f}-{max(margins):.2f}, "
              f"{dt:.2f} s each", flush=True)
    print(f"   up within 10 deg: {total - bad}/{total} (worst {worst_all:.1f} deg) "
          f"{'PASS' if bad == 0 else 'MISS'}")


if __name__ == "__main__":
    main()
