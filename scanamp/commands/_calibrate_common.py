"""Arguments shared by ``scanamp calibrate camera`` and ``scanamp calibrate stereo``."""

from __future__ import annotations

import argparse
from pathlib import Path

from acquire.targets import TARGET_SPEC_HELP


def add_board_arguments(p: argparse.ArgumentParser, *, out_name: str, out_help: str,
                        dist_default: str) -> None:
    """``--board``, ``--out`` and ``--dist-model``."""
    p.add_argument("--board", required=True, metavar="SPEC", help=TARGET_SPEC_HELP)
    p.add_argument("--out", required=True, type=Path, metavar=out_name,
                   help=f"{out_help}; its report (NAME_report.json) is written beside it")
    p.add_argument("--dist-model", choices=("k1k2", "k1k2p1p2", "full"), default=dist_default,
                   help=f"distortion terms estimated (default {dist_default}: "
                        + ("radial only)" if dist_default == "k1k2" else
                           "radial + tangential)"))


def report_path(out: Path) -> Path:
    """``camera.yaml`` -> ``camera_report.json``."""
    return out.with_name(out.stem + "_report.json")
