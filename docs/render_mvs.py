"""Figures of docs/sfm.md from a ``make bench`` run's MVS outputs (bench_mvs.py):

    python docs/render_mvs.py BENCH_MVS_DIR

writes ``docs/img/mvs_monstree.png`` and ``docs/img/mvs_dino.png`` (photo | mesh drawn
from that photo's camera, shaded, in its colours | a second view) and
``docs/img/mvs_depth.png`` (a photo beside its depth, normal and confidence maps), and
``docs/img/mvs_columns.png`` (the rendered scene of thin columns and steps: a render and
the mesh from two of its cameras), and ``docs/img/mvs_strecha_SET.png`` for each Strecha
set that ``bench_mvs.py strecha`` reconstructed from its true cameras (a photo and the
mesh from two of the benchmark's cameras).
"""

import json
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def draw(mesh, cam, light=(0.3, -0.4, -1.0)):
    """The mesh seen by ``cam``: vertex colours x Lambert shading, white background."""
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(mesh))
    rays = o3d.t.geometry.RaycastingScene.create_rays_pinhole(
        o3d.core.Tensor(cam.K), o3d.core.Tensor(cam.cam_from_world), cam.width, cam.height)
    hit = scene.cast_rays(rays)
    ok = np.isfinite(hit["t_hit"].numpy())
    prim = hit["primitive_ids"].numpy()
    uv = hit["primitive_uvs"].numpy()
    tri = np.asarray(mesh.triangles)
    col = np.asarray(mesh.vertex_colors) if mesh.has_vertex_colors() else \
        np.full((len(mesh.vertices), 3), 0.8)
    f = tri[np.where(ok, prim, 0)]
    w = np.stack([1 - uv[..., 0] - uv[..., 1], uv[..., 0], uv[..., 1]], -1)
    rgb = np.einsum("hwk,hwkc->hwc", w, col[f])
    n = hit["primitive_normals"].numpy()
    L = np.asarray(light) / np.linalg.norm(light)
    R = cam.world_from_cam[:3, :3]
    shade = 0.35 + 0.65 * np.abs(n @ (R @ L))
    img = np.where(ok[..., None], rgb * shade[..., None], 1.0)
    return (255 * np.clip(img, 0, 1)).astype(np.uint8)


def _fit(img, h):
    import cv2

    return cv2.resize(img, (round(img.shape[1] * h / img.shape[0]), h),
                      interpolation=cv2.INTER_AREA)


def figure(rec: Path, images: Path, names, out: Path, h=360):
    import pycolmap

    from core.io.image import read_image, write_image
    from core.io.mesh import read_mesh
    from reconstruct.camera_files import camera_from_colmap, image_cam_from_world

    mesh = read_mesh(rec / "mesh.ply")
    report = json.loads((rec / "report.json").read_text())
    # a mesh written in the scene's frame (renders with ground truth) is drawn from the
    # model's cameras carried there by the evaluation's Sim(3), its scale taken out
    sfm_from_scene, scale = np.eye(4), 1.0
    if str(report.get("frame", "")).startswith("scene") and "alignment_scene_from_sfm" in report:
        a = np.asarray(report["alignment_scene_from_sfm"], float)
        sfm_from_scene, scale = np.linalg.inv(a), float(np.cbrt(np.linalg.det(a[:3, :3])))
    model = pycolmap.Reconstruction(str(rec / "sparse" / "0"))
    by = {im.name: im for im in model.images.values()}
    tiles = []
    for i, name in enumerate(names):
        cam = camera_from_colmap(by[name].camera, image_cam_from_world(by[name]))
        cam_from_scene = cam.cam_from_world @ sfm_from_scene
        cam_from_scene[:3] *= scale  # a rotation again; the same pixels
        cam = cam.__class__(cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy,
                            np.zeros(5), cam_from_scene)
        if i == 0:
            photo = read_image(images / name)
            tiles.append(_fit(photo if photo.ndim == 3 else np.dstack([photo] * 3), h))
        tiles.append(_fit(draw(mesh, cam), h))
    write_image(out, np.hstack(tiles))


def depth_figure(rec: Path, images: Path, name: str, out: Path, h=360):
    from core.io.image import read_image, write_image

    photo = read_image(images / name)
    prev = read_image(rec / "dense" / f"{name}.preview.png")
    write_image(out, np.hstack([_fit(photo, h), _fit(prev, h)]))


def main(bench: Path):
    img = ROOT / "docs" / "img"
    img.mkdir(exist_ok=True)
    real = Path(os.environ.get("SCANAMP_REAL_DATA") or ROOT.parent / "shared" / "data" / "real")
    mt = bench / "monstree_patchmatch"
    if (mt / "mesh.ply").is_file():
        views = list(json.loads((mt / "report.json").read_text())["dense"]["views"])
        figure(mt, real / "monstree" / "images", [views[0], views[len(views) // 2]],
               img / "mvs_monstree.png")
        depth_figure(mt, real / "monstree" / "images", views[0], img / "mvs_depth.png")
    dino = bench / "dino_patchmatch"
    if (dino / "mesh.ply").is_file():
        figure(dino, real / "dinoSparseRing" / "images", ["dinoSR0001.png", "dinoSR0005.png",
                                                          "dinoSR0011.png"],
               img / "mvs_dino.png")
    cols = bench / "columns"
    if (cols / "mesh.ply").is_file():
        # a capture folder's views are named by their path in it
        names = sorted(f"images/{p.name}" for p in (bench / "columns24" / "images").glob("*.png"))
        figure(cols, bench / "columns24", [names[0], names[len(names) // 3]],
               img / "mvs_columns.png")
    for name in ("fountain-P11", "Herz-Jesu-P8", "entry-P10"):
        rec = bench / f"strecha_{name}"
        if (rec / "mesh.ply").is_file():
            views = sorted(json.loads((rec / "report.json").read_text())["dense"]["views"])
            figure(rec, real / "strecha" / name / "images",
                   [views[len(views) // 2], views[0]], img / f"mvs_strecha_{name}.png", h=200)


if __name__ == "__main__":
    main(Path(sys.argv[1]))
