"""Figures and the table of the ``lidar-ground`` study (docs/lidar.md).

    scanamp study lidar-ground --out OUT --workers 2
    python docs/render_lidar_ground.py OUT

Reads the study's run records (``OUT/runs/*.json``), prints its table (markdown) and
draws ``docs/img/lidar_ground_study.png``: total error and DTM RMSE against the mean
slope asked, one line per density / understory / species mix.
"""

import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

KEYS = ("forest.slope", "forest.density", "forest.understory", "forest.species")


def load(out: Path) -> list[dict]:
    rows = []
    for f in sorted((out / "runs").glob("*.json")):
        d = json.loads(f.read_text())
        if not d.get("metrics"):
            continue
        rows.append({**{k: d["params"][k] for k in KEYS}, **d["metrics"]})
    return rows


def main(out: Path) -> None:
    rows = load(out)
    rows.sort(key=lambda r: tuple(str(r[k]) if k == "forest.species" else r[k] for k in KEYS))
    print("| slope (deg) | measured mean slope | trees/ha | shrubs/ha | species "  # noqa: T201
          "| type I % | type II % | total % | DTM RMSE m | tree F |")
    print("|---|---|---|---|---|---|---|---|---|---|")  # noqa: T201
    for r in rows:
        print(f"| {r['forest.slope']:g} | "  # noqa: T201
              f"{r['terrain.mean_slope_deg']:.1f} | "
              f"{r['forest.density']:g} | {r['forest.understory']:g} | "
              f"{r['forest.species']} | {100 * r['ground.type_i']:.2f} | "
              f"{100 * r['ground.type_ii']:.2f} | {100 * r['ground.total']:.2f} | "
              f"{r['dtm.rmse']:.3f} | {r['trees.f']:.3f} |")
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.5))
    groups = sorted({tuple(r[k] for k in KEYS[1:]) for r in rows}, key=str)
    for g in groups:
        sel = sorted((r for r in rows if tuple(r[k] for k in KEYS[1:]) == g),
                     key=lambda r: r["forest.slope"])
        x = [r["forest.slope"] for r in sel]
        label = f"{g[0]:g} trees/ha, {g[1]:g} shrubs/ha, {g[2]}"
        ax[0].plot(x, [100 * r["ground.total"] for r in sel], "o-", label=label)
        ax[1].plot(x, [r["dtm.rmse"] for r in sel], "o-", label=label)
        ax[2].plot(x, [r["trees.f"] for r in sel], "o-", label=label)
    ax[0].axhline(3.0, color="k", ls=":", lw=1)
    ax[1].plot([0, 35, 35, 45], [0.15, 0.15, 0.30, 0.30], "k:", lw=1)
    ax[2].axhline(0.75, color="k", ls=":", lw=1)
    for a, t in zip(ax, ("ground total error (%)", "DTM RMSE vs true terrain (m)",
                         "tree detection F"), strict=True):
        a.set_xlabel("mean slope asked (deg)")
        a.set_title(t)
        a.grid(alpha=0.3)
    ax[2].legend(fontsize=6)
    fig.tight_layout()
    dst = Path(__file__).resolve().parent / "img" / "lidar_ground_study.png"
    fig.savefig(dst, dpi=90)
    print(f"\nwrote {dst}")  # noqa: T201


if __name__ == "__main__":
    main(Path(sys.argv[1]))
