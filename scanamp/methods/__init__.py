"""The registry of acquisition methods: one module per method, one protocol for all.

Every module of this room that defines ``METHOD`` (an instance of
:class:`~scanamp.methods.protocol.Method`) is a method: ``laser``, ``lidar``, ``scans``,
``sfm``, ``stereo``, ``structured_light``. The ``scanamp capture KIND`` and ``scanamp
reconstruct KIND`` commands, the study kinds (:data:`scanamp.study.KINDS`) and the demo
find methods here and nowhere else, so adding a method is adding one module (and its
tests): docs/architecture.md says how.

>>> sorted(methods())
['laser', 'lidar', 'scans', 'sfm', 'stereo', 'structured-light']
>>> get_method("stereo").recon_config.__name__
'StereoOptions'
"""

from __future__ import annotations

import contextlib
import importlib
import pkgutil
from collections.abc import Iterator

from scanamp.methods.protocol import Method, scene_for_capture

__all__ = ["Method", "methods", "get_method", "registered", "scene_for_capture"]

_REGISTRY: dict[str, Method] = {}


def _discover() -> dict[str, Method]:
    found: dict[str, Method] = {}
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda i: i.name):
        if info.name.startswith("_"):
            continue
        method = getattr(importlib.import_module(f"{__name__}.{info.name}"), "METHOD", None)
        if method is None:
            continue
        if not isinstance(method, Method):
            raise TypeError(f"{__name__}.{info.name}.METHOD: expected a Method, got "
                            f"{type(method).__name__}")
        if method.name in found:
            raise ValueError(f"{__name__}.{info.name}: method name {method.name!r} taken")
        found[method.name] = method
    return found


def methods() -> dict[str, Method]:
    """Every registered method by name (the room's modules, found on first use)."""
    if not _REGISTRY:
        _REGISTRY.update(_discover())
    return dict(_REGISTRY)


def get_method(name: str) -> Method:
    """The method ``name``; ValueError listing the registered ones otherwise."""
    from core.validate import check_choice

    found = methods()
    return found[check_choice(name, "method", found)]


@contextlib.contextmanager
def registered(*extra: Method) -> Iterator[dict[str, Method]]:
    """A temporary registry: the methods of this room plus ``extra`` while the block runs
    (the commands, study kinds and demo see them), the room's alone again after it."""
    base = methods()
    clash = [m.name for m in extra if m.name in base]
    if clash:
        raise ValueError(f"method name {clash[0]!r} is taken")
    _REGISTRY.update({m.name: m for m in extra})
    try:
        yield dict(_REGISTRY)
    finally:
        _REGISTRY.clear()
        _REGISTRY.update(base)
