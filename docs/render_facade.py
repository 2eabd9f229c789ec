"""The facade figure of docs/amplify.md: a facade whose largest plane is its wall
(``data_synth.facades.facade_mesh``, seed 1, at a random rotation), subdivided three times
(so that the mesh clean step sees a long open boundary, as on a real reconstruction, and
closes only small holes), through ``scanamp amplify --recipe forest``; before and after
side by side.

Usage: ``python docs/render_facade.py [WORK_DIR] [OUT_PNG]`` (default OUT_PNG:
docs/img/amplify_facade.png).
"""

import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv):
    import numpy as np
    import open3d as o3d

    from core.io.image import read_image, write_image
    from data_synth.facades import facade_mesh
    from scanamp.amplify import run

    work = Path(argv[0]) if argv else Path(tempfile.mkdtemp(prefix="facade_"))
    out = Path(argv[1]) if len(argv) > 1 else ROOT / "docs" / "img" / "amplify_facade.png"
    v, f, up = facade_mesh(np.random.default_rng(1), width=24, height=13, ground_depth=6,
                           floors=4, bays=7)
    mesh = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(v),
                                     o3d.utility.Vector3iVector(f)).subdivide_midpoint(3)
    mesh.compute_vertex_normals()
    work.mkdir(parents=True, exist_ok=True)
    o3d.io.write_triangle_mesh(str(work / "facade.ply"), mesh)
    amp = run(work / "facade.ply", "forest", work / "amp", seed=0)
    pair = np.hstack([read_image(amp / "before.png"), read_image(amp / "after.png")])
    write_image(out, pair)
    sys.stdout.write(f"true up {np.round(up, 3).tolist()}; wrote {out}\n")


if __name__ == "__main__":
    main(sys.argv[1:])
