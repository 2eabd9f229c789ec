"""What one study run does, per kind: build the configs, capture, reconstruct, report.

Every registered acquisition method (:mod:`scanamp.methods`) is a kind of the same name
(:func:`method_kind`): there is no second table. A run reads its capture config with the
loader that ``scanamp capture KIND --config FILE`` uses (the run's overrides are written
as that TOML file first, so a study accepts exactly the keys and values the capture
command accepts) and takes its reconstruction options from the reconstruction config
dataclass the ``scanamp reconstruct KIND`` command fills (overridden by
``reconstruct.*`` keys). It captures and reconstructs through the method, and its report
is what the method's ``evaluate`` makes of the reconstruction (by default the
reconstruction's own report, which scores it against the capture's ground truth).

Three kinds are not a method's own run: ``amplified-laser`` (an amplified scene through
the laser scanner, :mod:`scanamp.study.amplified`), ``peak-detector`` and ``_test``.

``peak-detector`` is cheaper: it renders the laser frames of the scan (the same rig,
renderer, speckle and sensor model as ``capture laser``, no calibration captures),
runs one stripe detector of :mod:`reconstruct.laser.stripe` with the laser reconstruction's
own acceptance options, and scores the detected columns against the renderer's true
stripe centre per row. That isolates the detector from calibration and meshing, which
is what a scanner engineer compares detectors on (Fisher & Naidu 1996 did the same
on synthetic stripes); the laser kind with ``reconstruct.detector`` swept gives the
end-to-end view.

``_test`` (hidden, for the runner's own tests) computes ``y = x**2`` and can sleep,
fail, or leave a marker file per execution.
"""

from __future__ import annotations

import dataclasses
import os
import tempfile
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from core.files import read_toml, write_toml
from core.validate import InputError

__all__ = ["KINDS", "Kind", "method_kind", "split_overrides", "build_configs", "validate_run",
           "get_metric", "material_overrides", "MATERIAL_KEYS"]

# ``material.*`` overrides change the scanned object's material in the scene (any kind
# that captures a scene): its reflectance model and parameters, the rest of it (colour,
# texture) kept. ``material.preset`` names a set of them
# (:data:`acquire.render.materials.MATERIAL_PRESETS`); ``material.object`` names the object
# (default: ``object``).
MATERIAL_KEYS = ("object", "preset", "brdf", "roughness", "ior", "mfp", "anisotropy", "albedo")


@dataclass(frozen=True)
class Kind:
    """A study kind: how to read its capture config, its reconstruction defaults,
    how to execute one run, and the metrics reported when the study names none."""

    name: str
    load_capture: Callable[[Path], Any]
    recon_default: Callable[[], Any]
    execute: Callable[..., dict]
    default_metrics: tuple


# -- override plumbing -------------------------------------------------------------------
def split_overrides(overrides: dict) -> tuple[dict, dict]:
    """Dotted overrides -> (nested capture-config TOML tables, reconstruction options)."""
    cap: dict = {}
    rec: dict = {}
    for key, value in overrides.items():
        if key.startswith("material."):
            continue            # the scene's, not a config's: material_overrides
        if key.startswith("reconstruct."):
            rec[key[len("reconstruct."):]] = value
            continue
        t = cap
        parts = key.split(".")
        for p in parts[:-1]:
            nxt = t.setdefault(p, {})
            if not isinstance(nxt, dict):
                raise InputError(f"{p!r} is both a value and a table", field=key)
            t = nxt
        if isinstance(t.get(parts[-1]), dict):
            raise InputError(f"{parts[-1]!r} is both a value and a table", field=key)
        t[parts[-1]] = value
    return cap, rec


def _type_ok(default: Any, value: Any) -> bool:
    if default is None:
        return True
    if isinstance(default, bool):
        return isinstance(value, bool)
    if isinstance(value, bool):
        return False
    if isinstance(default, int):
        return isinstance(value, int)
    if isinstance(default, float):
        return isinstance(value, (int, float))
    if isinstance(default, str):
        return isinstance(value, str)
    if isinstance(default, (tuple, list)):
        return isinstance(value, list)
    return True


def apply_options(obj: Any, options: dict, *, prefix: str = "reconstruct") -> Any:
    """A copy of dataclass ``obj`` with dotted ``options`` (``meshing.depth``) replaced.

    Raises ValueError ``reconstruct.<key>: ...`` for unknown keys, wrong types and
    values the dataclass rejects.
    """
    names = {f.name for f in dataclasses.fields(obj)}
    nested: dict[str, dict] = {}
    flat: dict = {}
    for key, value in options.items():
        head, _, rest = key.partition(".")
        if head not in names:
            raise InputError(f"unknown reconstruction option; expected one of "
                             f"{', '.join(sorted(names))}", field=f"{prefix}.{head}")
        cur = getattr(obj, head)
        if rest:
            if not dataclasses.is_dataclass(cur):
                raise InputError("not a table of options", field=f"{prefix}.{head}")
            nested.setdefault(head, {})[rest] = value
            continue
        if dataclasses.is_dataclass(cur) or not _type_ok(cur, value):
            kind = type(cur).__name__ if cur is not None else "a value"
            raise InputError(f"expected {kind}, got {value!r}", field=f"{prefix}.{key}")
        flat[key] = tuple(value) if isinstance(cur, tuple) else value
    for head, sub in nested.items():
        flat[head] = apply_options(getattr(obj, head), sub, prefix=f"{prefix}.{head}")
    try:
        return dataclasses.replace(obj, **flat)
    except (TypeError, ValueError) as exc:
        msg = str(exc)
        name, sep, rest = msg.partition(": ")
        if sep and name in names:
            raise InputError(rest, field=f"{prefix}.{name}") from None
        raise InputError(msg, field=prefix) from None


def build_configs(kind: Kind, overrides: dict, toml_path: Path) -> tuple[Any, Any]:
    """Write the capture overrides as ``toml_path`` and read both configs back.

    Errors are :class:`InputError` whose ``field`` is the dotted override key at fault
    when it can be told (``rig.triangulation_angle_deg``, ``reconstruct.detector``).
    """
    cap_tables, rec_opts = split_overrides(overrides)
    write_toml(toml_path, cap_tables)
    try:
        cap_cfg = kind.load_capture(toml_path)
    except InputError as exc:
        raise InputError(exc.message, field=exc.field) from None
    except ValueError as exc:
        raise InputError(str(exc)) from None
    rec_cfg = apply_options(kind.recon_default(), rec_opts)
    return cap_cfg, rec_cfg


def material_overrides(overrides: dict) -> dict:
    """The ``material.*`` overrides of a run as ``{field: value}`` (checked: known
    fields of :class:`acquire.render.materials.Material` and values it accepts)."""
    from acquire.render.materials import MATERIAL_PRESETS, Material

    out = {}
    for key, value in overrides.items():
        if not key.startswith("material."):
            continue
        name = key[len("material."):]
        if name not in MATERIAL_KEYS:
            raise InputError(f"unknown material field; expected one of "
                             f"{', '.join(MATERIAL_KEYS)}", field=key)
        out[name] = value
    if "preset" in out:
        preset = out.pop("preset")
        if preset not in MATERIAL_PRESETS:
            raise InputError(f"expected one of {', '.join(MATERIAL_PRESETS)}, got {preset!r}",
                             field="material.preset")
        out = {**MATERIAL_PRESETS[preset], **out}
    fields = {k: v for k, v in out.items() if k != "object"}
    if fields:
        try:
            Material(**{k: (np.asarray(v, float) if k == "albedo" else v)
                        for k, v in fields.items()})
        except (TypeError, ValueError) as exc:
            name, sep, rest = str(exc).partition(": ")
            raise InputError(rest if sep else str(exc),
                             field=f"material.{name}" if sep else "material") from None
    return out


def validate_run(study, run) -> None:
    """Build one run's configs now; errors name the study file and the override key."""
    kind = KINDS[study.kind]
    try:
        # the overrides go through the capture command's own TOML loader; the file lives
        # only as long as that (the scene is built after it is gone)
        with tempfile.TemporaryDirectory(prefix="scanamp-study-") as tmp:
            build_configs(kind, run.overrides, Path(tmp) / "capture.toml")
        material_overrides(run.overrides)
        if study.kind == "lidar-ground":  # its runs grow their own forests: the spec
            from scanamp.study.lidar_ground import check_scene

            check_scene(study.scene)
        elif study.kind != "_test":
            _scene(study.scene, material_overrides(run.overrides))
    except InputError as exc:
        raise InputError(exc.message, path=study.path,
                         field=_locate(exc.field, study, run)) from None


def _locate(field: str | None, study, run) -> str | None:
    """The study field behind a config field: ``sweep.KEY`` or ``base.KEY``."""
    if not field:
        return None
    for section, keys in (("sweep", study.sweep), ("base", study.base)):
        for k in keys:
            if k == field or k.startswith(field + ".") or field.startswith(k + "."):
                return f"{section}.{k}"
    return field


def get_metric(report: dict, key: str) -> Any:
    """``report["a"]["b"]`` for ``"a.b"`` (list items by index: ``"x.0"``); None if absent."""
    cur: Any = report
    for part in key.split("."):
        if isinstance(cur, dict) and part in cur:
            cur = cur[part]
        elif isinstance(cur, list) and part.lstrip("-").isdigit() and -len(cur) <= int(
                part) < len(cur):
            cur = cur[int(part)]
        else:
            return None
    if isinstance(cur, bool):
        return float(cur)
    if isinstance(cur, (int, float)):
        return cur
    return None if isinstance(cur, (dict, list)) else cur


# -- the kinds ---------------------------------------------------------------------------
def _scene(scene: str, material: dict | None = None):
    """The scene bundle of a run, its scanned object's material changed by the run's
    ``material.*`` overrides."""
    import copy

    from data_synth.scenes import build_scene

    bundle = build_scene(scene)
    if material:
        fields = {k: v for k, v in material.items() if k != "object"}
        name = material.get("object", "object")
        spec = copy.deepcopy(bundle.spec)
        objs = [o for o in spec.get("objects", []) if o.get("name") == name]
        if not objs:
            names = [o.get("name") for o in spec.get("objects", [])]
            raise InputError(f"the scene has no object {name!r}; expected one of "
                             f"{', '.join(map(str, names))}", field="material.object")
        objs[0]["material"] = {**objs[0].get("material", {}), **fields}
        bundle = build_scene(spec)
    info = {"path": scene, "name": bundle.name, "seed": bundle.seed}
    return bundle, info


def _scene_path(scene: str) -> str | None:
    """The scene's file, None for a built-in name."""
    return scene if "/" in scene or scene.endswith(".toml") else None


def _execute(method):
    """A study run of an acquisition method (:mod:`scanamp.methods`): the scene (with the
    run's materials), the capture, the reconstruction and the method's evaluation."""

    def execute(cap_cfg, rec_cfg, *, scene: str, seed: int, work: Path,
                material: dict | None = None) -> dict:
        if material and not method.takes_materials:
            raise InputError(f"a {method.name} study takes no material overrides",
                             field="material")
        bundle, _ = _scene(scene, material)
        method.check_scene(bundle)
        cap = method.capture(method.scene(bundle, cap_cfg), cap_cfg, work / "capture",
                             rng=np.random.default_rng(seed), seed=seed,
                             scene_path=_scene_path(scene))
        res = method.reconstruct(method.seeded(rec_cfg, seed), method.inputs(cap),
                                 work / "reconstruction")
        if not res.ok:
            raise RunFailed(res.message or f"{method.name} failed", res.report)
        return method.evaluate(Path(cap), res, bundle)

    return execute


def method_kind(method) -> Kind:
    """The study kind of an acquisition method: its configs, its run, its metrics."""
    return Kind(method.name, method.load_capture_config, method.default_recon_config,
                _execute(method), tuple(method.metrics))


class RunFailed(RuntimeError):
    """A run whose algorithm failed but still produced a report worth keeping."""

    def __init__(self, message: str, report: dict | None = None):
        super().__init__(message)
        self.report = report or {}


def _run_peaks(cap_cfg, rec_cfg, *, scene: str, seed: int, work: Path,
               material: dict | None = None) -> dict:
    """Render the scan's laser frames, detect the stripe, score against the true centre."""
    from acquire.render.laser_sheet import LaserRenderer
    from core.progress import track
    from reconstruct.laser.pipeline import extract_frames

    bundle, _ = _scene(scene, material)
    rng = np.random.default_rng(seed)
    rig, sensor = cap_cfg.rig, cap_cfg.sensor
    cam0, laser0 = rig.camera(), rig.laser()
    renderer = LaserRenderer(bundle.render_scene, cam0)
    images, truth = [], []
    for k, pos in enumerate(track(rig.frame_positions(), "laser frames")):
        W = rig.world_from_object(pos)
        fr = renderer.frame(cam0.cam_from_world @ W, laser0.transformed(np.linalg.inv(W)),
                            rng=rng)
        images.append(sensor.apply(fr.radiance, rng))
        if len(fr.stripe):
            truth.append(np.column_stack([np.full(len(fr.stripe), k), fr.stripe]))
    cols, saturated = extract_frames(images, rec_cfg.stripe_options(sensor.bit_depth))
    st = np.concatenate(truth) if truth else np.zeros((0, 3))
    report = {"kind": "peak-detector", "detector": rec_cfg.detector,
              "noise": {"read_noise_e": sensor.read_noise,
                        "read_noise_dn": sensor.read_noise * sensor.gain / sensor.full_well
                        * (2 ** sensor.bit_depth - 1)},
              "counts": {"frames": len(images), "true_rows": int(len(st)),
                         "detected_rows": int(np.isfinite(cols).sum()),
                         "saturated_peaks": int(saturated.sum())}}
    report["peak_error"] = score_peaks(cols, st)
    return report


def score_peaks(cols: np.ndarray, truth: np.ndarray, *, gate_px: float = 2.0) -> dict:
    """Detected stripe columns against the true crossings.

    Parameters
    ----------
    cols : (f, h) float64
        Detected column per frame and row (NaN = none).
    truth : (k, 3) float64
        ``frame, row, column`` of every true crossing (a row may hold several).
    gate_px : float
        A detection farther than this from every true crossing of its row is an outlier.

    Returns
    -------
    dict
        ``rms_px``, ``bias_px``, ``mad_px`` (robust sigma), ``p95_px`` of the matched
        errors (detected - true); ``detection_rate`` (true rows detected within the gate),
        ``outlier_rate`` (detections outside the gate).
    """
    f, h = cols.shape
    best = np.full((f, h), np.inf)
    signed = np.full((f, h), np.nan)
    has_truth = np.zeros((f, h), bool)
    for k, r, u in truth:
        k, r = int(k), int(r)
        has_truth[k, r] = True
        d = cols[k, r] - u
        if np.isfinite(d) and abs(d) < best[k, r]:
            best[k, r], signed[k, r] = abs(d), d
    det = np.isfinite(cols)
    matched = det & (best < gate_px)
    e = signed[matched]
    out = {"matched": int(matched.sum()), "true_rows": int(has_truth.sum()),
           "detections": int(det.sum()),
           "detection_rate": float(matched.sum() / max(has_truth.sum(), 1)),
           "outlier_rate": float((det & ~matched).sum() / max(det.sum(), 1))}
    if e.size:
        out.update(rms_px=float(np.sqrt(np.mean(e ** 2))), bias_px=float(np.mean(e)),
                   mad_px=float(1.4826 * np.median(np.abs(e - np.median(e)))),
                   p95_px=float(np.percentile(np.abs(e), 95)))
    else:
        out.update(rms_px=None, bias_px=None, mad_px=None, p95_px=None)
    return out


# -- amplified scenes through a scanner (scanamp.study.amplified) ---------------------------
def _load_amplified(path: Path):
    from core.config import load_config
    from scanamp.study.amplified import AmplifiedLaserConfig

    return load_config(AmplifiedLaserConfig, path)


def _run_amplified(cap_cfg, rec_cfg, *, scene: str, seed: int, work: Path,
                   material: dict | None = None) -> dict:
    from scanamp.study.amplified import run_amplified

    bundle, _ = _scene(scene, material)
    report = run_amplified(bundle, cap_cfg, rec_cfg, seed=seed, work=work,
                           scene_path=_scene_path(scene))
    if not report.pop("ok"):
        raise RunFailed(report.pop("message") or "laser failed", report)
    return report


@dataclass
class _TestConfig:
    """Test-only kind: ``y = x**2``; ``sleep`` seconds; ``fail_above``: raise when x >
    it; ``crash_at``: the worker process dies (``os._exit``) when x equals it;
    ``marker_dir``: one file per completed execution."""

    x: float = 0.0
    sleep: float = 0.0
    fail_above: float = float("inf")
    crash_at: float = float("nan")
    marker_dir: str = ""


def _test_capture(path: Path) -> _TestConfig:
    data = read_toml(path)
    names = {f.name for f in dataclasses.fields(_TestConfig)}
    for k, v in data.items():
        if k not in names:
            raise InputError(f"unknown key; expected one of {', '.join(sorted(names))}",
                             path=path, field=k)
        if k != "marker_dir" and (isinstance(v, bool) or not isinstance(v, (int, float))):
            raise InputError(f"expected a number, got {v!r}", path=path, field=k)
    return _TestConfig(**data)


@dataclass
class _TestRecon:
    scale: float = 1.0


def _run_test(cfg: _TestConfig, rec: _TestRecon, *, scene: str, seed: int, work: Path,
              material: dict | None = None) -> dict:
    time.sleep(cfg.sleep)
    if cfg.x == cfg.crash_at:
        os._exit(9)  # a native crash, as a segfault in a C extension would end the worker
    if cfg.x > cfg.fail_above:
        raise RuntimeError(f"x = {cfg.x:g} is above fail_above = {cfg.fail_above:g}")
    if cfg.marker_dir:
        m = Path(cfg.marker_dir)
        m.mkdir(parents=True, exist_ok=True)
        (m / f"{os.getpid()}-{time.monotonic_ns()}-x{cfg.x:g}.done").write_text(f"{cfg.x!r}\n")
    return {"y": rec.scale * cfg.x ** 2, "x": cfg.x, "seed": seed}


def _lidar_ground_kind() -> Kind:
    """The ground filter on mountainsides (:mod:`scanamp.study.lidar_ground`)."""
    from scanamp.study import lidar_ground as lg

    return Kind("lidar-ground", lg.load_capture, lg.recon_default, lg.execute, lg.METRICS)


class _Kinds(Mapping):
    """The study kinds: one per registered acquisition method (:mod:`scanamp.methods`,
    read at each look-up, so a method registered later is a kind too), then the kinds that
    are not a method's own capture and reconstruction."""

    def _all(self) -> dict[str, Kind]:
        from scanamp.methods import methods

        laser = _laser_kind()
        return {**{name: method_kind(m) for name, m in methods().items()},
                "amplified-laser": Kind("amplified-laser", _load_amplified,
                                        laser.recon_default, _run_amplified,
                                        laser.default_metrics),
                "peak-detector": Kind("peak-detector", laser.load_capture,
                                      laser.recon_default, _run_peaks,
                                      ("peak_error.rms_px", "peak_error.detection_rate",
                                       "peak_error.outlier_rate")),
                "lidar-ground": _lidar_ground_kind(),
                "_test": _TEST_KIND}

    def __getitem__(self, name: str) -> Kind:
        if name == "_test":  # the runner's own tests: no method's modules to load
            return _TEST_KIND
        if name == "lidar-ground":  # grows its own forests: no method's modules either
            return _lidar_ground_kind()
        return self._all()[name]

    def __iter__(self):
        return iter(self._all())

    def __len__(self) -> int:
        return len(self._all())


def _laser_kind() -> Kind:
    from scanamp.methods import get_method

    return method_kind(get_method("laser"))


_TEST_KIND = Kind("_test", _test_capture, _TestRecon, _run_test, ("y",))
KINDS: Mapping[str, Kind] = _Kinds()
