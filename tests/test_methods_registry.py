"""The registry of acquisition methods: six methods behind one protocol, and a method added
as one module reaches the commands and the studies with nothing else edited.

The toy method below is what a seventh method's module looks like: its configs (declared
once, the CLI's flags and the study's overrides come from them), capture, reconstruct and
the frame of its output. It samples the scene's surface with noise and reconstructs the
centroid of the samples, so the figures it reports can be checked against the truth.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from core.config import Config, option
from core.files import atomic_dir, json_data, write_json
from reconstruct.result import ReconstructionResult
from scanamp.methods import Method, get_method, methods, registered


@dataclass
class ToyCapture(Config):
    """The toy scanner: ``points`` samples of the surface with Gaussian noise."""

    points: int = option(400, range="[1, inf)", help="surface samples")
    noise: float = option(0.0, unit="m", range="[0, inf)", help="noise sigma per axis")
    seed: int = option(0, range="[0, inf)", help="sampling and noise seed")


@dataclass
class ToyRecon(Config):
    """The toy reconstruction: the centroid of every ``stride``-th sample."""

    stride: int = option(1, range="[1, inf)", help="keep every stride-th sample")


class Toy(Method):
    name = "toy"
    title = "toy surface sampler"
    capture_help = "sample a scene's surface with noise"
    reconstruct_help = "the centroid of the samples"
    capture_config = ToyCapture
    recon_config = ToyRecon
    frame = "world"
    metrics = ("points", "centroid_error_m")

    def capture(self, bundle, config, out_dir, *, rng, seed=0, scene_path=None) -> Path:
        from core.meshes import mesh_arrays
        from core.sampling import sample_surface

        v, f = mesh_arrays(bundle.gt_mesh())
        p, _ = sample_surface(v, f, config.points, rng=rng)
        p = p + rng.normal(0.0, config.noise, p.shape) if config.noise else p
        truth, _ = sample_surface(v, f, 20000, rng=np.random.default_rng(1))
        with atomic_dir(out_dir) as tmp:
            np.save(tmp / "points.npy", p)
            write_json(tmp / "truth.json", {"centroid": truth.mean(0)})
        return Path(out_dir)

    def reconstruct(self, config, inputs, out_dir):
        p = np.load(Path(inputs) / "points.npy")[::config.stride]
        truth = np.asarray(json.loads((Path(inputs) / "truth.json").read_text())["centroid"])
        report = {"points": len(p), "centroid": p.mean(0),
                  "centroid_error_m": float(np.linalg.norm(p.mean(0) - truth))}
        with atomic_dir(out_dir) as tmp:
            write_json(tmp / "report.json", report)
        return ReconstructionResult(Path(out_dir), json_data(report))


def test_the_registry_holds_the_six_methods_behind_one_protocol():
    found = methods()
    assert sorted(found) == ["laser", "lidar", "scans", "sfm", "stereo", "structured-light"]
    for name, m in found.items():
        assert isinstance(m, Method) and m.name == name
        assert dataclasses.is_dataclass(m.capture_config)
        assert dataclasses.is_dataclass(m.recon_config)
        assert m.frame and m.metrics and m.capture_help and m.reconstruct_help
        assert "seed" in {f.name for f in dataclasses.fields(m.capture_config)}
    with pytest.raises(ValueError, match="method"):
        get_method("toy")


def test_every_method_is_a_capture_and_a_reconstruct_command_and_a_study_kind():
    from scanamp.cli import build_parser
    from scanamp.study import KINDS

    sub = next(a for a in build_parser()._actions if a.dest == "command")
    for group in ("capture", "reconstruct"):
        kinds = next(a for a in sub.choices[group]._actions if a.dest == "kind")
        assert set(kinds.choices) == set(methods()), group
    assert set(methods()) <= set(KINDS)
    for name, m in methods().items():
        assert KINDS[name].default_metrics == m.metrics


def test_a_method_added_as_one_module_reaches_the_cli_and_the_studies(tmp_path):
    from scanamp.cli import main
    from scanamp.study import KINDS, execute_run, load_study

    with registered(Toy()):
        cap, rec = tmp_path / "cap", tmp_path / "rec"
        # the CLI: flags from the toy's declared options
        assert main(["-q", "capture", "toy", "object", "--points", "300", "--noise", "0.001",
                     "--out", str(cap)]) == 0
        assert len(np.load(cap / "points.npy")) == 300
        assert main(["-q", "reconstruct", "toy", str(cap), "--stride", "3",
                     "--out", str(rec)]) == 0
        report = json.loads((rec / "report.json").read_text())
        assert report["points"] == 100
        assert 0 < report["centroid_error_m"] < 0.01  # 100 samples of a ~10 cm object
        # the studies: a kind of the same name, overrides checked against its configs
        assert KINDS["toy"].default_metrics == Toy.metrics
        spec = tmp_path / "toy.toml"
        spec.write_text('[study]\nname = "toy"\nkind = "toy"\nscene = "object"\nseed = 2\n'
                        '[sweep]\npoints = [50, 5000]\n"reconstruct.stride" = [1]\n'
                        '[output]\nmetrics = ["points", "centroid_error_m"]\n')
        study = load_study(spec)
        records = [execute_run({"run_id": r.run_id, "kind": "toy", "scene": study.scene,
                                "seed": r.seed, "params": r.params, "overrides": r.overrides,
                                "metrics": list(study.metrics), "record_path": None,
                                "keep_dir": str(tmp_path / "work")}) for r in study.runs]
        assert [r["status"] for r in records] == ["ok", "ok"], records
        by_points = {r["metrics"]["points"]: r["metrics"]["centroid_error_m"] for r in records}
        assert set(by_points) == {50, 5000}
        assert by_points[5000] < by_points[50]  # more samples, a truer centroid
        bad = spec.read_text().replace("points = [50, 5000]", "pointz = [50]")
        spec.write_text(bad)
        with pytest.raises(ValueError, match="pointz"):
            load_study(spec)
    # gone with the temporary registry
    assert "toy" not in methods() and "toy" not in KINDS
    with pytest.raises(SystemExit) as exit_:
        main(["-q", "capture", "toy", "object", "--out", str(tmp_path / "x")])
    assert exit_.value.code == 2
    assert not (tmp_path / "x").exists()


def test_a_method_name_is_registered_once():
    with pytest.raises(ValueError, match="laser"):
        with registered(type("Laser2", (Toy,), {"name": "laser"})()):
            pass
    assert get_method("laser").recon_config.__name__ == "LaserReconConfig"
