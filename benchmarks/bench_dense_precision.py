"""Which dense stage puts surface outside the object: the fuse and mesh stages re-run on
the same depth maps with one stage switched at a time, scored against silhouettes.

    python benchmarks/bench_dense_precision.py temple|dino DIR

DIR is a reconstruction from true cameras with the default options that
`bench_mvs.py temple` or `dino` wrote (`temple_cameras`, `temple_turntable`,
`dino_patchmatch`; MVS_BENCH_DIR keeps them; the temple's capture is the input folder's
parent): its depth maps are
reused, only fusion and the surface run again. For each variant: the mesh's pixels inside
the silhouettes (the temple's true ones, the dino's by a threshold on its black
background), the silhouettes covered, and the truth-free precision the dense stage
reports. A bar chart goes to docs/img/mvs_precision_stages.png with --plot.
"""

import json
import os
import sys
from pathlib import Path

os.environ.setdefault("NUMBA_THREADING_LAYER", "omp")
import cv2  # noqa: E402,F401  (before pycolmap)
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_mvs import REAL, SIL_THRESHOLD, temple_scores  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

# one stage switched at a time, against the defaults
VARIANTS = {
    "defaults": {},
    "unseen trim off": {"unseen_views": 0},
    "unseen trim 3 views": {"unseen_views": 3},
    "fusion: 2 views agree": {"min_views": 2},
    "density trim 20 %": {"density_quantile": 0.2},
    "free space: every depth": {"free_space": "all"},
    "static match 6 px": {"static_match": 6.0},
}


def _scores(kind: str, out: Path, cap: Path | None):
    from core.io.image import read_image
    from core.io.mesh import read_mesh
    from reconstruct.camera_files import read_cameras
    from reconstruct.evaluation.masks import mask_scores

    if kind == "temple":
        return temple_scores(cap, out / "mesh.ply")
    base = REAL / "dinoSparseRing"
    imgs = sorted((base / "images").glob("*.png"))
    cams = read_cameras(base / "dinoSR_par.txt", sizes={p.name: (640, 480) for p in imgs})
    names = sorted(cams)
    masks = [read_image(base / "images" / n, grayscale=True) > SIL_THRESHOLD for n in names]
    sc = mask_scores(read_mesh(out / "mesh.ply"), [cams[n] for n in names], masks, dilate=2)
    return sc.mean_inside, sc.mean_covers


def main():
    from reconstruct.mvs.fusion import FusionOptions
    from reconstruct.sfm.pipeline import SfmConfig, run

    kind, out = sys.argv[1], Path(sys.argv[2])
    rep = json.loads((out / "report.json").read_text())
    inp = Path(rep["input"])
    cap = inp.parent if kind == "temple" else None
    rows = {}
    for name, change in VARIANTS.items():
        c = SfmConfig(cameras=rep["cameras_file"])
        c.mvs.fusion = FusionOptions(**change)
        res = run(c, inp, out, from_stage="fuse")
        inside, covers = _scores(kind, out, cap)
        seen = res.report["dense"].get("seen_precision", {}).get("mean", float("nan"))
        rows[name] = (inside, covers, seen, res.report["dense"]["triangles"])
        print(f"   {kind} {name:>24}: inside {inside:.4f}, covers {covers:.4f}, "
              f"precision (truth-free) {seen:.4f}, {rows[name][3]} triangles", flush=True)
    if "--plot" in sys.argv:
        _plot(kind, rows)
    return 0


def _plot(kind, rows):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(rows)
    x = np.arange(len(names))
    fig, ax = plt.subplots(figsize=(8, 3.2))
    for k, (label, off) in enumerate((("inside the silhouettes", -0.27),
                                      ("silhouettes covered", 0.0),
                                      ("precision (truth-free)", 0.27))):
        ax.bar(x + off, [rows[n][k] for n in names], 0.27, label=label)
    ax.set_xticks(x, names, rotation=20, fontsize=8)
    ax.set_ylim(0.6, 1.0)
    ax.set_title(f"{kind}: one stage switched at a time (same depth maps)")
    ax.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    fig.savefig(ROOT / "docs" / "img" / f"mvs_precision_{kind}.png", dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
