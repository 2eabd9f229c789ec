"""Capture folders: ``capture.json`` (``"format": "scanamp.capture/1"``), ``images/``, ``gt/``.

Layout of capture.json (kind-specific keys may be added inside ``rig``, frames and
calibration entries)::

    {
      "format": "scanamp.capture/1",
      "kind": "laser" | "stereo" | "structured-light" | "sfm" | "views" | "scans",
      "seed": 0,
      "scene": {"path": "...", "name": "object", "seed": 0},
      "sensor": {...Sensor settings...},
      "cameras": {"cam0": {"width": 640, "height": 480, ...nominal data a user knows}},
      "projectors": {...},
      "rig": {...},
      "frames": [{"image": "images/0000.png", "camera": "cam0", ...per-frame metadata}],
      "calibration": [{"kind": "camera", "images": [...], "target": {...}, ...}],
      "ground_truth": {...}   # for evaluation only: never read by a reconstruction
    }

Every path is relative to the capture folder. :func:`load_capture` checks the
structure and that every referenced file exists, and names the bad field.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from core.files import read_json, write_json
from core.validate import InputError

__all__ = ["FORMAT", "KINDS", "Capture", "load_capture", "write_capture"]

FORMAT = "scanamp.capture/1"
KINDS = ("laser", "stereo", "structured-light", "sfm", "views", "scans")


@dataclass
class Capture:
    """A loaded, validated capture folder."""

    root: Path
    data: dict

    @property
    def kind(self) -> str:
        return self.data["kind"]

    @property
    def frames(self) -> list[dict]:
        return self.data["frames"]

    @property
    def calibration(self) -> list[dict]:
        return self.data.get("calibration", [])

    @property
    def cameras(self) -> dict:
        return self.data.get("cameras", {})

    @property
    def rig(self) -> dict:
        return self.data.get("rig", {})

    @property
    def ground_truth(self) -> dict | None:
        """Ground truth for evaluation only (None for real captures)."""
        return self.data.get("ground_truth")

    def path(self, rel: str) -> Path:
        return self.root / rel

    def __getitem__(self, key: str) -> Any:
        return self.data[key]


def _check(cond: bool, msg: str, path: Path, field: str):
    if not cond:
        raise InputError(msg, path=path, field=field)


def _check_files(entry: dict, prefix: str, root: Path, jpath: Path):
    for key in ("image", "depth", "mask"):
        if key in entry:
            _check(isinstance(entry[key], str), "expected a relative path", jpath,
                   f"{prefix}.{key}")
            _check((root / entry[key]).is_file(), f"file not found: {entry[key]}", jpath,
                   f"{prefix}.{key}")
    if "images" in entry:
        imgs = entry["images"]
        _check(isinstance(imgs, list) and len(imgs) > 0, "expected a non-empty list", jpath,
               f"{prefix}.images")
        for j, rel in enumerate(imgs):
            if isinstance(rel, list):  # e.g. stereo pairs or pattern stacks
                for k, r in enumerate(rel):
                    _check((root / r).is_file(), f"file not found: {r}", jpath,
                           f"{prefix}.images[{j}][{k}]")
            else:
                _check(isinstance(rel, str) and (root / rel).is_file(),
                       f"file not found: {rel}", jpath, f"{prefix}.images[{j}]")


def validate_capture(data: Any, root: Path, jpath: Path) -> dict:
    """Check the structure of capture.json data; InputError naming the bad field."""
    _check(isinstance(data, dict), "expected a JSON object", jpath, "")
    _check(data.get("format") == FORMAT, f"expected {FORMAT!r}, got {data.get('format')!r}",
           jpath, "format")
    _check(data.get("kind") in KINDS,
           f"expected one of {', '.join(KINDS)}, got {data.get('kind')!r}", jpath, "kind")
    cams = data.get("cameras", {})
    _check(isinstance(cams, dict), "expected a table of cameras", jpath, "cameras")
    for name, cam in cams.items():
        for key in ("width", "height"):
            v = cam.get(key) if isinstance(cam, dict) else None
            _check(isinstance(v, int) and not isinstance(v, bool) and v > 0,
                   f"expected a positive integer, got {v!r}", jpath, f"cameras.{name}.{key}")
    frames = data.get("frames")
    _check(isinstance(frames, list), "expected a list", jpath, "frames")
    for i, fr in enumerate(frames):
        _check(isinstance(fr, dict), "expected an object", jpath, f"frames[{i}]")
        if "camera" in fr:
            _check(fr["camera"] in cams, f"unknown camera {fr['camera']!r}", jpath,
                   f"frames[{i}].camera")
        _check_files(fr, f"frames[{i}]", root, jpath)
    calib = data.get("calibration", [])
    _check(isinstance(calib, list), "expected a list", jpath, "calibration")
    for i, c in enumerate(calib):
        _check(isinstance(c, dict) and isinstance(c.get("kind"), str),
               "expected an object with a 'kind'", jpath, f"calibration[{i}]")
        _check_files(c, f"calibration[{i}]", root, jpath)
    return data


def load_capture(path: str | os.PathLike) -> Capture:
    """Load and validate a capture folder (or its capture.json)."""
    p = Path(path)
    jpath = p / "capture.json" if p.is_dir() else p
    if not jpath.is_file():
        raise InputError("not a capture folder (no capture.json)", path=p)
    data = read_json(jpath)
    root = jpath.parent
    return Capture(root=root, data=validate_capture(data, root, jpath))


def write_capture(out_dir: str | os.PathLike, data: dict) -> Path:
    """Write ``capture.json`` into ``out_dir`` after validating it against the files there."""
    out = Path(out_dir)
    data = {"format": FORMAT, **{k: v for k, v in data.items() if k != "format"}}
    validate_capture(data, out, out / "capture.json")
    return write_json(out / "capture.json", data)
