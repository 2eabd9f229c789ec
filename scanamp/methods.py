"""The acquisition methods, one row each: how a scene is captured and how the capture is
reconstructed, behind two entry points with one signature for every method.

``capture(scene, config, out_dir, *, rng, seed=0, scene_path=None) -> Path`` renders a
virtual capture of ``scene`` (a :class:`data_synth.bundle.SceneBundle`) with the rig
``config`` (what ``scanamp capture KIND --config`` reads, :attr:`Method.load_capture`).

``run(config, capture_dir, out_dir) -> Result`` reconstructs a capture folder with the
reconstruction ``config`` (:attr:`Method.recon_config`, the dataclass ``scanamp
reconstruct KIND`` fills from its flags).

The studies (:mod:`scanamp.study.kinds`) and the demo call these; adding a method means
adding a row to :data:`METHODS`.

>>> sorted(METHODS)
['active-stereo', 'laser', 'sfm', 'stereo', 'structured-light']
>>> METHODS["active-stereo"].recon_config().mode
'active'
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["Method", "Result", "METHODS", "get_method", "scene_for_capture"]


@dataclass(frozen=True)
class Result:
    """A reconstruction: its folder and ``report.json``; ``ok`` False when the algorithm
    failed but still wrote a report (SfM registering too few images)."""

    out_dir: Path
    report: dict
    ok: bool = True
    message: str = ""


@dataclass(frozen=True)
class Method:
    """One acquisition method (see the module docstring)."""

    name: str
    title: str
    load_capture: Callable[[str | os.PathLike | None], Any]
    recon_config: Callable[[], Any]
    capture: Callable[..., Path]
    run: Callable[[Any, Path, Path], Result]


def _scene_info(scene, scene_path) -> dict:
    return {"path": str(scene_path) if scene_path is not None else scene.name,
            "name": scene.name, "seed": scene.seed}


def scene_for_capture(scene: str, *, textureless: bool = False):
    """The scene bundle a capture command renders: a built-in name, scene folder or TOML;
    ``textureless`` gives every object a constant material (passive stereo fails there)."""
    import copy

    from data_synth.scenes import build_scene

    bundle = build_scene(scene)
    if textureless:
        spec = copy.deepcopy(bundle.spec)
        for obj in spec.get("objects", []):   # no texture; the reflectance model kept
            mat = obj.get("material", {})
            keep = {k: v for k, v in mat.items()
                    if k not in ("kind", "texture", "scale", "contrast", "seed", "albedo")}
            obj["material"] = {"kind": "constant",
                               "albedo": mat.get("albedo", [0.7, 0.7, 0.7]), **keep}
        bundle = build_scene(spec)
    return bundle


def _object_name(scene, config=None) -> str | None:
    """The scanned object: the config's ``object``, else 'object' when the scene has one."""
    names = [o.name for o in scene.render_scene.objects]
    chosen = getattr(config, "object", None)
    if chosen is not None and chosen not in names:
        raise ValueError(f"object: expected one of {', '.join(names)}, got {chosen!r}")
    return chosen or ("object" if "object" in names else None)


def _report(out_dir) -> dict:
    from core.files import read_json

    return read_json(Path(out_dir) / "report.json")


# -- laser ---------------------------------------------------------------------------------
def _laser_load(path):
    from acquire.laser.rig import LaserCaptureConfig
    from core.config import load_config

    return load_config(LaserCaptureConfig, path)


def _laser_config():
    from reconstruct.laser.pipeline import LaserReconConfig

    return LaserReconConfig()


def _laser_capture(scene, config, out_dir, *, rng: np.random.Generator, seed: int = 0,
                   scene_path=None) -> Path:
    from acquire.laser.capture import capture

    return capture(scene.render_scene, config, out_dir, rng,
                   scene_info=_scene_info(scene, scene_path), seed=seed,
                   gt_mesh=scene.gt_mesh())


def _laser_run(config, capture_dir, out_dir) -> Result:
    from reconstruct.laser.pipeline import run

    out = run(config, capture_dir, out_dir)
    return Result(Path(out), _report(out))


# -- stereo, active stereo, structured light -------------------------------------------------
def _stereo_load(path):
    from acquire.stereo.rig import StereoCaptureConfig
    from core.config import load_config

    return load_config(StereoCaptureConfig, path)


def _sl_load(path):
    from acquire.stereo.rig import SLCaptureConfig
    from core.config import load_config

    return load_config(SLCaptureConfig, path)


def _stereo_config():
    from reconstruct.stereo.options import StereoOptions

    return StereoOptions()


def _active_stereo_config():
    return dataclasses.replace(_stereo_config(), mode="active", compare=False)


def _stereo_capture(scene, config, out_dir, *, rng: np.random.Generator, seed: int = 0,
                    scene_path=None) -> Path:
    from acquire.stereo.capture import capture

    info = {**_scene_info(scene, scene_path),
            "textureless": bool(getattr(config, "textureless", False))}
    return capture(scene.render_scene, config, out_dir, rng, scene_info=info, seed=seed,
                   object_name=_object_name(scene, config))


def _stereo_run(config, capture_dir, out_dir) -> Result:
    from reconstruct.stereo.pipeline import run_capture

    out = run_capture(capture_dir, out_dir, config)
    return Result(Path(out), _report(out))


def _sl_config():
    from reconstruct.stereo.sl_pipeline import SLOptions

    return SLOptions()


def _sl_capture(scene, config, out_dir, *, rng: np.random.Generator, seed: int = 0,
                scene_path=None) -> Path:
    from acquire.stereo.capture_sl import capture

    return capture(scene.render_scene, config, out_dir, rng,
                   scene_info=_scene_info(scene, scene_path), seed=seed,
                   object_name=_object_name(scene, config))


def _sl_run(config, capture_dir, out_dir) -> Result:
    from reconstruct.stereo.sl_pipeline import run_capture

    out = run_capture(capture_dir, out_dir, config)
    return Result(Path(out), _report(out))


# -- structure from motion -------------------------------------------------------------------
def _sfm_load(path):
    from acquire.sfm.capture import SfmCaptureConfig
    from core.config import load_config

    return load_config(SfmCaptureConfig, path)


def _sfm_config():
    from reconstruct.sfm.pipeline import SfmConfig

    return SfmConfig()


def _sfm_capture(scene, config, out_dir, *, rng: np.random.Generator, seed: int = 0,
                 scene_path=None) -> Path:
    from acquire.sfm.capture import capture

    ref = {"name": scene.name, "seed": scene.seed,
           "path": None if scene_path is None else str(scene_path)}
    return capture(scene.render_scene, config, out_dir, rng=rng, scene_ref=ref,
                   gt_mesh=scene.gt_mesh(), seed=seed)


def _sfm_run(config, capture_dir, out_dir) -> Result:
    from reconstruct.sfm.pipeline import run

    res = run(config, capture_dir, out_dir)
    return Result(Path(res.out_dir), res.report, res.ok, res.message)


METHODS: dict[str, Method] = {
    "laser": Method("laser", "laser triangulation (turntable or stage)", _laser_load,
                    _laser_config, _laser_capture, _laser_run),
    "stereo": Method("stereo", "stereo (passive, and active when the rig projects)",
                     _stereo_load, _stereo_config, _stereo_capture, _stereo_run),
    "active-stereo": Method("active-stereo", "active stereo (random-dot projector)",
                            _stereo_load, _active_stereo_config, _stereo_capture,
                            _stereo_run),
    "structured-light": Method("structured-light", "structured light (Gray code + phase)",
                               _sl_load, _sl_config, _sl_capture, _sl_run),
    "sfm": Method("sfm", "structure from motion (pycolmap + dense surface)", _sfm_load,
                  _sfm_config, _sfm_capture, _sfm_run),
}


def get_method(name: str) -> Method:
    """The row of ``name``; ValueError listing the methods otherwise."""
    from core.validate import check_choice

    return METHODS[check_choice(name, "method", METHODS)]
