"""Lazy public names for a package: ``from room import name`` loads only the module that
defines ``name`` (PEP 562), so a room's ``__init__`` can name its whole public API without
importing numba kernels, OpenCV or pycolmap for a caller that needs one small module.

>>> getattr_, dir_ = lazy_exports("core", {"check_array": "validate"})
>>> getattr_("check_array").__name__
'check_array'
>>> "check_array" in dir_()
True
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping

__all__ = ["lazy_exports"]


def lazy_exports(package: str, exports: Mapping[str, str]) -> tuple[Callable, Callable]:
    """``(__getattr__, __dir__)`` for ``package`` serving ``exports`` (name -> module within
    the package) on first use."""
    exports = dict(exports)

    def __getattr__(name: str):
        if name not in exports:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module = importlib.import_module(f"{package}.{exports[name]}")
        return getattr(module, name)

    def __dir__() -> list[str]:
        return sorted(exports)

    return __getattr__, __dir__
