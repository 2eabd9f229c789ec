"""Contact sheets of the recipe matrix (docs/amplify.md): for each input, the cleaned
input's before view and every shipped recipe's after view.

Usage: ``python docs/render_amplify.py BENCH_DIR [OUT_DIR]`` where BENCH_DIR is the
``AMPLIFY_BENCH_DIR`` of ``benchmarks/bench_amplify.py`` (default OUT_DIR: docs/img).
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main(argv):
    from core.io.image import write_image
    from scanamp.amplify import recipe_names
    from scanamp.amplify.views import contact_sheet

    RECIPES = recipe_names()  # noqa: N806 - every shipped recipe

    bench = Path(argv[0])
    out = Path(argv[1]) if len(argv) > 1 else Path(__file__).parent / "img"
    for name in ("laser", "stereo", "sfm", "monstree"):
        runs = [(r, bench / f"{name}_{r}") for r in RECIPES]
        runs = [(r, d) for r, d in runs if (d / "after.png").is_file()]
        if not runs:
            continue
        images = [runs[0][1] / "before.png"] + [d / "after.png" for _, d in runs]
        captions = [f"{name}: input"] + [r for r, _ in runs]
        path = out / f"amplify_{name}.png"
        write_image(path, contact_sheet(images, captions, columns=5, width=300))
        sys.stdout.write(f"{path}\n")


if __name__ == "__main__":
    main(sys.argv[1:])
