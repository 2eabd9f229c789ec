"""The one protocol every acquisition method follows, and the scene helpers they share.

A method (:class:`Method`) declares its capture config and its reconstruction config
(the dataclasses ``scanamp capture NAME`` and ``scanamp reconstruct NAME`` read their flags
from, and the studies their overrides), and implements:

- :meth:`~Method.capture` — a virtual capture of a scene bundle into a folder;
- :meth:`~Method.reconstruct` — a capture (or real data) into a reconstruction folder,
  returning a :class:`reconstruct.result.ReconstructionResult` that holds the report;
- :meth:`~Method.evaluate` — what a study records of one capture-and-reconstruct run;
- :attr:`~Method.frame` and :meth:`~Method.world_from_output` — the frame its output is
  written in, and how a virtual capture's output is carried into the scene's world frame.

The rest (the scene a capture renders, which capture files the reconstruction reads, the
arguments and log lines of its reconstruct command) has defaults a method overrides when
it differs. The registry (:mod:`scanamp.methods`) holds one instance per method; the CLI,
the studies and the demo reach methods only through it.
"""

from __future__ import annotations

import abc
import argparse
import copy
import os
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

__all__ = ["Method", "add_from_stage", "scene_for_capture", "without_textures", "scene_info",
           "object_name", "world_from_table"]


class Method(abc.ABC):
    """One acquisition method (see the module docstring).

    Class attributes: ``name`` (the ``KIND`` of ``scanamp capture KIND`` and ``scanamp
    reconstruct KIND``, and the study kind), ``title``, ``capture_help`` and
    ``reconstruct_help`` (the commands' help), ``capture_config`` and ``recon_config``
    (config dataclasses, :mod:`core.config`), ``frame`` (the frame the reconstruction's
    files are in), ``metrics`` (what a study of it reports when it names none),
    ``takes_materials`` (whether a study's ``material.*`` overrides apply to its scenes).
    """

    name: ClassVar[str]
    title: ClassVar[str]
    capture_help: ClassVar[str]
    reconstruct_help: ClassVar[str]
    capture_config: ClassVar[type]
    recon_config: ClassVar[type]
    frame: ClassVar[str]
    metrics: ClassVar[tuple[str, ...]]
    takes_materials: ClassVar[bool] = True

    # -- configs ---------------------------------------------------------------------------
    def load_capture_config(self, path: str | os.PathLike | None):
        """The capture config of a TOML file (None: the defaults), as ``--config`` reads it."""
        from core.config import load_config

        return load_config(self.capture_config, path)

    def default_recon_config(self):
        """The reconstruction config a study starts from (the command's defaults)."""
        return self.recon_config()

    def seeded(self, recon_config, seed: int):
        """The reconstruction config of a study run seeded ``seed`` (unchanged unless the
        reconstruction itself draws random numbers)."""
        return recon_config

    # -- capture ---------------------------------------------------------------------------
    def scene(self, bundle, config):
        """The scene bundle the capture renders for ``config`` (the scene as built)."""
        return bundle

    def check_scene(self, bundle) -> None:
        """Raise InputError when ``bundle`` lacks the truth :meth:`evaluate` needs (any
        scene with a ground-truth mesh will do by default)."""
        return None

    @abc.abstractmethod
    def capture(self, bundle, config, out_dir: str | os.PathLike, *,
                rng: np.random.Generator, seed: int = 0,
                scene_path: str | os.PathLike | None = None) -> Path:
        """Capture ``bundle`` (a :class:`data_synth.scenes.SceneBundle`) with ``config``
        into ``out_dir``; the folder. ``scene_path``: the scene as the user named it (a
        built-in name, a folder or a TOML file), recorded in the capture; None: the
        bundle's name."""

    # -- reconstruction --------------------------------------------------------------------
    def inputs(self, capture_dir: str | os.PathLike) -> Any:
        """What :meth:`reconstruct` reads of a capture folder this method wrote."""
        return Path(capture_dir)

    @abc.abstractmethod
    def reconstruct(self, config, inputs, out_dir: str | os.PathLike, **options):
        """Reconstruct ``inputs`` (a capture folder, or the method's real data) into
        ``out_dir``; a :class:`reconstruct.result.ReconstructionResult`."""

    def evaluate(self, capture_dir: Path, result, bundle) -> dict:
        """What a study records of a run: by default the reconstruction's report, which
        already scores the output against the capture's ground truth."""
        return result.report

    def world_from_output(self, capture_config, capture_dir: Path, result) -> np.ndarray:
        """(4, 4) float64: the scene's world frame from the frame of ``result``'s files
        (:attr:`frame`), for a virtual capture made with ``capture_config``."""
        return np.eye(4)

    # -- the reconstruct command -----------------------------------------------------------
    def add_reconstruct_arguments(self, parser: argparse.ArgumentParser) -> None:
        """The inputs of ``scanamp reconstruct NAME`` (besides ``--out`` and the config's
        flags): by default one capture folder."""
        parser.add_argument("capture", type=Path,
                            help=f"capture folder written by 'scanamp capture {self.name}'")

    def reconstruct_from_args(self, config, args: argparse.Namespace):
        """Run :meth:`reconstruct` on what :meth:`add_reconstruct_arguments` parsed."""
        return self.reconstruct(config, args.capture, args.out)

    def describe(self, result) -> list[str]:
        """The lines ``scanamp reconstruct NAME`` logs about ``result``."""
        return [f"wrote {result.out_dir}"]


def add_from_stage(parser: argparse.ArgumentParser, stages) -> None:
    """``--from STAGE`` of a staged pipeline's reconstruct command
    (:class:`core.runs.stages.Stages`)."""
    parser.add_argument("--from", dest="from_stage", choices=stages, default=None,
                        help="re-run from this stage on (" + " -> ".join(stages) + "); without "
                             "it a stage whose options and inputs are unchanged is reused from "
                             "--out")


# -- scenes --------------------------------------------------------------------------------
def scene_for_capture(scene: str, *, textureless: bool = False):
    """The scene bundle a capture command renders: a built-in name, scene folder or TOML;
    ``textureless`` gives every object a constant material (passive stereo fails there)."""
    from data_synth.scenes import build_scene

    bundle = build_scene(scene)
    return without_textures(bundle) if textureless else bundle


def without_textures(bundle):
    """``bundle`` with every object's texture replaced by its constant albedo (the
    reflectance model kept)."""
    from data_synth.scenes import build_scene

    spec = copy.deepcopy(bundle.spec)
    for obj in spec.get("objects", []):
        mat = obj.get("material", {})
        keep = {k: v for k, v in mat.items()
                if k not in ("kind", "texture", "scale", "contrast", "seed", "albedo")}
        obj["material"] = {"kind": "constant",
                           "albedo": mat.get("albedo", [0.7, 0.7, 0.7]), **keep}
    return build_scene(spec)


def scene_info(bundle, scene_path) -> dict:
    """The scene as a capture records it: its path (else its name), name and seed."""
    return {"path": str(scene_path) if scene_path is not None else bundle.name,
            "name": bundle.name, "seed": bundle.seed}


def object_name(bundle, config=None) -> str | None:
    """The scanned object: the config's ``object``, else 'object' when the scene has one."""
    names = [o.name for o in bundle.render_scene.objects]
    chosen = getattr(config, "object", None)
    if chosen is not None and chosen not in names:
        raise ValueError(f"object: expected one of {', '.join(names)}, got {chosen!r}")
    return chosen or ("object" if "object" in names else None)


def world_from_table(report: dict, table_key: str, rig) -> np.ndarray:
    """The world from the calibrated turntable frame of a stereo or structured-light
    report: the identity when the axis board sat in the platter's jig (the table frame
    *is* the world), else through the true pose of the rig's left camera (the
    structured-light rig's camera)."""
    cal = report["calibration"]
    if cal["axis"].get("method") == "mount":
        return np.eye(4)
    left, _ = rig.stereo_cameras()
    return left.world_from_cam @ np.linalg.inv(np.asarray(cal[table_key]))
