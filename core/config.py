"""Configuration declared once: each option is a dataclass field that carries its own
help, unit, range and choices; TOML in and out; dotted overrides.

A config class is a dataclass that derives from :class:`Config` and declares its fields
with :func:`option`::

    @dataclass(frozen=True)
    class MeshingOptions(Config):
        depth: int = option(9, help="Poisson octree depth", range="[4, 12]")
        trim_distance: float = option(0.0, unit="m", help="...", range="[0, inf)")

Everything else reads the declaration: :func:`check_config` (called by
``Config.__post_init__``) validates types, ranges and choices; :func:`from_dict` and
:func:`load_config` read TOML tables with the same field names (nested configs are
sub-tables), naming the file and the dotted field on error; :func:`to_dict` writes the
effective config back (``config.toml`` in every output folder); :func:`with_options`
applies dotted overrides (``{"meshing.depth": 10}``), as study sweeps and CLI flags do;
:func:`iter_options` walks the declared options for the CLI's flag generator.

>>> from dataclasses import dataclass
>>> @dataclass(frozen=True)
... class Demo(Config):
...     steps: int = option(8, help="frames", range="[1, 1000]")
...     angle_deg: float = option(30.0, unit="deg", help="tilt", range="(0, 90)")
>>> to_dict(with_options(Demo(), {"steps": 12}))
{'steps': 12, 'angle_deg': 30.0}
>>> Demo(angle_deg=90)
Traceback (most recent call last):
...
ValueError: angle_deg: expected a value in (0, 90), got 90.0
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
import types
import typing
from collections.abc import Iterator, Sequence
from dataclasses import MISSING, dataclass
from pathlib import Path
from typing import Any

from core.files import read_toml, write_toml
from core.validate import InputError

__all__ = ["Config", "option", "Option", "check_config", "from_dict", "load_config", "to_dict",
           "with_options", "iter_options", "write_config", "parse_range", "format_value",
           "unwrap_optional"]

_RANGE = re.compile(r"^\s*([\[(])\s*([^,]+?)\s*,\s*([^,]+?)\s*([\])])\s*$")


def parse_range(text: str) -> tuple[float, float, bool, bool]:
    """``"(0, inf)"`` -> ``(lo, hi, lo_open, hi_open)``; brackets say closed or open."""
    m = _RANGE.match(text)
    if not m:
        raise ValueError(f"range: expected an interval such as '[0, 1)' or '(0, inf)', "
                         f"got {text!r}")
    lo, hi = float(m.group(2)), float(m.group(3))
    return lo, hi, m.group(1) == "(", m.group(4) == ")"


def option(default: Any = MISSING, *, help: str, unit: str | None = None,
           range: str | None = None, choices: Sequence[Any] | None = None,
           default_factory: Any = MISSING, flag: bool = True,
           short: str | None = None, metavar: tuple[str, ...] | None = None) -> Any:
    """A declared option: a dataclass field whose metadata documents and bounds it.

    Parameters
    ----------
    default, default_factory
        As for :func:`dataclasses.field` (a nested config uses ``default_factory``).
    help : str
        One sentence for ``--help`` and the docs.
    unit : str, optional
        ``"m"``, ``"deg"``, ``"px"``, ``"8-bit"``... shown in ``--help``.
    range : str, optional
        Allowed interval, ``"[lo, hi]"`` with ``(``/``)`` for open ends and ``inf``.
    choices : sequence, optional
        Allowed values (strings), listed in every error message.
    flag : bool
        False keeps the option out of the generated command-line flags (it is still
        read from ``--config FILE.toml``); for tables such as a calibration target.
    short : str, optional
        A short flag besides the long one (``"-n"``), where a command has always had it.
    metavar : tuple of str, optional
        For a fixed-length tuple: the flag takes that many space-separated values with
        these names (``--center RE IM``) instead of one comma-separated value.
    """
    if range is not None:
        parse_range(range)
    meta = {"help": help, "unit": unit, "range": range,
            "choices": None if choices is None else tuple(choices), "flag": flag,
            "short": short, "metavar": None if metavar is None else tuple(metavar)}
    if default_factory is not MISSING:
        return dataclasses.field(default_factory=default_factory, metadata={"scanamp": meta})
    return dataclasses.field(default=default, metadata={"scanamp": meta})


@dataclass(frozen=True)
class Option:
    """One declared option, as :func:`iter_options` yields it.

    ``name`` is dotted from the top config (``meshing.depth``); ``type`` is the field's
    resolved type; ``default`` its default value.
    """

    name: str
    type: Any
    default: Any
    help: str
    unit: str | None
    range: str | None
    choices: tuple | None
    flag: bool
    short: str | None = None
    metavar: tuple | None = None


def _hints(cls) -> dict:
    return typing.get_type_hints(cls)


def unwrap_optional(tp) -> tuple[Any, bool]:
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if len(args) == 1 and len(typing.get_args(tp)) == 2:
            return args[0], True
    return tp, False


def _is_config(tp) -> bool:
    return isinstance(tp, type) and dataclasses.is_dataclass(tp)


def _default(f: dataclasses.Field) -> Any:
    if f.default is not MISSING:
        return f.default
    if f.default_factory is not MISSING:
        return f.default_factory()
    return MISSING


def iter_options(cls_or_obj, prefix: str = "") -> Iterator[Option]:
    """Every declared option of a config class (or instance: its values as defaults),
    nested configs flattened to dotted names."""
    cls = cls_or_obj if isinstance(cls_or_obj, type) else type(cls_or_obj)
    hints = _hints(cls)
    for f in dataclasses.fields(cls):
        if not f.init:
            continue
        meta = f.metadata.get("scanamp")
        tp, _ = unwrap_optional(hints[f.name])
        value = (_default(f) if isinstance(cls_or_obj, type)
                 else getattr(cls_or_obj, f.name))
        name = f"{prefix}{f.name}"
        if _is_config(tp) and meta is not None and meta.get("flag", True):
            yield from iter_options(value if value is not MISSING else tp, prefix=name + ".")
            continue
        if meta is None:
            continue
        yield Option(name, hints[f.name], value, meta["help"], meta["unit"], meta["range"],
                     meta["choices"], meta["flag"], meta.get("short"), meta.get("metavar"))


def format_value(value: Any) -> str:
    """A value as a user writes it on the command line (tuples comma-separated)."""
    if isinstance(value, (tuple, list)):
        return ",".join(format_value(v) for v in value)
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


# ---------------------------------------------------------------------------- checking
def _type_name(tp) -> str:
    tp, opt = unwrap_optional(tp)
    origin = typing.get_origin(tp)
    names = {float: "a number", int: "an integer", str: "a string", bool: "true or false",
             dict: "a table"}
    if origin in (tuple, list) or tp in (tuple, list):
        base = "a list"
    elif _is_config(tp):
        base = "a table"
    else:
        base = names.get(tp, getattr(tp, "__name__", str(tp)))
    return base + (" or nothing" if opt else "")


def _coerce(value: Any, tp, name: str) -> Any:
    """``value`` converted to the declared type, or ValueError naming ``name``."""
    tp, optional = unwrap_optional(tp)
    if value is None:
        if optional:
            return None
        raise ValueError(f"{name}: expected {_type_name(tp)}, got None")
    origin = typing.get_origin(tp)
    bad = ValueError(f"{name}: expected {_type_name(tp)}, got {value!r}")
    if tp is bool:
        if not isinstance(value, bool):
            raise bad
        return value
    if isinstance(value, bool) and tp in (int, float, str):
        raise bad
    if tp is int:
        if isinstance(value, float) and value.is_integer():
            return int(value)
        if not isinstance(value, int):
            raise bad
        return int(value)
    if tp is float:
        if not isinstance(value, (int, float)):
            raise bad
        return float(value)
    if tp is str:
        if not isinstance(value, str):
            raise bad
        return value
    if tp in (tuple, list) or origin in (tuple, list):
        if not isinstance(value, (tuple, list)):
            raise bad
        args = typing.get_args(tp)
        if args and args[-1] is not Ellipsis and len(args) != len(value):
            raise ValueError(f"{name}: expected {len(args)} values, got {len(value)}")
        item = args[0] if args else None
        if item is not None:
            value = [_coerce(v, item, f"{name}[{i}]") for i, v in enumerate(value)]
        return tuple(value) if (tp is tuple or origin is tuple) else list(value)
    if tp is dict or origin is dict:
        if not isinstance(value, dict):
            raise bad
        return value
    return value


def _check_bounds(value: Any, name: str, meta: dict) -> None:
    if meta.get("choices") is not None and value is not None:
        allowed = meta["choices"]
        items = value if isinstance(value, (tuple, list)) else (value,)
        for v in items:
            if v not in allowed:
                listed = ", ".join(repr(a) for a in allowed)
                raise ValueError(f"{name}: expected one of {listed}, got {v!r}")
    if meta.get("range") and value is not None:
        lo, hi, lo_open, hi_open = parse_range(meta["range"])
        items = value if isinstance(value, (tuple, list)) else (value,)
        for v in items:
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                continue
            if (not math.isfinite(v) or (v <= lo if lo_open else v < lo)
                    or (v >= hi if hi_open else v > hi)):
                raise ValueError(f"{name}: expected a value in {meta['range']}, got {v!r}")


def check_config(obj) -> None:
    """Validate (and coerce in place) every declared field of a config instance.

    Raises ValueError ``field: expected ..., got ...`` for the first field at fault.
    """
    hints = _hints(type(obj))
    for f in dataclasses.fields(obj):
        meta = f.metadata.get("scanamp")
        if meta is None:
            continue
        value = getattr(obj, f.name)
        tp, _ = unwrap_optional(hints[f.name])
        if _is_config(tp):
            if value is not None and not isinstance(value, tp):
                raise ValueError(f"{f.name}: expected {tp.__name__}, got "
                                 f"{type(value).__name__}")
            continue
        new = _coerce(value, hints[f.name], f.name)
        _check_bounds(new, f.name, meta)
        if new is not value:
            object.__setattr__(obj, f.name, new)


class Config:
    """Base of the config dataclasses: ``__post_init__`` validates the declared options.

    A subclass that checks more (relations between fields) extends ``__post_init__`` and
    calls ``super().__post_init__()`` first.
    """

    def __post_init__(self):
        check_config(self)


# ---------------------------------------------------------------------------- TOML in/out
def _field_error(exc: Exception, prefix: str) -> tuple[str, str]:
    msg = str(exc)
    head, sep, rest = msg.partition(": ")
    if sep and re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*(\[\d+\])?", head):
        return f"{prefix}{head}", rest
    return prefix.rstrip("."), msg


def from_dict(cls, table: Any, *, path: str | os.PathLike | None = None, prefix: str = ""):
    """An instance of config class ``cls`` from a (TOML) table with the same field names.

    Missing keys take their defaults; nested configs are sub-tables. Unknown keys, wrong
    types and out-of-range values raise :class:`InputError` naming ``path`` and the
    dotted field.
    """
    where = prefix.rstrip(".") or None
    if not isinstance(table, dict):
        raise InputError(f"expected a table, got {table!r}", path=path, field=where)
    hints = _hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    kwargs = {}
    for key, value in table.items():
        if key not in fields:
            raise InputError(f"unknown option; expected one of {', '.join(sorted(fields))}",
                             path=path, field=f"{prefix}{key}")
        tp, _ = unwrap_optional(hints[key])
        if _is_config(tp) and isinstance(value, dict):
            base = _default(fields[key])  # a nested default may differ from its class's
            if dataclasses.is_dataclass(base) and not isinstance(base, type):
                value = {**to_dict(base), **value}
            value = from_dict(tp, value, path=path, prefix=f"{prefix}{key}.")
        kwargs[key] = value
    try:
        return cls(**kwargs)
    except InputError:
        raise
    except (TypeError, ValueError) as exc:
        field, msg = _field_error(exc, prefix)
        raise InputError(msg, path=path, field=field or None) from None


def load_config(cls, path: str | os.PathLike | None = None, **overrides):
    """Read config ``cls`` from a TOML file (None: the defaults), then dotted overrides."""
    obj = cls() if path is None else from_dict(cls, read_toml(path), path=path)
    return with_options(obj, overrides, path=path) if overrides else obj


def to_dict(obj) -> dict:
    """The config as a TOML-ready table (tuples as lists, nested configs as tables;
    options that are None are left out, so they read back as their default None)."""
    out = {}
    for f in dataclasses.fields(obj):
        if not f.init:
            continue
        value = getattr(obj, f.name)
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            out[f.name] = to_dict(value)
        elif value is None:
            continue
        else:
            out[f.name] = _plain(value)
    return out


def _plain(value):
    if isinstance(value, (tuple, list)):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, Path):
        return str(value)
    if hasattr(value, "item") and not isinstance(value, (str, bytes)):  # numpy scalar
        return value.item()
    return value


def write_config(path: str | os.PathLike, obj) -> Path:
    """Write the effective config as TOML (atomically)."""
    return write_toml(path, to_dict(obj))


def with_options(obj, options: dict, *, path: str | os.PathLike | None = None,
                 prefix: str = ""):
    """A copy of config ``obj`` with dotted ``options`` (``{"meshing.depth": 10}``) set.

    Raises :class:`InputError` naming the dotted field for unknown names, wrong types
    and values the config rejects.
    """
    names = {f.name for f in dataclasses.fields(obj) if f.init}
    nested: dict[str, dict] = {}
    flat: dict = {}
    for key, value in options.items():
        head, _, rest = key.partition(".")
        if head not in names:
            raise InputError(f"unknown option; expected one of {', '.join(sorted(names))}",
                             path=path, field=f"{prefix}{head}")
        cur = getattr(obj, head)
        if rest:
            if not (dataclasses.is_dataclass(cur) and not isinstance(cur, type)):
                raise InputError("not a table of options", path=path, field=f"{prefix}{head}")
            nested.setdefault(head, {})[rest] = value
        elif dataclasses.is_dataclass(cur) and isinstance(value, dict):
            flat[head] = from_dict(type(cur), {**to_dict(cur), **value}, path=path,
                                   prefix=f"{prefix}{head}.")
        else:
            flat[key] = value
    for head, sub in nested.items():
        flat[head] = with_options(getattr(obj, head), sub, path=path, prefix=f"{prefix}{head}.")
    try:
        return dataclasses.replace(obj, **flat)
    except InputError:
        raise
    except (TypeError, ValueError) as exc:
        field, msg = _field_error(exc, prefix)
        raise InputError(msg, path=path, field=field or None) from None
