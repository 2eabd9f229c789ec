"""Multi-view stereo: PatchMatch (the dense stage) against rectified-pair SGBM (the stage
it replaced), side by side on the same inputs, in one run.

1. Renders: the SfM capture of the 'object' scene (24 views at 640x480, as in
   bench_sfm). Targets: dense mesh F at tau = 1 % of the scene >= 0.97; the dense stage
   <= 80 s (it was 239 s); F at 0.5 % too.
2. Columns: the SfM capture of the 'columns' scene (thin textured columns on steps,
   24 views at 640x480). Targets: the dense mesh's recall at 1 % of the scene diagonal
   >= 0.95 and precision >= 0.97.
3. monstree (../shared/data/real/monstree/images: 23 phone photos, 2016x1512, 19 of them
   portrait by their EXIF orientation): all 23 registered; >= 60 % of the pixels of every
   registered view carry a fused depth; dense stage <= 1.2x the sparse stage (issue 32); megapixel-
   views per second on this machine.
4. dinoSparseRing from its given cameras (--cameras dinoSR_par.txt): silhouettes by a
   threshold on the black background, dilated 2 px. Of the mesh drawn into every view
   >= 97 % of the pixels fall inside the silhouette, and it covers >= 94.5 % of the
   silhouette pixels.
5. temple: the white temple of thin columns on black (16 views on a ring, 640x480, faint
   texture, noisy backdrop), from its bare capture and from its true cameras, against its
   true silhouettes: inside >= 0.97 and covered >= 0.85 (the targets of the real ring of
   the kind kept aside); P and R against the true surface at 1 %. Then the same from its
   true cameras as a turntable photographs it: a dim textured cloth behind the object at
   the same pixels in every view (data_synth.fixtures.turntable_backdrop), the trait of a
   real capture that makes the kept-aside ring's loss (docs/sfm.md). Not in the default
   list (three dense runs); name it.

Every dense line also prints the precision (truth-free): the mesh drawn into every view,
the share of its pixels on the view's own fused pixels (reconstruct.mvs.precision).

The real sets are read from ../shared/data/real when it is there; otherwise those parts
say so and are skipped (a fresh clone has no ../shared). SGBM runs beside PatchMatch only
with MVS_BENCH_PEERS=1 (the peers reuse PatchMatch's sparse stages). With MVS_BENCH_DIR
the captures and the unchanged stages of an earlier run there are reused (MVS_BENCH_FROM=dense
forces the dense stage and the later ones, after a change of code).
"""

import os
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")
import cv2  # noqa: E402,F401  (before pycolmap)
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
REAL = Path(os.environ.get("SCANAMP_REAL_DATA") or ROOT.parent / "shared" / "data" / "real")
SIL_THRESHOLD = 30  # grey level (of 255) separating the dino from its black background


def _check(name, value, bound, higher=True, fmt="{:.3f}"):
    ok = value >= bound if higher else value <= bound
    print(f"   {name}: {fmt.format(value)} (target {'>=' if higher else '<='} "
          f"{fmt.format(bound)}) {'PASS' if ok else 'MISS'}", flush=True)
    return ok


def _run(config, inp, out):
    from reconstruct.sfm.pipeline import run

    t = time.perf_counter()
    res = run(config, inp, out, from_stage=os.environ.get("MVS_BENCH_FROM") or None)
    rep = res.report
    rep["wall"] = time.perf_counter() - t
    return res, rep


def _config(method, **kw):
    from reconstruct.mvs.pipeline import MvsOptions
    from reconstruct.sfm.pipeline import SfmConfig

    return SfmConfig(mvs=MvsOptions(method=method), **kw)


def _peers(first: Path, inp, methods, **kw):
    """The peers' runs, each from a copy of the first run: only the dense stages run."""
    import shutil

    reps = {}
    if os.environ.get("MVS_BENCH_PEERS") != "1":
        return reps
    for m in methods:
        out = first.parent / f"{first.name}_{m}"
        if not out.is_dir():
            shutil.copytree(first, out)
        try:
            reps[m] = _run(_config(m, **kw), inp, out)[1]
        except Exception as exc:  # the peer failing must not hide our figures
            print(f"   {first.name} {m}: failed: {exc}", flush=True)
    return reps


def _side_by_side(label, reps):
    for method, rep in reps.items():
        d = rep.get("dense", {})
        covs = [v["fused_coverage"] for v in d.get("views", {}).values()] or [0.0]
        m = rep.get("metrics", {}).get("mesh", {})
        f = (f", F@1% {m['fscore']:.3f} (P {m['precision']:.3f}, R {m['recall']:.3f}), "
             f"F@0.5% {m['fscore_half_tau']:.3f}" if m else "")
        ran = ",".join(rep.get("stages", {}).get("ran", []))
        cpu = d.get("depth_maps_cpu_s") or 0.0
        print(f"   {label} {method:>10}: dense {rep['timings'].get('dense', 0):6.1f} s (depth "
              f"maps {d.get('timings', {}).get('depth_maps', 0):6.1f} s, CPU {cpu:6.1f} s), sparse "
              f"{rep['timings'].get('sparse_total', 0):6.1f} s, fused coverage mean "
              f"{np.mean(covs):.2f} min {np.min(covs):.2f}, {_seen(rep)}{f} (stages run: {ran})",
              flush=True)


def renders(root: Path):
    from bench_sfm import _capture

    cap = root / "orbit24"
    if not (cap / "capture.json").is_file():
        cap = _capture(root)
    first = root / "render"
    reps = {"patchmatch": _run(_config("patchmatch"), cap, first)[1]}
    reps.update(_peers(first, cap, ("sgbm",)))
    _side_by_side("renders", reps)
    rep = reps["patchmatch"]
    ok = _check("renders: PatchMatch mesh F at 1 % of the scene",
                rep["metrics"]["mesh"]["fscore"], 0.97)
    if "dense" in rep.get("stages", {}).get("ran", []):
        ok &= _check("renders: dense stage seconds (a shared machine)",
                     rep["timings"]["dense"], 80.0, higher=False, fmt="{:.1f}")
    return ok


def _columns_capture(root: Path) -> Path:
    from acquire.sfm.capture import PathConfig, capture
    from data_synth.scenes import build_scene

    if (root / "columns24" / "capture.json").is_file():
        return root / "columns24"
    bundle = build_scene("columns")
    cfg = PathConfig(kind="orbit", views=24, width=640, height=480)
    return capture(bundle.render_scene, cfg, root / "columns24", rng=np.random.default_rng(0),
                   scene_ref={"name": "columns", "seed": bundle.seed, "path": None},
                   gt_mesh=bundle.gt_mesh(), seed=0)


def columns(root: Path):
    cap = _columns_capture(root)
    res, rep = _run(_config("patchmatch"), cap, root / "columns")
    _side_by_side("columns", {"patchmatch": rep})
    m = rep["metrics"]["mesh"]
    ok = _check("columns: mesh recall at 1 % of the scene diagonal", m["recall"], 0.95)
    return ok & _check("columns: mesh precision at 1 % of the scene diagonal",
                       m["precision"], 0.97)


def monstree(root: Path):
    images = REAL / "monstree" / "images"
    if not images.is_dir():
        print(f"   monstree: {images} not found, skipped (a fresh clone has no ../shared)")
        return True
    reps = {}
    for m in ("patchmatch", "sgbm"):
        try:
            res, reps[m] = _run(_config(m), images, root / f"monstree_{m}")
        except Exception as exc:  # the peer failing must not hide our figures
            print(f"   monstree {m}: failed: {exc}", flush=True)
            if m == "patchmatch":
                return False
            continue
        print(f"   monstree {m}: {res.message}", flush=True)
    _side_by_side("monstree", reps)
    rep = reps["patchmatch"]
    ok = _check("monstree: registered", rep["registered"], 23, fmt="{:.0f}")
    # issue 32: the views fused at 0.70 or more on average; the worst view's 0.60 of the
    # last issue is retired (a view that is mostly far forest: docs/sfm.md), so reported
    cover = [v["fused_coverage"] for v in rep["dense"]["views"].values()]
    ok &= _check("monstree: fused coverage, mean over the views", float(np.mean(cover)), 0.70)
    print(f"   monstree: fused coverage of the worst view {min(cover):.3f} (reported; the "
          f"last issue's 0.60 is retired)")
    ratio = rep["timings"]["dense"] / rep["timings"]["sparse_total"]
    ok &= _check("monstree: dense stage / sparse stage", ratio, 1.2, higher=False,
                 fmt="{:.2f}")
    print(f"   monstree: {rep['dense']['megapixel_views_per_s']:.3f} megapixel-views/s on "
          f"{os.cpu_count()} cores (working size {max(rep['dense']['working_size'].values())})")
    return ok


def silhouette_scores(mesh_path: Path, images: Path, cameras: dict) -> tuple[float, float]:
    """Mean over views of (mesh pixels inside the silhouette, silhouette pixels covered):
    silhouettes by a threshold on the black background, dilated 2 px."""
    from core.io.image import read_image
    from core.io.mesh import read_mesh
    from reconstruct.evaluation.masks import mask_scores

    names = sorted(cameras)
    masks = [read_image(images / n, grayscale=True) > SIL_THRESHOLD for n in names]
    sc = mask_scores(read_mesh(mesh_path), [cameras[n] for n in names], masks, dilate=2)
    return sc.mean_inside, sc.mean_covers


def _seen(rep) -> str:
    sp = rep.get("dense", {}).get("seen_precision")
    return f"precision (truth-free) {sp['mean']:.4f}" if sp else "precision (truth-free) -"


def _temple_capture(root: Path) -> Path:
    """16 views on one ring at 30 degrees, 640x480, of the white temple on black, its
    faint plaster texture kept as the scene has it (no texture boost), a noisy black
    backdrop (read noise 400 e-: 3.4 grey levels rms) and soft optics (0.7 px)."""
    from data_synth.fixtures import sfm_capture

    return sfm_capture(root, scene="temple", views=16, width=640, height=480,
                       elevations_deg=(30.0,), distance_factor=1.3, texture_boost=1.0,
                       read_noise=400.0, blur_sigma=0.7)


def temple_scores(cap: Path, mesh_path: Path) -> tuple[float, float]:
    """(inside, covered) of the mesh against the capture's true silhouettes (its rendered
    depth > 0, dilated 2 px as the dino's), through the true cameras."""
    import json

    from acquire.camera import Camera
    from core.io.mesh import read_mesh
    from reconstruct.evaluation.masks import mask_scores

    gt = json.loads((cap / "capture.json").read_text())["ground_truth"]
    names = sorted(gt["cameras"])
    cams = [Camera.from_dict(gt["cameras"][n]) for n in names]
    masks = [np.load(cap / "gt" / f"depth_{i:04d}.npy") > 0 for i in range(len(names))]
    sc = mask_scores(read_mesh(mesh_path), cams, masks, dilate=2)
    return sc.mean_inside, sc.mean_covers


def temple(root: Path):
    """The white temple from its bare capture, from its true cameras, and from its true
    cameras as a turntable photographs it (a dim cloth at the same pixels of every view):
    inside >= 0.97 and covered >= 0.85 of the true silhouettes (the targets of the real
    ring kept aside), with the mesh's precision and recall against the true surface at 1 %."""
    import json

    from acquire.sfm.nerfstudio import write_transforms
    from data_synth.fixtures import turntable_backdrop

    base = _temple_capture(root)
    gt = json.loads((base / "capture.json").read_text())["ground_truth"]
    ok = True
    for mode in ("bare", "cameras", "turntable"):
        cap = base if mode != "turntable" else turntable_backdrop(
            base, root / "temple16_turntable", rng=np.random.default_rng(1))
        if mode != "bare":
            from acquire.camera import Camera

            names = sorted(gt["cameras"])
            tf = root / "temple16_transforms.json"
            write_transforms(tf, [Camera.from_dict(gt["cameras"][n]) for n in names],
                             [n.split("/")[-1] for n in names])
            res, rep = _run(_config("patchmatch", cameras=str(tf)), cap / "images",
                            root / f"temple_{mode}")
        else:
            res, rep = _run(_config("patchmatch"), cap, root / "temple_bare")
        if not res.ok:
            print(f"   temple {mode}: {res.message}")
            ok = False
            continue
        inside, covers = temple_scores(cap, res.out_dir / "mesh.ply")
        m = rep.get("metrics", {}).get("mesh")
        if m is None:  # from known cameras the folder holds no truth: score it here
            from acquire.camera import Camera
            from core.io.mesh import read_mesh
            from reconstruct.sfm.pipeline import _score_mesh

            names = sorted(gt["cameras"])
            m = _score_mesh(read_mesh(res.out_dir / "mesh.ply"), cap / gt["mesh"],
                            [Camera.from_dict(gt["cameras"][n]) for n in names],
                            gt.get("scene_size"))
        print(f"   temple {mode:>8}: inside {inside:.4f}, covers {covers:.4f}, P "
              f"{m['precision']:.3f} R {m['recall']:.3f} at 1 %, {_seen(rep)}, dense "
              f"{rep['timings']['dense']:.1f} s",
              flush=True)
        ok &= _check(f"temple {mode}: mesh pixels inside the silhouette", inside, 0.97)
        ok &= _check(f"temple {mode}: silhouette pixels covered by the mesh", covers, 0.85)
    return ok


def dino(root: Path):
    from reconstruct.camera_files import read_cameras

    base = REAL / "dinoSparseRing"
    if not (base / "dinoSR_par.txt").is_file():
        print(f"   dinoSparseRing: {base} not found, skipped (a fresh clone has no ../shared)")
        return True
    par = base / "dinoSR_par.txt"
    cams = read_cameras(par, sizes={p.name: (640, 480) for p in (base / "images").glob("*.png")})
    ok = True
    methods = ("patchmatch", "sgbm") if os.environ.get("MVS_BENCH_PEERS") == "1" else (
        "patchmatch",)
    for m in methods:
        res, rep = _run(_config(m, cameras=str(par)), base / "images", root / f"dino_{m}")
        if not res.ok:
            print(f"   dino {m}: {res.message}")
            ok &= m != "patchmatch"
            continue
        inside, covers = silhouette_scores(res.out_dir / "mesh.ply", base / "images", cams)
        print(f"   dino {m:>10}: inside {inside:.4f}, covers {covers:.4f}, {_seen(rep)}, dense "
              f"{rep['timings']['dense']:.1f} s", flush=True)
        if m == "patchmatch":
            ok &= _check("dino: mesh pixels inside the silhouette", inside, 0.97)
            ok &= _check("dino: silhouette pixels covered by the mesh", covers, 0.945)
            _keep_for_up(res.out_dir / "mesh.ply", "dino, our dense mesh from its cameras",
                         cams)
    return ok


STRECHA_SETS = ("fountain-P11", "Herz-Jesu-P8", "entry-P10")


def strecha(root: Path):
    """The Strecha sets from their true cameras: one dense run each, reported (no target
    of its own: the issue asks for the figures and the meshes' renders)."""
    ok = True
    for name in STRECHA_SETS:
        base = REAL / "strecha" / name
        if not (base / "cameras").is_dir():
            print(f"   strecha {name}: {base} not found, skipped (a fresh clone has no "
                  "../shared)")
            continue
        res, rep = _run(_config("patchmatch", cameras=str(base / "cameras")), base / "images",
                        root / f"strecha_{name}")
        if not res.ok:
            print(f"   strecha {name}: {res.message}")
            ok = False
            continue
        d = rep["dense"]
        cov = [v["fused_coverage"] for v in d["views"].values()]
        print(f"   strecha {name:>13}: {len(cov)} views at {max(d['working_size'].values())}, "
              f"dense {rep['timings']['dense']:.1f} s, sparse "
              f"{rep['timings'].get('sparse_total', 0):.1f} s, fused coverage mean "
              f"{np.mean(cov):.3f} min {np.min(cov):.3f}, {_seen(rep)}, "
              f"{d['triangles']} triangles", flush=True)
    return ok


def _keep_for_up(mesh_path: Path, label: str, cams: dict):
    """Keep a mesh of a real photo set for bench_up (``.cache/bench/up/``), with its true
    up: the axis of the ring of cameras (a turntable's), on the side the cameras stand
    above the object."""
    import json
    import shutil

    from core.io.mesh import read_mesh

    centres = np.array([c.center for c in cams.values()])
    axis = np.linalg.svd(centres - centres.mean(0))[2][2]
    centroid = np.asarray(read_mesh(mesh_path).vertices).mean(0)
    axis = axis if axis @ (centres.mean(0) - centroid) > 0 else -axis
    keep = ROOT / ".cache" / "bench" / "up"
    keep.mkdir(parents=True, exist_ok=True)
    name = label.split(",")[0].replace(" ", "_")
    shutil.copyfile(mesh_path, keep / f"{name}.ply")
    (keep / f"{name}.json").write_text(json.dumps({"label": label, "up": axis.tolist()}))


def main():
    root = Path(os.environ.get("MVS_BENCH_DIR") or tempfile.mkdtemp(prefix="bench_mvs_"))
    print(f"   outputs in {root}; real data from {REAL}", flush=True)
    parts = sys.argv[1:] or ["renders", "columns", "monstree", "dino"]
    ok = True
    for name in parts:
        ok &= {"renders": renders, "columns": columns, "monstree": monstree,
               "dino": dino, "temple": temple, "strecha": strecha}[name](root)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
