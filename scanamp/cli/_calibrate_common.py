"""Arguments shared by ``scanamp calibrate camera`` and ``scanamp calibrate stereo``."""

from __future__ import annotations

import argparse
from pathlib import Path

from acquire.targets import TARGET_SPEC_HELP


def add_board_arguments(p: argparse.ArgumentParser, *, out_name: str, out_help: str) -> None:
    """``--board`` and ``--out`` (``--dist-model`` is the command's declared option)."""
    p.add_argument("--board", required=True, metavar="SPEC", help=TARGET_SPEC_HELP)
    p.add_argument("--out", required=True, type=Path, metavar=out_name,
                   help=f"{out_help}; its report (NAME_report.json) is written beside it")


def report_path(out: Path) -> Path:
    """``camera.yaml`` -> ``camera_report.json``."""
    return out.with_name(out.stem + "_report.json")
