"""The ``amplified-laser`` study kind: amplify one object of a scene, put it back, scan the
scene with the laser rig and reconstruct it, so a study can sweep an amplification
parameter (``amplify.amplitude``) and read the scanner's figures on the amplified object
(its ground truth is the amplified surface).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from acquire.laser.rig import LaserCaptureConfig
from core.config import Config, option

__all__ = ["AmplifyStudyOptions", "AmplifiedLaserConfig", "run_amplified"]


@dataclass
class AmplifyStudyOptions(Config):
    """The ``[amplify]`` table of the ``amplified-laser`` kind."""

    recipe: str = option("displace", help="amplification recipe (a shipped name or TOML)")
    object: str = option("object", help="the scene object that is amplified")
    amplitude: float | None = option(None, range="[0, 10]",
                                     help="override of every displace step's amplitude")


@dataclass
class AmplifiedLaserConfig(LaserCaptureConfig):
    """A laser capture of the scene with one object amplified first."""

    amplify: AmplifyStudyOptions = option(default_factory=AmplifyStudyOptions,
                                          help="what is amplified, and how")


def run_amplified(bundle, cap_cfg: AmplifiedLaserConfig, rec_cfg, *, seed: int, work: Path,
                  scene_path=None) -> dict:
    """Amplify (up +z, the scene's), rebuild the scene around the result, capture and
    reconstruct; the reconstruction's report with ``amplify`` added, plus ``ok`` and
    ``message``."""
    from core.files import read_json
    from core.io.mesh import write_mesh
    from data_synth.scenes import build_scene
    from scanamp.amplify import load_recipe
    from scanamp.amplify import run as amplify_run
    from scanamp.methods import get_method

    opt = cap_cfg.amplify
    work = Path(work)
    obj_path = write_mesh(work / "object.ply", bundle.object_mesh(opt.object))
    recipe = load_recipe(opt.recipe)
    if opt.amplitude is not None:
        for step in recipe.steps:
            if step.kind == "displace":
                step.params["amplitude"] = float(opt.amplitude)
    amp = amplify_run(obj_path, recipe, work / "amplified", seed=seed, up=(0.0, 0.0, 1.0))
    surface = amp / "surface.ply" if (amp / "surface.ply").is_file() else amp / "mesh.ply"
    spec = copy.deepcopy(bundle.spec)
    for i, o in enumerate(spec["objects"]):
        if o.get("name") == opt.object:
            spec["objects"][i] = {"name": opt.object, "shape": "mesh", "path": str(surface),
                                  **({"material": o["material"]} if "material" in o else {})}
    method = get_method("laser")
    cap = method.capture(build_scene(spec), cap_cfg, work / "capture",
                         rng=np.random.default_rng(seed), seed=seed, scene_path=scene_path)
    res = method.reconstruct(rec_cfg, cap, work / "reconstruction")
    amp_rep = read_json(amp / "report.json")
    return {**res.report, "ok": res.ok, "message": res.message,
            "amplify": {"recipe": recipe.name, "amplitude": opt.amplitude,
                        "input": amp_rep["input"], "output": amp_rep["output"]}}
