"""Command-line flags generated from a command's config dataclass (see :mod:`core.config`).

Why our own generator over argparse rather than tyro: the declared fields already carry
help, unit, range and choices, and the CLI has its own contract (one-line ``error:``
messages with exit 2, ``--config FILE.toml`` merged under the flags, dotted names for
nested options that match the TOML tables and the study override keys). A hundred
lines over argparse keep that contract without a dependency whose error output and
nesting rules we would have to bend.

Every declared option ``name`` of the config becomes ``--name`` (underscores as
hyphens; nested options dotted, ``--meshing.depth``); booleans get ``--x/--no-x``;
tuples take comma-separated values; ``--help`` shows each default, unit and range.
Precedence: the dataclass defaults, then ``--config FILE.toml``, then the flags given.
"""

from __future__ import annotations

import argparse
import typing
from pathlib import Path

from core.config import format_value, iter_options, load_config, unwrap_optional, with_options

__all__ = ["add_config_flags", "config_from_args", "flag_name"]

_PREFIX = "opt:"


def flag_name(option_name: str) -> str:
    """``meshing.density_quantile`` -> ``--meshing.density-quantile``."""
    return "--" + option_name.replace("_", "-")


def _parser_for(tp):
    tp, optional = unwrap_optional(tp)
    origin = typing.get_origin(tp)
    if tp in (tuple, list) or origin in (tuple, list):
        args = [a for a in typing.get_args(tp) if a is not Ellipsis]
        item = _parser_for(args[0]) if args else str

        def parse_seq(text: str):
            if optional and text.lower() == "none":
                return None
            return [item(x) for x in text.split(",") if x.strip() != ""]

        return parse_seq
    base = {int: int, float: float, str: str}.get(tp, str)
    if not optional:
        return base

    def parse_opt(text: str):
        return None if text.lower() == "none" else base(text)

    return parse_opt


def _help(opt) -> str:
    parts = [opt.help.rstrip(".")]
    extras = []
    if opt.unit:
        extras.append(opt.unit)
    extras.append(f"default {format_value(opt.default) if opt.default is not None else 'none'}")
    if opt.range:
        extras.append(f"range {opt.range}")
    if opt.choices:
        extras.append("one of " + ", ".join(str(c) for c in opt.choices))
    return (f"{parts[0]} ({'; '.join(extras)})").replace("%", "%%")


def add_config_flags(parser: argparse.ArgumentParser, cls, *,
                     title: str = "configuration (flags, or --config FILE.toml)") -> None:
    """Add ``--config FILE.toml`` and one flag per declared option of config ``cls``."""
    parser.add_argument("--config", type=Path, default=None, metavar="FILE.toml",
                        help="read the options from a TOML file with the same names "
                             "(nested options as tables); flags given here win")
    group = parser.add_argument_group(title)
    for opt in iter_options(cls):
        if not opt.flag:
            continue
        tp, _ = unwrap_optional(opt.type)
        kw = dict(dest=_PREFIX + opt.name, default=argparse.SUPPRESS, help=_help(opt))
        if tp is bool:
            group.add_argument(flag_name(opt.name), action=argparse.BooleanOptionalAction, **kw)
            continue
        if opt.choices is not None and typing.get_origin(tp) not in (tuple, list):
            kw["choices"] = list(opt.choices)
        metavar = ("{" + ",".join(map(str, opt.choices)) + "}" if "choices" in kw
                   else opt.name.rsplit(".", 1)[-1].upper())
        names = [flag_name(opt.name)] + ([opt.short] if opt.short else [])
        if opt.metavar:  # a fixed-length tuple given as separate values: --center RE IM
            items = [a for a in typing.get_args(tp) if a is not Ellipsis]
            group.add_argument(*names, type=_parser_for(items[0] if items else str),
                               nargs=len(opt.metavar), metavar=opt.metavar, **kw)
            continue
        group.add_argument(*names, type=_parser_for(opt.type), metavar=metavar, **kw)


def given_options(args: argparse.Namespace) -> dict:
    """The options given as flags, by dotted name."""
    return {k[len(_PREFIX):]: v for k, v in vars(args).items() if k.startswith(_PREFIX)}


def config_from_args(cls, args: argparse.Namespace):
    """The effective config: defaults, then ``--config FILE.toml``, then the given flags.

    Errors are :class:`core.validate.InputError` naming the file (or the flag) and field.
    """
    from core.validate import InputError

    obj = load_config(cls, getattr(args, "config", None))
    given = given_options(args)
    if given:
        try:
            obj = with_options(obj, given, path="command line")
        except InputError as exc:  # name the flag the user typed: --meshing.depth
            if exc.path != "command line" or not exc.field:
                raise
            raise InputError(exc.message, field=flag_name(exc.field)) from None
    return obj

