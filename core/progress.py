"""Progress for long work, without the library ever printing.

Library code wraps long loops in :func:`track`. By default that only logs at
DEBUG level; the CLI calls :func:`enable` so the user sees a tqdm bar on stderr.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Iterator
from typing import TypeVar

T = TypeVar("T")
_log = logging.getLogger(__name__)
_enabled = False

__all__ = ["track", "enable", "enabled"]


def enable(on: bool = True) -> None:
    """Show progress bars (the CLI decides; libraries never call this)."""
    global _enabled
    _enabled = bool(on)


def enabled() -> bool:
    return _enabled


def track(iterable: Iterable[T], desc: str, *, total: int | None = None) -> Iterator[T]:
    """Iterate ``iterable``, showing a bar named ``desc`` when progress is enabled."""
    if _enabled:
        from tqdm import tqdm

        yield from tqdm(iterable, desc=desc, total=total, leave=False, dynamic_ncols=True)
        return
    _log.debug("%s: started", desc)
    yield from iterable
    _log.debug("%s: done", desc)
