"""scanamp render SCENE --out image.png [--view ...]"""

import logging
from dataclasses import dataclass

import numpy as np

from acquire.camera import Camera
from acquire.render.renderer import render
from acquire.sensor import Sensor
from core.config import Config, option
from core.files import atomic_dir
from core.io.image import write_image
from data_synth.scenes import build_scene

NAME = "render"
OUTPUT = "file"
HELP = "render one view of a scene (and its ground-truth depth, normals, ids)"
log = logging.getLogger("scanamp")


def companions(args, config=None):
    return [str(args.out)[:-4] + ".gt"] if config.gt else []


def _floats(text, n, flag):
    try:
        vals = [float(x) for x in text.split(",")]
    except ValueError:
        raise ValueError(f"{flag}: expected {n} comma-separated numbers, got {text!r}") from None
    if len(vals) != n:
        raise ValueError(f"{flag}: expected {n} comma-separated numbers, got {text!r}")
    return vals


@dataclass
class RenderConfig(Config):
    """Options of ``scanamp render``."""

    view: str | None = option(None, help="camera as 'ex,ey,ez,tx,ty,tz' (eye and target, "
                                         "metres); default: a view of the whole scene")
    size: str = option("640x480", unit="px", help="WIDTHxHEIGHT")
    fov: float = option(50.0, unit="deg", range="(0, 180)", help="horizontal field of view")
    supersample: int = option(2, range="[1, 8]", help="samples per pixel side")
    seed: int = option(0, range="[0, inf)", help="sensor noise seed")
    noise: bool = option(True, help="the sensor's noise (--no-noise: an ideal sensor)")
    gt: bool = option(False, help="also write NAME.gt/ with depth.npy, normals.npy, ids.npy, "
                                  "mask.npy")


CONFIG = RenderConfig


def add_arguments(p):
    p.add_argument("scene", help="scene folder, built-in name or .toml spec")
    p.add_argument("--out", required=True, help="output PNG")


def default_view(bounds):
    lo, hi = bounds
    c = (lo + hi) / 2
    r = np.linalg.norm(hi - lo)
    return c + r * np.array([0.35, -0.95, 0.55]), c


def run(args, config: RenderConfig):
    try:
        w, h = (int(x) for x in config.size.lower().split("x"))
    except ValueError:
        raise ValueError(f"--size: expected WIDTHxHEIGHT, got {config.size!r}") from None
    if not (0 < w <= 16384 and 0 < h <= 16384):
        raise ValueError(f"--size: expected WIDTHxHEIGHT between 1 and 16384, got {config.size!r}")
    if not str(args.out).lower().endswith(".png"):
        raise ValueError(f"--out: expected a .png path, got {args.out!r}")
    bundle = build_scene(args.scene)
    if config.view:
        v = _floats(config.view, 6, "--view")
        eye, target = np.array(v[:3]), np.array(v[3:])
    else:
        eye, target = default_view(bundle.bounds())
    cam = Camera.look_at(eye, target, width=w, height=h, fov_deg=config.fov)
    r = render(bundle.render_scene, cam, supersample=config.supersample)
    sensor = Sensor() if config.noise else Sensor.ideal()
    img = sensor.apply(r.radiance, np.random.default_rng(config.seed))
    write_image(args.out, img)
    if config.gt:
        from pathlib import Path

        gt = Path(str(args.out)[:-4] + ".gt")
        with atomic_dir(gt) as tmp:
            np.save(tmp / "depth.npy", r.depth)
            np.save(tmp / "normals.npy", r.normals)
            np.save(tmp / "ids.npy", r.object_id)
            np.save(tmp / "mask.npy", r.mask)
    log.info("rendered %r from %s -> %s (%d%% of pixels hit)", bundle.name,
             np.round(eye, 3).tolist(), args.out, round(100 * r.mask.mean()))
    return 0
