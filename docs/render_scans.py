"""Figure of docs/scans.md: range scans placed by their true poses, coloured by scan.

    python docs/render_scans.py [CAPTURE_DIR] [DRAGON_DIR]

CAPTURE_DIR is a ``scanamp capture scans`` output (default: captured here, 12 views of
``object``); DRAGON_DIR the Stanford dragon's range images with their ``.conf`` (default
``../shared/data/real/dragon_stand``, skipped when absent). Writes
``docs/img/scans_true_poses.png``: each scan's own triangulation (``load_scans``) placed by
``poses.json`` / the published ``.conf``, one colour per scan, drawn from two sides.
"""

import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "docs"))

DRAGON = Path(__file__).resolve().parents[2] / "shared" / "data" / "real" / "dragon_stand"


def placed_mesh(scans, poses):
    """One open3d mesh of ``scans`` placed by ``poses`` (name -> model_from_scan), each scan
    in its own colour."""
    import matplotlib
    import open3d as o3d

    cmap = matplotlib.colormaps["tab20"]
    verts, tris, cols, base = [], [], [], 0
    for i, s in enumerate(scans):
        T = poses[s.name]
        verts.append(s.points @ T[:3, :3].T + T[:3, 3])
        tris.append(s.triangles + base)
        cols.append(np.tile(cmap(i % 20)[:3], (len(s.points), 1)))
        base += len(s.points)
    mesh = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(np.vstack(verts)),
                                     o3d.utility.Vector3iVector(np.vstack(tris)))
    mesh.vertex_colors = o3d.utility.Vector3dVector(np.vstack(cols))
    return mesh


def views(mesh, eyes, up, size=(420, 360)):
    """The mesh drawn from ``eyes`` (offsets from its centre, in its diagonals)."""
    from render_mvs import draw

    from acquire.camera import Camera

    v = np.asarray(mesh.vertices)
    c = 0.5 * (v.min(0) + v.max(0))
    diag = float(np.linalg.norm(v.max(0) - v.min(0)))
    return [draw(mesh, Camera.look_at(c + 0.75 * diag * np.asarray(e), c, up=up, width=size[0],
                                      height=size[1], fov_deg=40)) for e in eyes]


def main(argv):
    from core.io.image import write_image
    from core.io.range import read_conf, read_poses_json
    from reconstruct.scans import load_scans

    cap = Path(argv[0]) if argv else None
    if cap is None:
        import numpy.random as npr

        from acquire.scans import ScansCaptureConfig, capture_scans
        from data_synth.scenes import build_scene

        cap = Path(tempfile.mkdtemp()) / "scans"
        bundle = build_scene("object")
        capture_scans(bundle.render_scene, ScansCaptureConfig(), cap, npr.default_rng(0))
    poses = {Path(p.file).name: p.model_from_scan for p in read_poses_json(cap / "poses.json")}
    rows = [np.hstack(views(placed_mesh(load_scans(cap), poses),
                            [(1.0, -1.2, 0.9), (-1.0, 1.2, 0.5)], up=(0, 0, 1)))]
    dragon = Path(argv[1]) if len(argv) > 1 else DRAGON
    if dragon.is_dir():
        conf = next(dragon.glob("*.conf"))
        poses = {name: T for name, T in read_conf(conf)}
        scans = load_scans(dragon)
        rows.append(np.hstack(views(placed_mesh(scans, poses),
                                    [(0.2, 0.3, 1.6), (-0.5, 0.3, -1.5)], up=(0, 1, 0))))
    out = ROOT / "docs" / "img" / "scans_true_poses.png"
    write_image(out, np.vstack(rows))


if __name__ == "__main__":
    main(sys.argv[1:])
