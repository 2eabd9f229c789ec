"""Stereo targets (issue 4): accuracy on textured / textureless turntable captures and the
speed of rectification + matching + fusion against the bare StereoSGBM call (same run).

Captures are rendered at 640x480 with the default rig (4 stage angles, 10 board views).
"""

import json
import tempfile
from pathlib import Path

import numpy as np
from _timing import best_of, report


def _capture(tmp, textureless):
    from acquire.capture_stereo import capture
    from acquire.stereo_rig import load_rig
    from scanamp.commands.capture_stereo import load_scene_for_capture

    bundle = load_scene_for_capture("object", textureless)
    out = Path(tmp) / ("plain" if textureless else "textured")
    return capture(bundle.render_scene, load_rig(None), out, np.random.default_rng(0),
                   object_name="object")


def _speed(cap_dir):
    import cv2

    from acquire.capture_io import load_capture
    from procgen.mesh_io import read_image
    from reconstruct.stereo import disparity_range, disparity_to_depth, match, rectify, rectify_pair
    from reconstruct.stereo_recon import StereoOptions, calibrate_capture, to_gray
    from reconstruct.tsdf import fuse_depth_maps

    cap = load_capture(cap_dir)
    calib, tfl, _ = calibrate_capture(cap)
    rect = rectify(calib)
    lo, num = disparity_range(rect, *cap.rig["working_range"])
    L = to_gray(read_image(cap.path(cap.frames[0]["images"][0])))
    R = to_gray(read_image(cap.path(cap.frames[0]["images"][1])))
    opts = StereoOptions(lr_check=False).match_options(lo, num)
    lr, rr = rectify_pair(L, R, rect)
    cam = rect.left_camera()
    voxel = cap.rig["working_range"][1] / 500

    def ours():
        a, b = rectify_pair(L, R, rect)
        d = match(a, b, opts)
        fuse_depth_maps([disparity_to_depth(d, rect)], [cam], voxel_size=voxel,
                        depth_max=cap.rig["working_range"][1])

    sg = cv2.StereoSGBM.create(minDisparity=lo, numDisparities=num, blockSize=5, P1=200, P2=800,
                               uniquenessRatio=5, speckleWindowSize=100, speckleRange=2)
    peer = best_of(lambda: sg.compute(lr, rr), repeat=3)
    t = best_of(ours, repeat=3)
    print(f"   one 640x480 pair: rectify+match+fuse {t * 1e3:.0f} ms, bare SGBM {peer * 1e3:.0f} ms"
          f" (search {num} disparities from {lo}; LR check off)")
    report("stereo pipeline time / bare SGBM", t, peer, 2.0, higher_is_better=False)


def main():
    from reconstruct.stereo_recon import StereoOptions, run_capture

    with tempfile.TemporaryDirectory() as tmp:
        tex = _capture(tmp, False)
        run_capture(tex, Path(tmp) / "r_tex", StereoOptions(compare=False, mode="passive"))
        r = json.loads((Path(tmp) / "r_tex" / "report.json").read_text())
        res = r["results"]["passive"]
        dm, ev = res["disparity_mean"], res["evaluation"]
        print(f"   textured (passive): bad-1.0 {dm['bad1.0']:.2f}%  bad-2.0 {dm['bad2.0']:.2f}%  "
              f"avgerr {dm['avgerr']:.3f} px  invalid {dm['invalid']:.2f}%")
        print(f"   textured (passive): F@1% {ev['fscore']:.3f} "
              f"(without ICP {ev['fscore_without_icp']:.3f})"
              f"  calib baseline err {r['calibration']['truth_errors']['baseline_rel_err']:.2e}")
        report("textured bad-2.0 (%)", dm["bad2.0"], 1.0, 2.0, higher_is_better=False, unit="%")
        report("textured F-score at 1%", ev["fscore"], 1.0, 0.9, unit="")
        _speed(tex)
        plain = _capture(tmp, True)
        run_capture(plain, Path(tmp) / "r_plain", StereoOptions(compare=True, mode="active"))
        r = json.loads((Path(tmp) / "r_plain" / "report.json").read_text())
        for mode in ("passive", "active"):
            res = r["results"][mode]
            print(f"   textureless {mode}: F@1% {res['evaluation']['fscore']:.3f}  "
                  f"bad-2.0 {res['disparity_mean']['bad2.0']:.2f}%  invalid "
                  f"{res['disparity_mean']['invalid']:.2f}%")
        report("textureless active F-score at 1%", r["results"]["active"]["evaluation"]["fscore"],
               1.0, 0.85, unit="")


if __name__ == "__main__":
    main()
