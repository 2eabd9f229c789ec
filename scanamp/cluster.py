"""A Dask scheduler to run work on: the study runner's runs and a LiDAR survey's legs.

Both accept ``--scheduler tcp://host:8786``; :func:`connect` gives them the same client
and the same one-line error when the scheduler cannot be reached.
"""

from __future__ import annotations

import logging

from core.validate import InputError

__all__ = ["connect"]


def connect(scheduler: str, *, timeout: float = 5.0):
    """A ``dask.distributed.Client`` on ``scheduler``; InputError if unreachable."""
    try:
        from distributed import Client
    except ImportError:  # pragma: no cover
        raise InputError("needs dask.distributed (pip install 'dask[distributed]')",
                         field="--scheduler") from None
    logging.getLogger("distributed").setLevel(logging.CRITICAL)
    try:
        return Client(scheduler, timeout=f"{timeout}s", set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"cannot reach the Dask scheduler {scheduler!r} within {timeout:g} s "
                         f"({reason[:160]})", field="--scheduler") from None
