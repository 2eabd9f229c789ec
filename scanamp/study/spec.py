"""Study specs: a TOML file -> a validated :class:`Study` and its list of :class:`Run`.

Format (``scanamp/studies/*.toml`` are the shipped examples)::

    [study]
    name = "laser-angle"
    kind = "laser"            # laser | stereo | structured-light | sfm | peak-detector |
                              # amplified-laser
    scene = "object"          # built-in scene name, scene folder or .toml (relative to this file)
    seed = 0                  # every run uses it (common random numbers) unless "seed" is swept
    mode = "grid"             # grid (Cartesian product) or random
    n = 20                    # random mode: number of runs

    [base]                    # dotted overrides applied to every run
    "rig.steps" = 120

    [sweep]                   # grid: lists; random: {min, max} (+ log, integer) or {choices}
    "rig.triangulation_angle_deg" = [10, 30, 50]

    [output]
    metrics = ["evaluation.depth_error.rms_m"]   # dotted keys into each run's report.json

A dotted key names a field of the capture config (the TOML file that
``scanamp capture KIND --config`` reads: ``rig.steps``, ``sensor.read_noise``; flat
keys such as ``views`` for SfM), a reconstruction option (``reconstruct.detector``,
``reconstruct.surface.meshing.depth``: fields of the kind's reconstruction config dataclass), or
``seed``. Every run's config is built and validated when the study is loaded, by the
same loaders the capture and reconstruct commands use, so a bad key or value fails
before anything runs, with an error naming the study file and the field.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import re
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from core.files import read_toml, require
from core.validate import InputError

__all__ = ["Run", "Study", "load_study", "shipped_studies", "study_path", "run_id"]

MODES = ("grid", "random")
_NUM = (int, float)


@dataclass(frozen=True)
class Run:
    """One cell of a study: its id, the swept values and the full override set.

    Attributes
    ----------
    run_id : str
        Deterministic from the kind, scene, seed and every override (readable prefix
        from the swept values, then a hash).
    params : dict
        The swept values of this run (dotted key -> value).
    overrides : dict
        ``[base]`` merged with ``params`` (dotted key -> value).
    seed : int
    """

    run_id: str
    params: dict
    overrides: dict
    seed: int


@dataclass
class Study:
    """A loaded, validated study spec."""

    name: str
    kind: str
    scene: str
    seed: int
    mode: str
    base: dict
    sweep: dict
    metrics: list
    path: Path | None = None
    runs: list = field(default_factory=list)

    @property
    def params(self) -> list[str]:
        """The swept keys, in file order."""
        return list(self.sweep)


def shipped_studies() -> list[str]:
    """Names of the shipped studies (``scanamp/studies/*.toml``)."""
    return sorted(p.name[:-5] for p in resources.files("scanamp.studies").iterdir()
                  if p.name.endswith(".toml") and not p.name.startswith("_"))


def study_path(name_or_path: str | Path) -> Path:
    """A study file from a shipped name (``laser-angle``) or a path."""
    p = Path(name_or_path)
    if p.suffix == ".toml" or p.exists() or str(name_or_path) not in shipped_studies():
        return p
    return Path(str(resources.files("scanamp.studies") / f"{name_or_path}.toml"))


def _slug(v: Any) -> str:
    s = f"{v:g}" if isinstance(v, float) else str(v)
    return re.sub(r"[^A-Za-z0-9.+-]+", "_", s)


def run_id(kind: str, scene: str, seed: int, overrides: dict, params: dict) -> str:
    """Deterministic id: swept values for reading, a hash of everything for safety.

    Editing ``[base]`` (or the scene, seed, kind) changes every id, so a resumed study
    never mixes runs made under another configuration.
    """
    blob = json.dumps({"kind": kind, "scene": scene, "seed": seed,
                       "overrides": {k: overrides[k] for k in sorted(overrides)}},
                      sort_keys=True, default=str)
    digest = hashlib.sha256(blob.encode()).hexdigest()[:10]
    parts = [f"{k.rsplit('.', 1)[-1]}={_slug(v)}" for k, v in params.items()]
    head = "_".join(parts)[:80] or "run"
    return f"{head}-{digest}"


def _is_scalar(v) -> bool:
    return isinstance(v, (bool, int, float, str))


def _dotted(table: dict, *, path, section: str) -> dict:
    """Flatten nested TOML tables (``[base.rig]``) into dotted keys."""
    out: dict = {}

    def walk(t, prefix):
        for k, v in t.items():
            key = f"{prefix}.{k}" if prefix else k
            if isinstance(v, dict):
                walk(v, key)
            else:
                out[key] = v

    walk(table, "")
    for k in out:
        if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*", k):
            raise InputError("expected a dotted parameter key (letters, digits, _ and .)",
                             path=path, field=f"{section}.{k}")
    return out


def _grid(sweep: dict, *, path) -> list[dict]:
    for k, values in sweep.items():
        f = f"sweep.{k}"
        if not isinstance(values, list):
            raise InputError(f"expected a list of values (grid mode), got {values!r}",
                             path=path, field=f)
        if not values:
            raise InputError("expected at least one value, got an empty list", path=path,
                             field=f)
        if len({json.dumps(v, sort_keys=True) for v in values}) != len(values):
            raise InputError(f"expected distinct values, got {values!r}", path=path, field=f)
    keys = list(sweep)
    return [dict(zip(keys, combo, strict=True))
            for combo in itertools.product(*(sweep[k] for k in keys))]


def _random(sweep: dict, n: int, rng: np.random.Generator, *, path) -> list[dict]:
    """``n`` draws; each key ``{min, max}`` (uniform; ``log = true`` log-uniform,
    ``integer = true`` rounded) or ``{choices = [...]}``; drawn key by key in file order."""
    specs = {}
    for k, spec in sweep.items():
        f = f"sweep.{k}"
        if not isinstance(spec, dict):
            raise InputError("expected {min, max} or {choices = [...]} (random mode), got "
                             f"{spec!r}", path=path, field=f)
        unknown = set(spec) - {"min", "max", "log", "integer", "choices"}
        if unknown:
            raise InputError(f"unknown key {sorted(unknown)[0]!r}; expected min, max, log, "
                             "integer or choices", path=path, field=f)
        if "choices" in spec:
            ch = require(spec, "choices", list, path=path, prefix=f)
            if not ch:
                raise InputError("expected at least one choice", path=path, field=f"{f}.choices")
            specs[k] = ("choice", ch)
            continue
        lo = require(spec, "min", float, path=path, prefix=f)
        hi = require(spec, "max", float, path=path, prefix=f)
        log = require(spec, "log", bool, path=path, prefix=f, default=False)
        integer = require(spec, "integer", bool, path=path, prefix=f, default=False)
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise InputError(f"expected finite min < max, got {lo!r}, {hi!r}", path=path,
                             field=f)
        if log and lo <= 0:
            raise InputError(f"log: expected min > 0, got {lo!r}", path=path, field=f"{f}.min")
        specs[k] = ("log" if log else "uniform", (lo, hi, integer))
    draws = []
    for _ in range(n):
        d = {}
        for k, (how, arg) in specs.items():
            if how == "choice":
                d[k] = arg[int(rng.integers(len(arg)))]
                continue
            lo, hi, integer = arg
            x = (math.exp(rng.uniform(math.log(lo), math.log(hi))) if how == "log"
                 else float(rng.uniform(lo, hi)))
            d[k] = int(round(x)) if integer else float(f"{x:.6g}")
        draws.append(d)
    return draws


def load_study(name_or_path: str | Path, *, validate: bool = True) -> Study:
    """Read, validate and expand a study (a shipped name or a TOML path).

    Parameters
    ----------
    name_or_path : str or Path
        ``"laser-angle"`` or ``"my_study.toml"``.
    validate : bool
        Build every run's capture and reconstruction config now (cheap; catches unknown
        keys and bad values before anything runs).

    Raises
    ------
    InputError
        Naming the file and the field: ``study.toml: sweep: expected at least one
        parameter``, ``study.toml: sweep.rig.angle: unknown field ...``.
    """
    from scanamp.study.kinds import KINDS, validate_run

    path = study_path(name_or_path)
    data = read_toml(path)
    for key in data:
        if key not in ("study", "base", "sweep", "output"):
            raise InputError("unknown table; expected study, base, sweep or output", path=path,
                             field=key)
    st = require(data, "study", dict, path=path)
    for key in st:
        if key not in ("name", "kind", "scene", "seed", "mode", "n"):
            raise InputError("unknown key; expected name, kind, scene, seed, mode or n",
                             path=path, field=f"study.{key}")
    name = require(st, "name", str, path=path, prefix="study", default=path.stem)
    kind = require(st, "kind", str, path=path, prefix="study")
    public = sorted(k for k in KINDS if not k.startswith("_"))
    if kind not in KINDS:
        raise InputError(f"unknown kind; expected one of {', '.join(public)}, got {kind!r}",
                         path=path, field="study.kind")
    scene = require(st, "scene", str, path=path, prefix="study", default="object")
    scene = _resolve_scene(scene, path)
    seed = require(st, "seed", int, path=path, prefix="study", default=0)
    mode = require(st, "mode", str, path=path, prefix="study", default="grid")
    if mode not in MODES:
        raise InputError(f"expected one of {', '.join(MODES)}, got {mode!r}", path=path,
                         field="study.mode")
    base = _dotted(require(data, "base", dict, path=path, default={}), path=path, section="base")
    for k, v in base.items():
        if not (_is_scalar(v) or (isinstance(v, list) and all(_is_scalar(x) for x in v))):
            raise InputError(f"expected a value, got {v!r}", path=path, field=f"base.{k}")
    raw_sweep = require(data, "sweep", dict, path=path, default={})
    sweep = _dotted(raw_sweep, path=path, section="sweep") if mode == "grid" else _random_keys(
        raw_sweep, path=path)
    if not sweep:
        raise InputError("expected at least one swept parameter, got an empty sweep",
                         path=path, field="sweep")
    out = require(data, "output", dict, path=path, default={})
    metrics = require(out, "metrics", list, path=path, prefix="output", default=None)
    if metrics is None:
        metrics = list(KINDS[kind].default_metrics)
    for i, m in enumerate(metrics):
        if not isinstance(m, str) or not m:
            raise InputError(f"expected a dotted key into report.json, got {m!r}", path=path,
                             field=f"output.metrics[{i}]")
    if mode == "grid":
        if "n" in st:
            raise InputError("only with mode = \"random\"", path=path, field="study.n")
        cells = _grid(sweep, path=path)
    else:
        n = require(st, "n", int, path=path, prefix="study")
        if n < 1:
            raise InputError(f"expected a positive integer, got {n}", path=path, field="study.n")
        cells = _random(sweep, n, np.random.default_rng(seed), path=path)
    study = Study(name, kind, scene, seed, mode, base, sweep, metrics, path)
    seen = set()
    for params in cells:
        over = {**base, **params}
        rseed = over.pop("seed", seed)
        if isinstance(rseed, bool) or not isinstance(rseed, int):
            raise InputError(f"expected an integer, got {rseed!r}", path=path,
                             field="sweep.seed" if "seed" in sweep else "base.seed")
        rid = run_id(kind, scene, rseed, over, params)
        if rid in seen:  # random draws of choices can repeat a cell: one run is enough
            continue
        seen.add(rid)
        study.runs.append(Run(rid, params, over, rseed))
    if validate:
        for run in study.runs:
            validate_run(study, run)
    return study


def _random_keys(raw: dict, *, path) -> dict:
    """Random-mode sweep: top-level dotted keys whose values are tables of the draw spec."""
    out = {}

    def walk(t, prefix):
        for k, v in t.items():
            key = f"{prefix}.{k}" if prefix else k
            if isinstance(v, dict) and not ({"min", "max", "choices"} & set(v)):
                walk(v, key)
            else:
                out[key] = v

    walk(raw, "")
    return out


def _resolve_scene(scene: str, study_file: Path) -> str:
    from data_synth.scenes import scene_names

    if scene in scene_names():
        return scene
    p = Path(scene)
    if not p.is_absolute():
        p = Path(study_file).parent / p
    if not p.exists():
        raise InputError(f"expected a built-in scene ({', '.join(scene_names())}), a scene "
                         f"folder or a .toml spec, got {scene!r}", path=study_file,
                         field="study.scene")
    return str(p.resolve())
