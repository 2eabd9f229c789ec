"""``scanamp reconstruct KIND INPUT... --out DIR``: a capture (or real data) reconstructed,
one ``KIND`` per registered acquisition method (:mod:`scanamp.methods`); the options are
the method's reconstruction config (flags, or ``--config FILE.toml``), the inputs and any
further flags the method's (``--from STAGE`` for the staged pipelines). An algorithm that
failed exits 1 with its diagnosis."""

from __future__ import annotations

import logging
from pathlib import Path
from types import SimpleNamespace

log = logging.getLogger("scanamp")


def commands():
    """One ``reconstruct`` command per registered method."""
    from scanamp.methods import methods

    return [_command(m) for m in methods().values()]


def _command(method) -> SimpleNamespace:
    def add_arguments(p):
        method.add_reconstruct_arguments(p)
        p.add_argument("--out", required=True, type=Path, help="reconstruction folder to write")

    def run(args, config) -> int:
        result = method.reconstruct_from_args(config, args)
        if not result.ok:
            raise RuntimeError(result.message)
        for line in method.describe(result):
            log.info("%s", line)
        return 0

    return SimpleNamespace(GROUP="reconstruct", NAME=method.name, HELP=method.reconstruct_help,
                           CONFIG=method.recon_config, add_arguments=add_arguments, run=run)
