"""Real photographs (``make real-data``: the sample images OpenCV ships, from Debian's
opencv-doc package).

1. Stereo calibration of a real rig from its 13 chessboard pairs (left01..right14,
   640x480, 10x7 squares; the square size is not given, so lengths are in squares):
   RMS, the epipolar error of the corners after rectification, and the focal length
   against the result OpenCV's own stereo_calib sample shipped beside the images
   (intrinsics.yml, one focal length shared by both cameras).
2. The Middlebury "Aloe" pair (1282x1110, rectified, ground-truth disparity aloeGT.png):
   ``scanamp reconstruct stereo --left --right --calibration --disparity-gt`` with its
   default options and with the LR check, against the bare StereoSGBM with the
   parameters of OpenCV's stereo_match sample (same disparity range, same run).
"""

import json
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / ".cache" / "real" / "opencv"


def _calibration():
    import cv2

    from acquire.targets import target_from_spec
    from reconstruct.calibration.images import calibrate_stereo_images, sorted_images

    left = sorted_images(str(DATA / "left[01]*.jpg"))
    right = sorted_images(str(DATA / "right[01]*.jpg"))
    calib, rep = calibrate_stereo_images(left, right, target_from_spec("chessboard:10x7:1.0"))
    fs = cv2.FileStorage(str(DATA / "intrinsics.yml"), cv2.FILE_STORAGE_READ)
    ref = fs.getNode("M1").mat()
    fs.release()
    f_ours = 0.5 * (calib.K1[0, 0] + calib.K2[0, 0])
    print(f"   real stereo calibration: {rep['pairs_used']} of {rep['pairs']} pairs; RMS left "
          f"{rep['rms_left_px']:.3f} px, right {rep['rms_right_px']:.3f} px, stereo "
          f"{rep['rms_stereo_px']:.3f} px")
    print(f"   baseline {rep['baseline']:.3f} squares; epipolar error after rectification "
          f"RMS {rep['epipolar_rms_px']:.3f} px, max {rep['epipolar_max_px']:.3f} px")
    print(f"   focal length: left {calib.K1[0, 0]:.2f}, right {calib.K2[0, 0]:.2f} px; mean "
          f"{f_ours:.2f} vs OpenCV sample's {ref[0, 0]:.2f} px ({f_ours / ref[0, 0] - 1:+.2%})")
    ok = rep["epipolar_rms_px"] <= 0.5
    print(f"   epipolar RMS on the real rig: {rep['epipolar_rms_px']:.2f} px "
          f"(bound <= 0.5 px) {'PASS' if ok else 'FAIL'}")
    return ok


def _bare_sgbm(left, right, num):
    """OpenCV's stereo_match sample's SGBM (window 3), the same disparity range."""
    import cv2

    ws = 3
    sgbm = cv2.StereoSGBM_create(minDisparity=0, numDisparities=num, blockSize=ws,
                                 P1=8 * 3 * ws ** 2, P2=32 * 3 * ws ** 2, disp12MaxDiff=1,
                                 uniquenessRatio=10, speckleWindowSize=100, speckleRange=32)
    d = sgbm.compute(left, right).astype(np.float64) / 16.0
    return np.where(d >= 0, d, np.nan)


def _aloe():
    from core.io.image import read_image
    from reconstruct.calibration.io import write_stereo_yaml
    from reconstruct.calibration.rectify import StereoCalibration
    from reconstruct.evaluation.disparity import disparity_metrics
    from reconstruct.stereo.options import StereoOptions
    from reconstruct.stereo.pair import read_disparity, run_pair

    L, R = DATA / "aloeL.jpg", DATA / "aloeR.jpg"
    gt = read_disparity(DATA / "aloeGT.png")
    h, w = gt.shape
    # rectified already: identical cameras, a pure x baseline (Middlebury 2006: f 3740 px,
    # 160 mm); the disparity does not depend on these, the depth does
    K = np.array([[3740.0, 0, (w - 1) / 2], [0, 3740.0, (h - 1) / 2], [0, 0, 1]])
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        yaml = write_stereo_yaml(Path(tmp) / "aloe.yaml", StereoCalibration(
            K, np.zeros(5), K, np.zeros(5), np.eye(3), np.array([-0.16, 0, 0]), (w, h)))
        for name, opts in (("scanamp (defaults)", StereoOptions(num_disparities=256)),
                           ("scanamp --lr-check", StereoOptions(num_disparities=256,
                                                                lr_check=True))):
            out = run_pair(L, R, yaml, Path(tmp) / name.split()[-1], options=opts,
                           disparity_gt=DATA / "aloeGT.png")
            rows.append((name, json.loads((out / "report.json").read_text())
                         ["disparity_metrics"]))
        bare = _bare_sgbm(read_image(L, grayscale=True), read_image(R, grayscale=True), 256)
        rows.append(("bare SGBM, OpenCV sample params", disparity_metrics(bare, gt)))
    print("   Middlebury Aloe (real, 1282x1110), all pixels with ground truth:")
    print("   | matcher | bad-1.0 % | bad-2.0 % | bad-2.0 % of matched | avgerr px | "
          "density % |")
    print("   |---|---|---|---|---|---|")
    for name, m in rows:
        print(f"   | {name} | {m['bad1.0']:.2f} | {m['bad2.0']:.2f} | "
              f"{m['bad2.0_sparse']:.2f} | {m['avgerr']:.2f} | {m['density']:.1f} |")
    ours, peer = rows[0][1]["bad2.0"], rows[-1][1]["bad2.0"]
    ok = ours <= peer
    print(f"   bad-2.0 ours / bare SGBM with the sample's parameters: {ours / peer:.2f}x "
          f"(bound <= 1.0x) {'PASS' if ok else 'FAIL'}")
    return ok


def main():
    if not (DATA / "aloeGT.png").is_file():
        print(f"   no real data in {DATA}: run `make real-data` (make bench does)")
        return 1
    ok = _calibration()
    ok = _aloe() and ok
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
