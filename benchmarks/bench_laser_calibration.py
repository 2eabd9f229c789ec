"""Laser scanner: the calibration part of the error model, checked across calibrations.

One scan has one calibration, so its calibration error is a single draw: bench_laser
can only check that side one way. Here the calibration captures are rendered K times
with different seeds (fresh sensor noise, speckle and board poses), each followed by a
short scan (12 frames), and the figures are pooled over the K calibrations:

- the depth error the calibration adds, sqrt(RMS_total^2 - RMS_peak-only^2) per scan,
  against the prediction of the error model (laser-plane jackknife + intrinsics
  bootstrap), RMS over the scans; both ways, bound 1.5x (K = 8 draws of a few
  parameters: the ratio itself scatters by about 1/sqrt(2K) = 25 %);
- the focal-length error across calibrations against OpenCV's own standard deviation;
- the laser-plane normal error, worst and RMS over the calibrations (target <= 0.05 deg).

    python benchmarks/bench_laser_calibration.py [K]
"""

import json
import sys
import tempfile
from pathlib import Path

import numpy as np
from _timing import report

from acquire.laser.capture import capture
from acquire.laser.rig import LaserCaptureConfig, LaserRig
from data_synth.scenes import build_scene
from reconstruct.laser.pipeline import LaserReconConfig, run


def main(k: int = 8):
    scene = build_scene("object")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for seed in range(k):
            rig = LaserCaptureConfig(rig=LaserRig(steps=12))
            capture(scene.render_scene, rig, tmp / f"c{seed}", np.random.default_rng(seed))
            run(LaserReconConfig(), tmp / f"c{seed}", tmp / f"r{seed}")
            rep = json.loads((tmp / f"r{seed}" / "report.json").read_text())
            ev, de = rep["evaluation"], rep["evaluation"]["depth_error"]
            parts = de["predicted_parts_rms_m"]
            rows.append({
                "calib_m2": max(de["rms_m"] ** 2 - de["peak_only_rms_m"] ** 2, 0.0),
                "pred_m2": parts["plane"] ** 2 + parts["intrinsics"] ** 2,
                "bias_m": de["bias_m"], "fx_err": ev["intrinsics_error"]["fx_px"],
                "fx_std": rep["calibration"]["camera"]["std_intrinsics"]["fx"],
                "plane_deg": ev["laser_plane_error"]["normal_deg"]})
            r = rows[-1]
            print(f"   seed {seed}: calibration part of the depth error "
                  f"{1e3 * np.sqrt(r['calib_m2']):.4f} mm (bias {1e3 * r['bias_m']:+.4f}), "
                  f"predicted {1e3 * np.sqrt(r['pred_m2']):.4f} mm; fx error "
                  f"{r['fx_err']:+.3f} px (OpenCV std {r['fx_std']:.3f}); plane normal "
                  f"{r['plane_deg']:.4f} deg", flush=True)
    calib = np.sqrt(np.mean([r["calib_m2"] for r in rows]))
    pred = np.sqrt(np.mean([r["pred_m2"] for r in rows]))
    fx = np.sqrt(np.mean([r["fx_err"] ** 2 for r in rows]))
    fx_std = np.sqrt(np.mean([r["fx_std"] ** 2 for r in rows]))
    plane = np.array([r["plane_deg"] for r in rows])
    print(f"   over {k} calibrations: calibration part of the depth error RMS "
          f"{1e3 * calib:.4f} mm, predicted {1e3 * pred:.4f} mm; fx error RMS {fx:.3f} px, "
          f"OpenCV std {fx_std:.3f} px; plane normal error RMS "
          f"{np.sqrt(np.mean(plane ** 2)):.4f} deg, max {plane.max():.4f} deg")
    report("calibration depth error / prediction", calib, pred, 1.5, higher_is_better=False)
    report("prediction / calibration depth error", pred, calib, 1.5, higher_is_better=False)
    report("fx error RMS / OpenCV std", fx, fx_std, 1.5, higher_is_better=False)
    report("OpenCV std / fx error RMS", fx_std, fx, 1.5, higher_is_better=False)
    report("laser-plane normal error, worst calibration", plane.max(), 1.0, 0.05,
           higher_is_better=False, unit=" deg")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 8)
