"""Multi-view stereo and photos as cameras write them: EXIF orientation and focal length,
camera files of other tools, PatchMatch against a plane of known depth, fusion, and the
SfM pipeline on a phone-like folder and from known cameras."""

import dataclasses
import json

import cv2
import numpy as np
import pytest

from acquire.camera import Camera
from core.validate import InputError
from scanamp.cli import main

# -- photos: EXIF orientation and focal length ---------------------------------------------


def _exif_jpeg(path, stored: np.ndarray, orientation: int, f35=None):
    from PIL import Image

    exif = Image.Exif()
    exif[0x0112] = orientation
    if f35 is not None:
        exif.get_ifd(0x8769)[0xA405] = f35
    Image.fromarray(stored).save(path, quality=98, exif=exif)
    return path


@pytest.mark.parametrize("orientation,upright_of", [
    (1, lambda a: a), (3, lambda a: np.rot90(a, 2)), (6, lambda a: np.rot90(a, -1)),
    (8, lambda a: np.rot90(a, 1)), (2, lambda a: a[:, ::-1])])
def test_images_are_read_upright_by_their_exif_orientation(tmp_path, orientation, upright_of):
    from core.io.image import photo_info, read_image

    # blocks of flat colour survive JPEG; the stored pixels are 64 wide, 48 high
    stored = np.zeros((48, 64, 3), np.uint8)
    stored[:24, :32] = (250, 0, 0)
    stored[24:, 32:] = (0, 0, 250)
    path = _exif_jpeg(tmp_path / "p.jpg", stored, orientation, f35=28)
    img = read_image(path)
    want = upright_of(stored)
    assert img.shape == want.shape
    assert np.abs(img.astype(int) - want).mean() < 4  # JPEG noise only
    info = photo_info(path)
    assert (info.width, info.height) == (want.shape[1], want.shape[0])
    assert info.orientation == orientation
    # 35 mm equivalent: f35 x image diagonal / 43.27 mm (the film's diagonal)
    assert info.focal_px == pytest.approx(28 * 80 / np.hypot(36, 24))
    grey = read_image(path, grayscale=True)
    assert grey.shape == want.shape[:2]


def test_truncated_jpeg_and_sixteen_bit_images(tmp_path):
    from core.io.image import photo_info, read_image, to_uint8

    path = _exif_jpeg(tmp_path / "p.jpg", np.full((40, 50, 3), 99, np.uint8), 1)
    data = path.read_bytes()
    (tmp_path / "cut.jpg").write_bytes(data[: len(data) - 40])
    with pytest.raises(InputError, match="cut.jpg: truncated JPEG"):
        read_image(tmp_path / "cut.jpg")
    with pytest.raises(InputError, match="truncated"):
        photo_info(tmp_path / "cut.jpg")
    sixteen = (np.arange(40 * 50, dtype=np.uint16).reshape(40, 50) * 30).astype(np.uint16)
    cv2.imwrite(str(tmp_path / "s.tif"), sixteen)
    got = read_image(tmp_path / "s.tif")
    assert got.dtype == np.uint16 and np.array_equal(got, sixteen)
    assert np.array_equal(to_uint8(got), np.rint(sixteen / 257.0).astype(np.uint8))


def test_camera_groups_by_size_and_focal_length():
    from core.io.image import PhotoInfo
    from reconstruct.sfm.photo_set import camera_groups

    infos = {"a": PhotoInfo(40, 30, 1, 50.0), "b": PhotoInfo(30, 40, 6, 50.0),
             "c": PhotoInfo(40, 30, 1, 50.0), "d": PhotoInfo(40, 30, 1, 70.0)}
    assert [g.names for g in camera_groups(infos, "auto")] == [["a", "c"], ["b"], ["d"]]
    assert [g.names for g in camera_groups(infos, "per-image")] == [["a"], ["b"], ["c"],
                                                                     ["d"]]
    with pytest.raises(ValueError, match="'single' needs one image size.*b \\(30x40\\)"):
        camera_groups(infos, "single")


# -- camera files of other tools -----------------------------------------------------------

def _ring(n=4, w=64, h=48):
    return [Camera(w, h, 70.0 + i, 71.0 + i, 31.0, 24.5, np.zeros(5),
                   Camera.look_at((2 * np.cos(a), 2 * np.sin(a), 0.7), (0, 0, 0)).cam_from_world)
            for i, a in enumerate(np.linspace(0, 2 * np.pi, n, endpoint=False))]


def _num(v) -> str:
    return repr(float(v))


def test_middlebury_transforms_and_colmap_files_give_the_same_cameras(tmp_path):
    from acquire.sfm.nerfstudio import write_transforms
    from reconstruct.camera_files import colmap_params_from_camera, read_cameras

    cams = _ring()
    names = [f"v{i}.png" for i in range(len(cams))]
    sizes = {n: (64, 48) for n in names}
    lines = [str(len(cams))] + [
        " ".join([n, *map(_num, c.K.ravel()), *map(_num, c.cam_from_world[:3, :3].ravel()),
                  *map(_num, c.cam_from_world[:3, 3])])
        for n, c in zip(names, cams, strict=True)]
    (tmp_path / "ring_par.txt").write_text("\n".join(lines) + "\n")
    write_transforms(tmp_path / "transforms.json", cams, names)
    model = tmp_path / "model"
    model.mkdir()
    cam_lines, im_lines = [], []
    from scipy.spatial.transform import Rotation

    for i, (n, c) in enumerate(zip(names, cams, strict=True), start=1):
        m, p = colmap_params_from_camera(c, "PINHOLE")
        cam_lines.append(f"{i} {m} 64 48 {p.replace(',', '')}")
        x, y, z, w = Rotation.from_matrix(c.cam_from_world[:3, :3]).as_quat()
        pose = " ".join(map(_num, (w, x, y, z, *c.cam_from_world[:3, 3])))
        im_lines.append(f"{i} {pose} {i} {n}\n")
    (model / "cameras.txt").write_text("\n".join(cam_lines) + "\n")
    (model / "images.txt").write_text("\n".join(im_lines) + "\n")
    (model / "points3D.txt").write_text("")
    for source in (tmp_path / "ring_par.txt", tmp_path / "transforms.json", model):
        got = read_cameras(source, sizes=sizes)
        assert sorted(got) == names, source
        for n, c in zip(names, cams, strict=True):
            np.testing.assert_allclose(got[n].cam_from_world, c.cam_from_world, atol=1e-9)
            np.testing.assert_allclose(got[n].K, c.K, atol=1e-9)


def test_bad_camera_files_are_named(tmp_path):
    from reconstruct.camera_files import read_cameras

    par = tmp_path / "x_par.txt"
    par.write_text("1\nv0.png 70 0 32 0 70 24 0 0 1 1 0 0 0 1 0 0 0 1 0 0 2\n")
    with pytest.raises(InputError, match="x_par.txt: line 2: image v0.png is not in"):
        read_cameras(par, sizes={"other.png": (64, 48)})
    from acquire.sfm.nerfstudio import write_transforms

    write_transforms(tmp_path / "transforms.json", _ring(1), ["v0.png"])
    with pytest.raises(InputError, match="transforms.json: v0.png: camera of v0.png is 64x48, "
                                         "the image is 640x480"):
        read_cameras(tmp_path / "transforms.json", sizes={"v0.png": (640, 480)})
    par.write_text("1\nv0.png 70 0 32\n")
    with pytest.raises(InputError, match="line 2: expected 'name' and 21 numbers"):
        read_cameras(par, sizes={"v0.png": (64, 48)})


# -- PatchMatch against a textured plane of known depth --------------------------------------

def _plane_views(n=3, w=128, h=96):
    """Views of the textured plane z = 0 (world), rendered exactly by homography."""
    rng = np.random.default_rng(1)
    tex = cv2.GaussianBlur(rng.random((400, 400)).astype(np.float32), (0, 0), 2.0)
    tex = (255 * (tex - tex.min()) / np.ptp(tex)).astype(np.uint8)
    A = np.array([[3.0 / 400, 0, -1.5], [0, 3.0 / 400, -1.5], [0, 0, 1]])  # tex px -> X, Y
    cams, imgs = [], []
    for i in range(n):
        eye = (0.35 * (i - 1), -0.5 + 0.1 * i, 2.0)
        pose = Camera.look_at(eye, (0.05 * i, 0, 0), up=(0, 1, 0)).cam_from_world
        cam = Camera(w, h, 110.0, 110.0, (w - 1) / 2, (h - 1) / 2, np.zeros(5), pose)
        T = cam.cam_from_world
        H = cam.K @ np.column_stack([T[:3, 0], T[:3, 1], T[:3, 3]]) @ A
        imgs.append(cv2.warpPerspective(tex, H, (w, h), flags=cv2.INTER_LINEAR))
        cams.append(cam)
    return cams, imgs


def _true_depth(cam: Camera) -> np.ndarray:
    px = cam.pixel_grid().reshape(-1, 2)
    o, d = cam.rays(px)
    t = -o[:, 2] / d[:, 2]
    X = o + t[:, None] * d
    return cam.to_camera(X)[:, 2].reshape(cam.height, cam.width)


def test_patchmatch_recovers_the_depth_and_normal_of_a_plane():
    from reconstruct.mvs.patchmatch import PatchMatchOptions, depth_range, patchmatch, prepare_views

    cams, imgs = _plane_views()
    pts = np.column_stack([np.random.default_rng(2).uniform(-0.8, 0.8, (60, 2)), np.zeros(60)])
    opt = PatchMatchOptions(max_image_size=128, iterations=4, geom_iterations=1, seed=3)
    views = prepare_views(["a", "b", "c"], imgs, cams, opt.max_image_size)
    for v in views:
        v.depth_range = depth_range(v.camera, pts, np.arange(60), opt.depth_margin)
    maps, timings = patchmatch(views, [[1, 2], [0, 2], [0, 1]], opt)
    assert {"photometric", "geometric"} <= set(timings)
    ref = maps[0]
    truth = _true_depth(views[0].camera)
    inner = np.zeros_like(truth, bool)
    inner[8:-8, 8:-8] = True  # the window needs its radius inside the other views
    good = inner & (ref.depth > 0) & (np.abs(ref.depth - truth) < 0.005 * truth)
    assert good.sum() > 0.8 * inner.sum()
    # the normal of the plane z = 0, in the reference camera's frame, facing the camera
    n_true = views[0].camera.cam_from_world[:3, :3] @ np.array([0, 0, 1.0])
    n_true = -n_true if n_true[2] > 0 else n_true
    cosang = ref.normal[good] @ n_true
    assert np.median(cosang) > np.cos(np.radians(5))
    assert ref.confidence[good].mean() > 0.8 and ref.sources == ["b", "c"]
    # the same seed gives the same bytes; another seed other bytes, the same plane
    again, _ = patchmatch(views, [[1, 2], [0, 2], [0, 1]], opt)
    assert again[0].depth.tobytes() == ref.depth.tobytes()


def _plane_setup(n, opt, junk=()):
    from reconstruct.mvs.patchmatch import depth_range, prepare_views

    cams, imgs = _plane_views(n=n)
    for j in junk:  # a source that sees something else (an occluder): noise
        imgs[j] = np.random.default_rng(j).integers(0, 256, imgs[j].shape, np.uint8)
    pts = np.column_stack([np.random.default_rng(2).uniform(-0.8, 0.8, (60, 2)), np.zeros(60)])
    views = prepare_views([f"v{i}" for i in range(n)], imgs, cams, opt.max_image_size)
    for v in views:
        v.depth_range = depth_range(v.camera, pts, np.arange(60), opt.depth_margin)
    return views


def test_the_interleaved_row_order_visits_every_row_once():
    from reconstruct.mvs._patchmatch_kernels import _row

    for h in (1, 7, 16, 17, 96, 480, 481):
        order = [_row(k, h) for k in range(h)]
        assert sorted(order) == list(range(h)), h
        if h >= 32:  # the first half of the loop (one thread's share) spans the image
            assert max(order[: h // 2]) > 0.9 * h


def test_the_window_cost_agrees_with_a_direct_warp_sample_by_sample():
    """The kernel's cost of a plane (reference window read once, bounds tested at the
    window's four corners) against a direct implementation: each sample warped by the
    full homography K_s (R + t n^T / dp) K_r^-1, tested on its own, sampled bilinearly,
    and the weighted NCC; planes tilted enough that many windows leave the source."""
    from reconstruct.mvs import _patchmatch_kernels as pk
    from reconstruct.mvs.patchmatch import PatchMatchOptions, _relative, homography_parts

    opt = PatchMatchOptions(max_image_size=128)
    ref, src = _plane_setup(2, opt)
    cam, sc = ref.camera, src.camera
    kinv = np.linalg.inv(cam.K)
    R, t = _relative(cam, sc)
    hm = homography_parts(cam.K, sc.K[None], R[None], t[None])
    wts, stats = pk.bilateral_weights(ref.gray, 4, 2, 0.2, 4.0)
    sizes = np.array([[sc.width, sc.height]])
    img = src.gray
    h, w = ref.gray.shape
    win, xs, ys = np.empty(50), np.empty(5, np.int64), np.empty(5, np.int64)
    truth = _true_depth(cam)
    rng = np.random.default_rng(4)
    bad = 0
    for _ in range(400):
        x, y = int(rng.integers(0, w)), int(rng.integers(0, h))
        d = truth[y, x] * rng.uniform(0.7, 1.3)
        ray = kinv @ (x, y, 1.0)
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        n = -n if n @ ray > 0 else n
        pk._window(x, y, ref.gray, wts, 4, 2, win, xs, ys)
        got = pk._view_cost(x, y, d, *n, 0, stats, src.gray[None], sizes, kinv, hm,
                            opt.min_texture ** 2, win, xs, ys)
        H = sc.K @ (R + np.outer(t, n) / (d * (n @ ray))) @ kinv
        samples = []  # (weight, reference grey, source grey); None: off the source
        for k, (yy, xx) in enumerate(np.ndindex(5, 5)):
            yy, xx = min(max(y - 4 + 2 * yy, 0), h - 1), min(max(x - 4 + 2 * xx, 0), w - 1)
            p = H @ (xx, yy, 1.0)
            u, v = p[:2] / p[2]
            if p[2] <= 1e-12 or not (0 <= u <= sc.width - 1.001 and 0 <= v <= sc.height - 1.001):
                samples = None
                break
            x0, y0 = int(u), int(v)
            fx, fy = u - x0, v - y0
            b = ((img[y0, x0] * (1 - fx) + img[y0, x0 + 1] * fx) * (1 - fy)
                 + (img[y0 + 1, x0] * (1 - fx) + img[y0 + 1, x0 + 1] * fx) * fy)
            samples.append((wts[y, x, k], ref.gray[yy, xx], b))
        want = 2.0
        if samples is not None:
            wt, a, b = np.array(samples).T
            ma, mb = wt @ a / wt.sum(), wt @ b / wt.sum()
            va, vb = wt @ a ** 2 / wt.sum() - ma ** 2, wt @ b ** 2 / wt.sum() - mb ** 2
            if min(va, vb) >= opt.min_texture ** 2:
                want = 1.0 - np.clip((wt @ (a * b) / wt.sum() - ma * mb) / np.sqrt(va * vb),
                                     -1, 1)
        bad += want == 2.0
        assert got == pytest.approx(want, abs=2e-4), (x, y, d, n)
    assert 40 < bad < 360  # both kinds of window were tried


def test_half_resolution_planes_start_the_full_resolution_iterations():
    """coarse_iterations: the half-resolution views see a world point at the same place
    (pixel centres: (u + 0.5) / 2 - 0.5), and one full-resolution iteration from their
    upsampled planes recovers the plane as the random start's four do."""
    from reconstruct.mvs.patchmatch import PatchMatchOptions, _half, patchmatch

    opt = PatchMatchOptions(max_image_size=128, coarse_iterations=3, iterations=1,
                            geom_iterations=0, seed=3)
    views = _plane_setup(3, opt)
    half = _half(views, [0, 2])
    assert half[1] is views[1] and half[0].gray.shape == (48, 64)
    X = np.random.default_rng(5).uniform(-0.5, 0.5, (20, 3)) * (1, 1, 0)
    for j in (0, 2):
        full_px, _ = views[j].camera.project(X)
        half_px, _ = half[j].camera.project(X)
        np.testing.assert_allclose(half_px, (full_px + 0.5) / 2 - 0.5, atol=1e-9)
    ref = patchmatch(views, [[1, 2], [0, 2], [0, 1]], opt)[0][0]
    truth = _true_depth(views[0].camera)
    inner = np.zeros_like(truth, bool)
    inner[8:-8, 8:-8] = True
    good = inner & (ref.depth > 0) & (np.abs(ref.depth - truth) < 0.005 * truth)
    assert good.sum() > 0.8 * inner.sum()


def test_active_sources_are_the_cheapest_and_find_the_same_plane():
    """A pixel's active sources are the views whose single-view cost of its plane is the
    lowest (the kernel's bits against each source scored alone); scoring the later
    iterations only against them finds the plane the all-source run finds, with a source
    that sees something else among them."""
    from reconstruct.mvs import _patchmatch_kernels as pk
    from reconstruct.mvs.patchmatch import (
        PatchMatchOptions,
        _relative,
        homography_parts,
        patchmatch,
    )

    opt = PatchMatchOptions(max_image_size=128, iterations=3, geom_iterations=1, seed=3)
    views = _plane_setup(4, opt, junk=(2,))
    ref, srcs = views[0], [1, 2, 3]
    cam = ref.camera
    kinv = np.linalg.inv(cam.K)
    wts, stats = pk.bilateral_weights(ref.gray, 4, 2, 0.2, 4.0)
    h, w = ref.gray.shape
    D, N = np.zeros((h, w)), np.zeros((h, w, 3))
    pk.initialise(D, N, *ref.depth_range, kinv, 5)

    def costs(js, nact):
        rel = [_relative(cam, views[j].camera) for j in js]
        C, S = np.zeros((h, w)), np.zeros((h, w), np.int64)
        ks = np.stack([views[j].camera.K for j in js])
        rs, ts = np.stack([r for r, _ in rel]), np.stack([t for _, t in rel])
        pk.final_costs(D, N, C, S, nact, ref.gray, wts, stats,
                       np.stack([views[j].gray for j in js]),
                       np.array([[views[j].camera.width, views[j].camera.height] for j in js]),
                       kinv, cam.K, ks, rs, ts, homography_parts(cam.K, ks, rs, ts), 4, 2,
                       opt.min_texture ** 2, 1, 0.0, np.zeros((len(js), h, w), np.float32),
                       3.0)
        return C, S

    alone = np.stack([costs([j], 0)[0] for j in srcs], axis=2)
    C, S = costs(srcs, 2)
    np.testing.assert_allclose(C, alone.min(axis=2), atol=1e-9)
    order = np.argsort(alone, axis=2, kind="stable")
    distinct = np.abs(np.diff(np.sort(alone, axis=2), axis=2)).min(axis=2) > 1e-9
    want = (1 << order[..., 0]) | (1 << order[..., 1])
    assert distinct.mean() > 0.5 and np.array_equal(S[distinct], want[distinct])

    truth = _true_depth(views[0].camera)
    inner = np.zeros_like(truth, bool)
    inner[8:-8, 8:-8] = True
    runs = {}
    for a in (0, 1):
        o = dataclasses.replace(opt, active_sources=a)
        runs[a] = patchmatch(views, [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]], o)[0][0]
        good = inner & (runs[a].depth > 0) & (np.abs(runs[a].depth - truth) < 0.005 * truth)
        assert good.sum() > 0.8 * inner.sum(), a
    both = (runs[0].depth > 0) & (runs[1].depth > 0) & inner
    rel = np.abs(runs[0].depth[both] - runs[1].depth[both]) / runs[0].depth[both]
    assert np.median(rel) < 0.001


def test_the_second_pass_fills_holes_on_confirmed_surfaces_only():
    """Every view's true depth of the plane, with three holes punched in view 0: one on
    the plane as every view sees it, one where view 0 sees something no other view does
    (its image there is noise), and a strip along the image's edge. The second pass gives
    the first the plane's depth, within 0.5 %, the second nothing where its windows see
    only the noise, and the strip (seeds on one side only: the edge of a surface)
    nothing; every other depth is left as it was."""
    from reconstruct.mvs.patchmatch import DepthMap, PatchMatchOptions, fill_holes

    opt = PatchMatchOptions(max_image_size=128, seed=3)
    views = _plane_setup(4, opt)
    views[0].gray[24:38, 74:88] = np.random.default_rng(7).random((14, 14)) * 0.8 + 0.1
    maps = []
    for v in views:
        n = v.camera.cam_from_world[:3, :3] @ np.array([0, 0, 1.0])
        n = -n if n[2] > 0 else n
        d = _true_depth(v.camera).astype(np.float32)
        nrm = np.broadcast_to(n, d.shape + (3,)).astype(np.float32).copy()
        maps.append(DepthMap(d, nrm, np.full(d.shape, 0.9, np.float32), [], d.copy()))
    truth = maps[0].depth.copy()
    on, off, strip = (np.zeros(truth.shape, bool) for _ in range(3))
    on[50:64, 30:44] = True  # on the plane
    off[24:38, 74:88] = True  # the noise
    strip[:, 10:16] = True  # the edge of the surface (nothing to its left)
    strip_left = np.zeros_like(strip)
    strip_left[:, :10] = True
    holes = on | off | strip | strip_left
    maps[0].depth[holes] = 0.0
    maps[0].normal[holes] = 0.0
    sources = [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]]
    out, stats = fill_holes(views, sources, maps, opt)
    got = out[0].depth
    assert (got[on] > 0).all()
    assert np.abs(got[on] - truth[on]).max() < 0.005 * truth[on].min()
    inner_off = np.zeros_like(off)
    inner_off[29:33, 79:83] = True  # farther than the window's radius from the plane
    assert not (got[inner_off] > 0).any() and (got[off] > 0).mean() < 0.5
    assert not (got[strip] > 0).any()
    assert np.array_equal(got[~holes], maps[0].depth[~holes])
    assert stats["filled"] == int(((got > 0) & (maps[0].depth <= 0)).sum())


def test_confirmed_depths_are_what_fusion_keeps_before_erosion():
    """The compiled agreement test (the second pass's "confirmed", and fusion's) against
    the same test in numpy, on depths and normals perturbed so that about half of them
    agree."""
    from reconstruct.mvs.fusion import (
        FusionOptions,
        _agree,
        _backproject,
        confirmed_depths,
        fuse_points,
    )

    cams, _ = _plane_views(n=4)
    rng = np.random.default_rng(4)
    depths, normals = [], []
    for c in cams:
        d = _true_depth(c) * (1 + rng.uniform(-0.015, 0.015, (c.height, c.width)))
        d[rng.random(d.shape) < 0.1] = 0.0
        n = c.cam_from_world[:3, :3] @ np.array([0, 0, 1.0])
        n = (-n if n[2] > 0 else n) + rng.normal(0, 0.25, (c.height, c.width, 3))
        depths.append(d.astype(np.float32))
        normals.append((n / np.linalg.norm(n, axis=2, keepdims=True)).astype(np.float32))
    nb = [[j for j in range(4) if j != i] for i in range(4)]
    opt = FusionOptions(edge_erosion=0, min_views=2)
    cos_max = np.cos(np.radians(opt.max_normal_deg))
    want = []
    for i, cam in enumerate(cams):
        u, v, pc = _backproject(cam, depths[i])
        X = pc @ cam.world_from_cam[:3, :3].T + cam.world_from_cam[:3, 3]
        n_ref = normals[i][v, u].astype(np.float64) @ cam.world_from_cam[:3, :3].T
        count = sum(_agree(X, n_ref, u, v, cam, cams[j], depths[j], normals[j], opt, cos_max)
                    for j in nb[i])
        m = np.zeros(depths[i].shape, bool)
        m[v[count >= 2], u[count >= 2]] = True
        want.append(m)
    got = confirmed_depths(cams, depths, normals, nb, opt)
    fused = fuse_points(cams, depths, normals, [np.zeros(d.shape + (3,), np.uint8)
                                                for d in depths], nb, opt).masks
    for g, f, m in zip(got, fused, want, strict=True):
        assert 0.2 < m.mean() < 0.8 and (g != m).mean() < 1e-3
        assert np.array_equal(f, g)


def test_fusion_keeps_what_views_agree_on():
    from reconstruct.mvs.fusion import FusionOptions, fuse_points

    cams, _ = _plane_views(n=4)
    depths = [_true_depth(c).astype(np.float32) for c in cams]
    normals = []
    for c in cams:
        n = c.cam_from_world[:3, :3] @ np.array([0, 0, 1.0])
        n = -n if n[2] > 0 else n
        normals.append(np.broadcast_to(n, (c.height, c.width, 3)).astype(np.float32))
    colors = [np.zeros((c.height, c.width, 3), np.uint8) for c in cams]
    nb = [[j for j in range(4) if j != i] for i in range(4)]
    opt = FusionOptions(edge_erosion=0, min_views=2)
    fused = fuse_points(cams, depths, normals, colors, nb, opt)
    assert min(fused.coverage) > 0.5
    np.testing.assert_allclose(fused.points[:, 2], 0.0, atol=1e-6)  # on the plane
    assert fused.visibility.min() >= 3  # itself and the 2 that had to agree
    loose = fuse_points(cams, depths, normals, colors, nb, FusionOptions(edge_erosion=0,
                                                                         min_views=1))
    assert loose.visibility.min() == 2 and len(loose.points) > len(fused.points)
    # a view whose depth is 5 % off agrees with nobody: its points go, the others' stay
    wrong = [depths[0] * 1.05, *depths[1:]]
    fused2 = fuse_points(cams, wrong, normals, colors, nb, opt)
    assert fused2.coverage[0] == 0.0 and min(fused2.coverage[1:]) > 0.5


def test_only_confirmed_depths_trim_the_mesh_as_free_space():
    """Two views whose depth in one region lies 10 and 25 % behind the plane (no other
    view agrees: fusion drops it) see through the plane there: with free_space "all" they trim
    the Poisson surface over that region, with "confirmed" (the default) they do not."""
    from reconstruct.mvs.fusion import FusionOptions, fuse_points, poisson_surface

    cams, _ = _plane_views(n=4)
    depths = [_true_depth(c).astype(np.float32) for c in cams]
    normals = []
    for c in cams:
        n = c.cam_from_world[:3, :3] @ np.array([0, 0, 1.0])
        normals.append(np.broadcast_to(-n if n[2] > 0 else n, (c.height, c.width, 3))
                       .astype(np.float32))
    colors = [np.zeros((c.height, c.width, 3), np.uint8) for c in cams]
    nb = [[j for j in range(4) if j != i] for i in range(4)]
    fused = fuse_points(cams, depths, normals, colors, nb, FusionOptions(edge_erosion=0))
    wrong = [d.copy() for d in depths]
    wrong[0][30:60, 40:80] *= 1.1  # each behind the plane, and not where the other is
    wrong[1][30:60, 40:80] *= 1.25
    masks = fuse_points(cams, wrong, normals, colors, nb, FusionOptions(edge_erosion=0)).masks
    assert not masks[0][30:60, 40:80].any() and masks[0].mean() > 0.3

    def area_near(mesh, X):  # vertices within 2 cm of the world points X
        from scipy.spatial import cKDTree

        return int((cKDTree(np.asarray(mesh.vertices)).query(X)[0] < 0.02).sum())

    region = np.zeros(depths[0].shape, bool)
    region[35:55, 45:75] = True
    v, u = np.nonzero(region)
    X = cams[0].unproject(np.column_stack([u, v]).astype(float), depths[0][region])
    kept = poisson_surface(fused, cams, wrong, FusionOptions(), confirmed=masks)
    cut = poisson_surface(fused, cams, wrong, FusionOptions(free_space="all"), confirmed=masks)
    assert area_near(kept, X) == len(X)
    assert area_near(cut, X) < 0.2 * len(X)


# -- the pipeline on photos as phones write them, and from known cameras ---------------------

@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    from data_synth.fixtures import sfm_capture

    return sfm_capture(tmp_path_factory.mktemp("mvs_fixture"))


def _cli(capsys, *argv):
    code = main(list(map(str, argv)))
    return code, capsys.readouterr().err.strip().splitlines()


def test_phone_folder_with_exif_rotations_and_mixed_sizes(capture, tmp_path, capsys):
    """Like a phone: some photos stored sideways with an EXIF tag, two others really
    portrait (cropped), one TIFF in 16 bit; all read upright, one camera per size."""
    folder = tmp_path / "phone"
    folder.mkdir()
    for i, p in enumerate(sorted((capture / "images").glob("*.png"))):
        img = cv2.imread(str(p))[..., ::-1]
        if i % 3 == 1:  # stored rotated, tagged 6: upright is the original
            _exif_jpeg(folder / f"{i:02d}.jpg", np.ascontiguousarray(np.rot90(img, 1)), 6)
        elif i == 2:
            cv2.imwrite(str(folder / f"{i:02d}.tif"), img[..., ::-1].astype(np.uint16) * 257)
        else:
            _exif_jpeg(folder / f"{i:02d}.jpg", img, 1)
    code, err = _cli(capsys, "-q", "reconstruct", "sfm", folder, "--out", tmp_path / "rec",
                     "--no-dense", "--num-threads", "1")
    assert code == 0, err
    rep = json.loads((tmp_path / "rec" / "report.json").read_text())
    assert rep["registered"] == 12
    assert rep["exif_rotated"] == ["01.jpg", "04.jpg", "07.jpg", "10.jpg"]
    assert rep["image_sizes"] == [[320, 240]]  # upright: one size, one camera
    assert len(rep["sparse"]["cameras"]) == 1
    # per-image cameras: one each
    code, err = _cli(capsys, "-q", "reconstruct", "sfm", folder, "--out", tmp_path / "rec2",
                     "--no-dense", "--num-threads", "1", "--camera-mode", "per-image")
    assert code == 0, err
    rep = json.loads((tmp_path / "rec2" / "report.json").read_text())
    assert len(rep["sparse"]["cameras"]) == 12 and rep["registered"] >= 10


def test_known_cameras_are_kept_and_the_dense_stage_runs_on_them(capture, tmp_path, capsys):
    from acquire.sfm.nerfstudio import write_transforms
    from reconstruct.camera_files import camera_from_colmap, image_cam_from_world

    data = json.loads((capture / "capture.json").read_text())
    true = {n: Camera.from_dict(c) for n, c in data["ground_truth"]["cameras"].items()}
    names = sorted(true)
    write_transforms(tmp_path / "transforms.json", [true[n] for n in names],
                     [f"images/{n.split('/')[-1]}" for n in names])
    folder = capture / "images"
    code, err = _cli(capsys, "-q", "reconstruct", "sfm", folder, "--out", tmp_path / "rec",
                     "--cameras", tmp_path / "transforms.json", "--num-threads", "1",
                     "--mvs.patchmatch.max-image-size", "160")
    assert code == 0, err
    rep = json.loads((tmp_path / "rec" / "report.json").read_text())
    assert rep["registered"] == 12 and rep["intrinsics_source"].startswith("--cameras")
    import pycolmap

    rec = pycolmap.Reconstruction(str(tmp_path / "rec" / "sparse" / "0"))
    for im in rec.images.values():  # the poses and intrinsics were held fixed
        cam = camera_from_colmap(im.camera, image_cam_from_world(im))
        t = true[f"images/{im.name}"] if f"images/{im.name}" in true else true[im.name]
        np.testing.assert_allclose(cam.cam_from_world, t.cam_from_world, atol=1e-9)
        np.testing.assert_allclose(cam.K, t.K, atol=1e-9)
    assert rep["sparse"]["num_points"] > 300
    assert rep["sparse"]["mean_reprojection_error_px"] < 0.5
    # the dense stage's files, per view
    d = rep["dense"]
    assert d["method"] == "patchmatch" and d["surface"] == "poisson"
    some = next(iter(d["views"]))
    for kind in ("depth", "normal", "confidence"):
        arr = np.load(tmp_path / "rec" / "dense" / f"{some}.{kind}.npy")
        assert arr.shape[:2] == (120, 160)
    assert (tmp_path / "rec" / "dense" / "coverage.png").is_file()
    assert d["min_fused_coverage"] > 0.3 and d["views"][some]["sources"]
    assert (tmp_path / "rec" / "mesh.ply").is_file() and (tmp_path / "rec" / "fused.ply").is_file()


def test_camera_file_disagreeing_with_the_folder_is_one_line(capture, tmp_path, capsys):
    from acquire.sfm.nerfstudio import write_transforms

    data = json.loads((capture / "capture.json").read_text())
    true = [Camera.from_dict(c) for c in data["ground_truth"]["cameras"].values()]
    write_transforms(tmp_path / "t.json", true[:4],
                     ["0000.png", "0001.png", "0002.png", "missing.png"])
    code, err = _cli(capsys, "reconstruct", "sfm", capture / "images", "--out",
                     tmp_path / "o", "--cameras", tmp_path / "t.json")
    assert code == 2 and len(err) == 1 and "missing.png" in err[0] and "t.json" in err[0]
    assert not (tmp_path / "o").exists()
    big = [c.__class__(640, 480, c.fx, c.fy, c.cx, c.cy, c.dist, c.cam_from_world)
           for c in true[:3]]
    write_transforms(tmp_path / "t.json", big, ["0000.png", "0001.png", "0002.png"])
    code, err = _cli(capsys, "reconstruct", "sfm", capture / "images", "--out",
                     tmp_path / "o", "--cameras", tmp_path / "t.json")
    assert code == 2 and len(err) == 1 and "640x480" in err[0] and "320x240" in err[0]
    assert not (tmp_path / "o").exists()


def test_a_view_without_sources_is_skipped_with_a_warning(tmp_path, caplog):
    """Four views of a textured plane and one camera that looks away: its depth map is
    empty, the log names it, the others make the surface."""
    from reconstruct.mvs.patchmatch import PatchMatchOptions
    from reconstruct.mvs.pipeline import MvsOptions, dense_surface

    cams, imgs = _plane_views(n=4)
    away = Camera(128, 96, 110.0, 110.0, 63.5, 47.5, np.zeros(5),
                  Camera.look_at((0, 0, 2.0), (0, 0, 5.0), up=(0, 1, 0)).cam_from_world)
    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(-0.8, 0.8, (80, 2)), np.zeros(80)])
    visible = [np.arange(80)] * 4 + [np.zeros(0, np.int64)]
    names = ["a", "b", "c", "d", "away"]
    opt = MvsOptions(patchmatch=PatchMatchOptions(max_image_size=128, iterations=3,
                                                  geom_iterations=1))
    with caplog.at_level("WARNING"):
        mesh, rep = dense_surface(names, [*imgs, np.zeros((96, 128), np.uint8)],
                                  [*cams, away], visible, pts, tmp_path, opt)
    assert any("away: no depth map" in r.getMessage() for r in caplog.records)
    assert rep["views"]["away"]["sources"] == [] and rep["views"]["away"]["fused_coverage"] == 0
    assert min(rep["views"][n]["fused_coverage"] for n in "abcd") > 0.3
    v = np.asarray(mesh.vertices)
    assert len(v) > 100 and np.percentile(np.abs(v[:, 2]), 90) < 0.01  # the plane z = 0
    for n in names:
        assert (tmp_path / "dense" / f"{n}.preview.png").is_file()


def test_a_turntable_backdrop_is_the_same_pattern_at_the_same_pixels_in_every_view(
        capture, tmp_path):
    """The turntable test bed: the object's pixels are untouched, and behind it every view
    gains one dim textured pattern at the same pixels (the cloth behind a turntable), of
    the asked level and contrast; the truth is copied as it was."""
    import cv2

    from core.io.image import read_image
    from data_synth.fixtures import turntable_backdrop

    out = turntable_backdrop(capture, tmp_path / "tt", rng=np.random.default_rng(0),
                             level=20.0, contrast=6.0, scale=8.0, vignetting=0.0)
    assert turntable_backdrop(capture, out, rng=np.random.default_rng(0)) == out  # once
    names = sorted(p.name for p in (capture / "images").glob("*.png"))
    k = np.ones((7, 7), np.uint8)
    diffs, backs = [], []
    for i, n in enumerate(names):
        a = read_image(capture / "images" / n).astype(float)
        b = read_image(out / "images" / n).astype(float)
        sil = (np.load(capture / "gt" / f"depth_{i:04d}.npy") > 0).astype(np.uint8)
        inner = cv2.erode(sil, k) > 0
        back = cv2.dilate(sil, k) == 0
        assert np.abs(a - b)[inner].max() <= 1.0  # the object, as rendered
        diffs.append((b - a).mean(axis=2) if b.ndim == 3 else b - a)
        brightest = a.max(axis=2) if a.ndim == 3 else a
        backs.append(back & (brightest < 200))  # not clipped at 255
        assert np.array_equal(np.load(out / "gt" / f"depth_{i:04d}.npy"),
                              np.load(capture / "gt" / f"depth_{i:04d}.npy"))
    common = np.logical_and.reduce(backs)
    assert common.mean() > 0.2
    pattern = np.median([d[common] for d in diffs], axis=0)
    assert abs(pattern.mean() - 20.0) < 2.0 and abs(pattern.std() - 6.0) < 1.5
    for d in diffs:  # the same pattern in every view (rounding only)
        assert np.abs(d[common] - pattern).max() <= 1.0
