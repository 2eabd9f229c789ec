"""``scanamp clean DIR [--dry-run]``: remove what killed runs of scanamp left under DIR.

An output is written into a temporary sibling and renamed into place, and a study's runs
work in scratch folders under the study folder; a run killed outright (SIGKILL, a power
cut) leaves them behind. This removes those names of ours (:func:`core.files.stale_temporaries`:
``.NAME.scanamp-tmp-XXXXXXXX``, ``.NAME.scanamp-old-XXXXXXXX``, ``.NAME.scanamp-lock``,
``.scanamp-scratch-XXXXXXXX``) that no running process holds, and nothing else: a user's
file with a similar name is kept. Each removed path is printed, one a line.
"""

from __future__ import annotations

import logging
import sys
from dataclasses import dataclass
from pathlib import Path

from core.config import Config, option

NAME = "clean"
HELP = ("remove the temporary files and scratch folders that killed scanamp runs left under "
        "a folder (only scanamp's own, never one in use)")

log = logging.getLogger("scanamp")


@dataclass(frozen=True)
class CleanConfig(Config):
    """The options of ``scanamp clean``."""

    dry_run: bool = option(False, help="print what would be removed and remove nothing")


CONFIG = CleanConfig


def add_arguments(p):
    p.add_argument("folder", type=Path, help="the folder to clean (searched recursively)")


def run(args, config: CleanConfig) -> int:
    from core.files import remove_stale, stale_temporaries
    from core.validate import InputError

    if not args.folder.is_dir():
        raise InputError("is not a folder", path=args.folder)
    found = stale_temporaries(args.folder) if config.dry_run else remove_stale(args.folder)
    for p in found:
        sys.stdout.write(f"{p}\n")
    log.info("%s %d stale temporar%s under %s", "found" if config.dry_run else "removed",
             len(found), "y" if len(found) == 1 else "ies", args.folder)
    return 0
