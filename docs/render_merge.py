"""Figures of docs/scans.md's merging section: the Stanford dragon's 15 range scans on their
published poses, before and after the volumetric merge.

    python docs/render_merge.py [DRAGON_FOLDER]

writes ``docs/img/scans_merge_dragon.png``: the posed scans, each in its colour | the
merged surface (``fill_holes``), the triangles that close holes in orange | the same seen
from below, where the stand hid the dragon from every scan. The folder defaults to
``../shared/data/real/dragon_stand``.
"""

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
PALETTE = np.array([[0.90, 0.33, 0.31], [0.30, 0.60, 0.85], [0.45, 0.75, 0.40],
                    [0.95, 0.70, 0.25], [0.60, 0.45, 0.80], [0.35, 0.80, 0.80],
                    [0.85, 0.50, 0.70], [0.65, 0.65, 0.30], [0.40, 0.45, 0.70],
                    [0.80, 0.60, 0.45], [0.50, 0.80, 0.60], [0.75, 0.35, 0.50],
                    [0.55, 0.70, 0.90], [0.90, 0.85, 0.45], [0.45, 0.55, 0.45]])


def draw(meshes, colours, world_from_cam, *, size=(420, 560), fov_deg=30.0,
         light=(0.3, -0.5, -1.0)):
    """Meshes seen from a pinhole camera: per-triangle colours x Lambert shading."""
    import open3d as o3d

    H, W = size
    scene = o3d.t.geometry.RaycastingScene()
    for m in meshes:
        scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(m))
    f = 0.5 * W / np.tan(np.radians(fov_deg) / 2)
    jj, ii = np.meshgrid(np.arange(W), np.arange(H))
    d = np.stack([(jj - W / 2) / f, (ii - H / 2) / f, np.ones((H, W))], -1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    R, o = world_from_cam[:3, :3], world_from_cam[:3, 3]
    rays = np.concatenate([np.broadcast_to(o, d.shape), d @ R.T], -1).astype(np.float32)
    hit = scene.cast_rays(o3d.core.Tensor(rays.reshape(-1, 6)))
    ok = np.isfinite(hit["t_hit"].numpy()).reshape(H, W)
    geo = np.where(ok.ravel(), hit["geometry_ids"].numpy(), 0)
    prim = np.where(ok.ravel(), hit["primitive_ids"].numpy(), 0)
    rgb = np.stack([colours[g][p] for g, p in zip(geo, prim, strict=True)]).reshape(H, W, 3)
    n = hit["primitive_normals"].numpy().reshape(H, W, 3)
    L = np.asarray(light) / np.linalg.norm(light)
    shade = 0.3 + 0.7 * np.abs(n @ (R @ L))
    img = np.where(ok[..., None], rgb * shade[..., None], 1.0)
    return (255 * np.clip(img, 0, 1)).astype(np.uint8)


def look_at(eye, target, up=(0.0, 1.0, 0.0)):
    z = np.asarray(target, float) - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.stack([x, np.cross(z, x), z], axis=1)
    T[:3, 3] = eye
    return T


def main(folder: Path):
    from core.io.image import write_image
    from core.io.range import read_conf
    from core.meshes import make_mesh
    from reconstruct.scans import load_scans
    from reconstruct.surface.volumetric import MergeOptions, merge_scans

    conf = [(f, T) for f, T in read_conf(folder / "dragonStandRight.conf") if f.endswith(".ply")]
    scans = load_scans([folder / f for f, _ in conf])
    poses = [T for _, T in conf]
    posed = [make_mesh(s.points @ T[:3, :3].T + T[:3, 3], s.triangles)
             for s, T in zip(scans, poses, strict=True)]
    merged, _ = merge_scans(scans, poses, MergeOptions(fill_holes=True))
    filled = np.asarray(merged.triangle_material_ids) == 1
    grey, orange = np.array([0.78, 0.78, 0.76]), np.array([0.95, 0.55, 0.15])
    merged_colours = [np.where(filled[:, None], orange, grey)]
    centre = np.asarray(merged.get_axis_aligned_bounding_box().get_center())
    front = look_at(centre + np.array([0.0, 0.05, 0.55]), centre)
    below = look_at(centre + np.array([0.25, -0.45, 0.25]), centre)
    scan_colours = [np.broadcast_to(PALETTE[k % len(PALETTE)], (len(m.triangles), 3))
                    for k, m in enumerate(posed)]
    panels = [draw(posed, scan_colours, front), draw([merged], merged_colours, front),
              draw([merged], merged_colours, below)]
    out = ROOT / "docs" / "img" / "scans_merge_dragon.png"
    write_image(out, np.concatenate(panels, axis=1))
    sys.stdout.write(f"{out}\n")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else
         ROOT.parents[1] / "shared" / "data" / "real" / "dragon_stand")
