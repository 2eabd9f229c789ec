"""A real, tiny study end to end: the peak-detector kind renders laser frames of the
object through the capture's renderer and sensor, detects the stripe and scores it
against the true centre. Physics the result must show: more image noise, larger peak
error; the sub-pixel Gaussian fit beats the integer argmax on clean images."""

import pandas as pd

from scanamp.cli import main

SPEC = """
[study]
name = "peaks-tiny"
kind = "peak-detector"
scene = "object"
seed = 0
[base]
"rig.width" = 320
"rig.height" = 240
"rig.steps" = 3
"rig.step_deg" = 120.0
[sweep]
"sensor.read_noise" = [0, 1600]
"reconstruct.detector" = ["argmax", "gaussian"]
[output]
metrics = ["peak_error.rms_px", "peak_error.detection_rate", "counts.true_rows"]
"""


def test_tiny_peak_detector_study_moves_the_right_way(tmp_path, capsys):
    spec = tmp_path / "peaks.toml"
    spec.write_text(SPEC)
    assert main(["-q", "study", str(spec), "--out", str(tmp_path / "o"), "--workers", "2"]) == 0
    out = capsys.readouterr().out
    assert "4 runs" in out and "gaussian" in out  # the summary table is printed
    df = pd.read_csv(tmp_path / "o" / "results.csv")
    assert (df["status"] == "ok").all() and len(df) == 4
    assert (df["counts.true_rows"] > 100).all()  # the stripe crosses the object
    rms = df.set_index(["sensor.read_noise", "reconstruct.detector"])["peak_error.rms_px"]
    for det in ("argmax", "gaussian"):
        assert rms[(1600, det)] > rms[(0, det)]
    # argmax is off by up to half a pixel (rms ~0.29 for a uniform error); the Gaussian
    # three-point fit is several times better on noise-free frames (measured 0.06 px)
    assert rms[(0, "gaussian")] < 0.5 * rms[(0, "argmax")]
    assert (tmp_path / "o" / "plots" / "peak_error.rms_px_vs_sensor.read_noise.png").is_file()


AMPLIFIED = """
[study]
name = "amplified-tiny"
kind = "amplified-laser"
scene = "object"
seed = 0
[base]
"rig.width" = 320
"rig.height" = 240
"rig.steps" = 24
"rig.camera_views" = 10
"rig.laser_views" = 4
"rig.axis_views" = 7
"target.squares_x" = 6
"target.squares_y" = 5
"target.square_length" = 0.025
"target.marker_length" = 0.018
"reconstruct.tau" = 0.002
"amplify.recipe" = "RECIPE"
[sweep]
"amplify.amplitude" = [0.0, 3.0]
[output]
metrics = ["evaluation.surface.fscore", "evaluation.surface.precision",
           "evaluation.depth_error.rms_m", "amplify.output.triangles"]
"""

RECIPE = """
[[step]]
kind = "clean"
edge_fraction = 0.02
[[step]]
kind = "displace"
edge = 0.5
wavelength = 3.0
"""


def test_an_amplification_parameter_swept_through_a_scanner(tmp_path):
    """The amplified-laser kind: the object is amplified, scanned and scored against its
    amplified self; zero amplitude leaves a smooth blob the scanner reconstructs well,
    a strong one adds detail that it recovers less well."""
    (tmp_path / "recipe.toml").write_text(RECIPE)
    spec = tmp_path / "amp.toml"
    spec.write_text(AMPLIFIED.replace("RECIPE", str(tmp_path / "recipe.toml")))
    assert main(["-q", "study", str(spec), "--out", str(tmp_path / "o"), "--workers", "1"]) == 0
    df = pd.read_csv(tmp_path / "o" / "results.csv").set_index("amplify.amplitude")
    assert (df["status"] == "ok").all() and len(df) == 2
    assert df.loc[0.0, "evaluation.surface.precision"] > 0.6   # as the plain blob scans
    smooth, rough = df.loc[0.0], df.loc[3.0]
    assert rough["evaluation.surface.precision"] < smooth["evaluation.surface.precision"]
    assert rough["evaluation.depth_error.rms_m"] > smooth["evaluation.depth_error.rms_m"]


SCANS_SPEC = """
[study]
name = "scans-tiny"
kind = "scans"
scene = "object"
seed = 0
[base]
"head.steps" = 60
"head.height" = 120
"head.width" = 120
"head.laser_thickness" = 0.0025
[sweep]
views = [3, 9]
[output]
metrics = ["registered_fraction", "poses.rotation_error_deg.max", "mesh.fscore"]
"""


def test_tiny_scans_study_registers_more_with_more_views(tmp_path):
    """The scans kind end to end: scan, register with no pose given, merge, score. Three
    views on the band barely overlap: the run fails and the study records why (no pair
    verified) instead of forcing scans together; nine place every scan near its true
    pose (the study measures 0.046 deg at 9 views with this head and the spacetime
    firmware, 0.18 with spatial peaks), and the merged mesh, carried into the world by the
    fitted gauge, lies on the scene."""
    spec = tmp_path / "scans.toml"
    spec.write_text(SCANS_SPEC)
    assert main(["-q", "study", str(spec), "--out", str(tmp_path / "o"), "--workers", "2"]) == 0
    df = pd.read_csv(tmp_path / "o" / "results.csv").set_index("views")
    assert df.loc[9, "status"] == "ok" and df.loc[9, "registered_fraction"] == 1.0
    assert (df.loc[3, "status"] == "failed"
            and "no two scans could be registered" in df.loc[3, "error"]) or \
        df.loc[3, "registered_fraction"] < 1.0
    assert df.loc[9, "poses.rotation_error_deg.max"] < 0.15
    assert df.loc[9, "mesh.fscore"] > 0.5
