"""``scanamp capture KIND SCENE --out DIR``: a virtual capture of a scene, one ``KIND`` per
registered acquisition method (:mod:`scanamp.methods`); the options are the method's capture
config (flags, or ``--config FILE.toml``), its help the method module's docstring."""

from __future__ import annotations

import logging
from pathlib import Path
from types import SimpleNamespace

import numpy as np

log = logging.getLogger("scanamp")


def commands():
    """One ``capture`` command per registered method."""
    from scanamp.methods import methods

    return [_command(m) for m in methods().values()]


def _command(method) -> SimpleNamespace:
    def add_arguments(p):
        p.add_argument("scene", help="built-in scene name (e.g. 'object'), scene folder or "
                                     ".toml spec")
        p.add_argument("--out", required=True, type=Path, help="capture folder to write")

    def run(args, config) -> int:
        from scanamp.methods import scene_for_capture

        bundle = method.scene(scene_for_capture(args.scene), config)
        out = method.capture(bundle, config, args.out,
                             rng=np.random.default_rng(config.seed), seed=config.seed,
                             scene_path=args.scene)
        log.info("%s capture of %r -> %s", method.name, bundle.name, out)
        return 0

    return SimpleNamespace(GROUP="capture", NAME=method.name, HELP=method.capture_help,
                           CONFIG=method.capture_config, add_arguments=add_arguments, run=run)
