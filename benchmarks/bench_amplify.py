"""Amplification recipe matrix (issue 19): every shipped recipe on

1. the demo's laser, stereo and SfM reconstructions (``scanamp demo`` is run into the
   bench folder first, unless it is there);
2. our own dense mesh of the monstree phone photos (benchmarks/bench_mvs.py writes it to
   ``$MVS_BENCH_DIR/monstree_patchmatch``; skipped with a note when absent);
3. the demo scene's true surface under a random rotation, at scales 0.01 and 100.

Targets: 0 failures; the size of what a recipe adds, relative to the input's diagonal,
the same within 5 % at both scales; each recipe at most 15 s on a ~200k-triangle
reconstruction (the monstree mesh decimated to 200k triangles; the stereo reconstruction,
154k, when monstree is absent), 2 cores.

"Added size": the 95th percentile of the distance from the output's vertices to the input
surface, over the input's bounding-box diagonal (how far the recipe reaches out).

Usage: ``python benchmarks/bench_amplify.py`` (``AMPLIFY_BENCH_DIR`` keeps the outputs).
"""

import json
import os
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
def _shipped() -> tuple[str, ...]:
    from scanamp.amplify import recipe_names

    return tuple(recipe_names())


RECIPES = _shipped()   # every shipped recipe


def _added_size(out: Path, inp_v, inp_f, up) -> float:
    import open3d as o3d

    from core.io.mesh import read_mesh
    from core.meshes import bbox_diagonal

    rs = o3d.t.geometry.RaycastingScene()
    tm = o3d.t.geometry.TriangleMesh()
    tm.vertex.positions = o3d.core.Tensor(inp_v.astype(np.float32))
    tm.triangle.indices = o3d.core.Tensor(inp_f.astype(np.int32))
    rs.add_triangles(tm)
    v = np.asarray(read_mesh(out / "mesh.ply").vertices)
    d = rs.compute_distance(o3d.core.Tensor(v.astype(np.float32))).numpy()
    return float(np.percentile(d, 95) / bbox_diagonal(inp_v))


def _matrix(label: str, mesh_path: Path, work: Path, rows: list, *, up=None):
    from core.io.mesh import read_mesh
    from core.meshes import mesh_arrays
    from scanamp.amplify import run

    v, f = mesh_arrays(read_mesh(mesh_path))
    for r in RECIPES:
        out = work / f"{label}_{r}"
        t = time.perf_counter()
        try:
            run(mesh_path, r, out, seed=0, up=up)
            ok, err = True, ""
        except Exception as exc:  # a failure is a row of the table, not the end of the run
            ok, err = False, f"{type(exc).__name__}: {exc}"
        sec = time.perf_counter() - t
        row = {"input": label, "recipe": r, "ok": ok, "seconds": sec, "triangles": len(f),
               "error": err}
        if ok:
            rep = json.loads((out / "report.json").read_text())
            row["up_source"] = rep["up"]["source"]
            row["added"] = _added_size(out, v, f, up)
            row["output_triangles"] = rep["output"]["triangles"]
        rows.append(row)
        print(f"   | {label} | {r} | {'ok' if ok else 'FAIL'} | {sec:.1f} | "
              f"{row.get('added', float('nan')):.4f} | {row.get('up_source', '-')} | "
              f"{err[:80]} |", flush=True)


def _demo(work: Path) -> Path:
    demo = work / "demo"
    if not (demo / "recon" / "stereo" / "mesh.ply").is_file():
        from scanamp.cli import main

        assert main(["-q", "demo", "--out", str(demo)]) == 0
    return demo


def _rotated_scene(work: Path, scale: float) -> Path:
    from scipy.spatial.transform import Rotation

    from core.io.mesh import write_mesh
    from core.meshes import make_mesh, mesh_arrays
    from data_synth.scenes import build_scene

    v, f = mesh_arrays(build_scene("demo").gt_mesh())
    R = Rotation.random(random_state=7).as_matrix()
    path = work / f"scene_x{scale:g}" / "mesh.ply"
    path.parent.mkdir(parents=True, exist_ok=True)
    write_mesh(path, make_mesh(scale * v @ R.T, f))
    return path


def _decimated(src: Path, work: Path, n: int = 200_000) -> Path:
    import shutil

    from core.io.mesh import read_mesh, write_mesh

    m = read_mesh(src).simplify_quadric_decimation(n)
    folder = work / "monstree200k"
    folder.mkdir(exist_ok=True)
    for extra in ("transforms.json",):  # the cameras beside it, for up
        if (src.parent / extra).is_file():
            shutil.copy(src.parent / extra, folder / extra)
    return write_mesh(folder / "mesh.ply", m)


def main():
    keep = os.environ.get("AMPLIFY_BENCH_DIR")
    tmp = None if keep else tempfile.TemporaryDirectory(prefix="bench-amplify-")
    work = Path(keep or tmp.name)
    work.mkdir(parents=True, exist_ok=True)
    rows = []
    print("   | input | recipe | ok | seconds | added / diagonal (P95) | up from | error |")
    print("   |---|---|---|---|---|---|---|")
    demo = _demo(work)
    for m in ("laser", "stereo", "sfm"):
        _matrix(m, demo / "recon" / m / "mesh.ply", work, rows)
    mvs = Path(os.environ.get("MVS_BENCH_DIR", "/nonexistent")) / "monstree_patchmatch"
    timed = "stereo"
    if (mvs / "mesh.ply").is_file():
        _matrix("monstree", mvs / "mesh.ply", work, rows)
        _matrix("monstree200k", _decimated(mvs / "mesh.ply", work), work, rows)
        timed = "monstree200k"
    else:
        print("   monstree: no dense mesh (run bench_mvs with MVS_BENCH_DIR set); skipped")
    for scale in (0.01, 100.0):
        _matrix(f"scene_x{scale:g}", _rotated_scene(work, scale), work, rows)
    fails = [r for r in rows if not r["ok"]]
    print(f"   failures: {len(fails)} of {len(rows)} (target 0) "
          f"{'PASS' if not fails else 'MISS'}")
    by = {(r["input"], r["recipe"]): r for r in rows}
    worst = 0.0
    for r in RECIPES:
        a, b = by.get(("scene_x0.01", r)), by.get(("scene_x100", r))
        if a and b and a["ok"] and b["ok"] and max(a["added"], b["added"]) > 0:
            rel = abs(a["added"] - b["added"]) / max(a["added"], b["added"])
            worst = max(worst, rel)
            print(f"   scale 0.01 vs 100, {r}: added {a['added']:.4f} vs {b['added']:.4f} "
                  f"({100 * rel:.1f} %)")
    print(f"   worst added-size difference across scales: {100 * worst:.1f} % (target <= 5 %) "
          f"{'PASS' if worst <= 0.05 else 'MISS'}")
    slow = max((r["seconds"] for r in rows if r["input"] == timed and r["ok"]), default=0)
    tri = next((r["triangles"] for r in rows if r["input"] == timed), 0)
    print(f"   slowest recipe on {timed} ({tri} triangles): {slow:.1f} s (target <= 15 s) "
          f"{'PASS' if slow <= 15 else 'MISS'}")
    (work / "matrix.json").write_text(json.dumps(rows, indent=1))
    if tmp is not None:
        tmp.cleanup()
    return 0


if __name__ == "__main__":
    sys.exit(main())
