"""``scanamp simulate cloth RECIPE [--mesh M.ply] --out DIR`` (options as for particles)."""

from __future__ import annotations

from scanamp.cli.simulate_particles import SimulationOptions, add_arguments, run_kind

GROUP = "simulate"
NAME = "cloth"
CONFIG = SimulationOptions
HELP = "run a cloth recipe (e.g. drape over a scan) and write VTP/.pvd, PLY, MP4 and report.json"

__all__ = ["add_arguments", "run"]


def run(args, config: SimulationOptions) -> int:
    return run_kind("cloth", args, config)
