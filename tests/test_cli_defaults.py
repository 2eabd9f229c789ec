"""Configuration declared once (issue 14): a command's options are its config dataclass.

The CLI's defaults cannot drift from the library's: with no flags, a command's effective
config equals its dataclass's defaults; every generated flag's help shows its default
(and unit where it has one); every command declares its options so.
"""

from __future__ import annotations

import argparse
import dataclasses

import pytest

from core.config import iter_options
from scanamp.cli import build_parser, config_from_args


def _commands():
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name, p in sub.choices.items():
        if p.get_default("_run") is not None:
            yield name, p
            continue
        inner = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction))
        for kind, q in inner.choices.items():
            yield f"{name} {kind}", q


COMMANDS = dict(_commands())


def _minimal_argv(p: argparse.ArgumentParser) -> list[str]:
    argv = []
    for a in p._actions:
        if a.option_strings and a.required:
            argv += [a.option_strings[0], "x"]
        elif not a.option_strings and a.nargs not in ("?", "*"):
            value = str(a.choices[0]) if a.choices else "x"  # a positional with choices
            argv += [value] * (a.nargs if isinstance(a.nargs, int) else 1)
    return argv


def test_every_command_is_declared():
    undeclared = sorted(n for n, p in COMMANDS.items() if p.get_default("_config_cls") is None)
    assert not undeclared, f"commands must declare CONFIG: {undeclared}"
    assert len(COMMANDS) >= 23 and {"reconstruct laser", "capture laser"} <= set(COMMANDS)


@pytest.mark.parametrize("name", sorted(n for n, p in COMMANDS.items()
                                        if p.get_default("_config_cls") is not None))
def test_cli_defaults_are_the_dataclass_defaults(name):
    p = COMMANDS[name]
    cls = p.get_default("_config_cls")
    args = p.parse_args(_minimal_argv(p))
    got = config_from_args(cls, args)
    assert dataclasses.asdict(got) == dataclasses.asdict(cls())
    helps = {a.dest: a.help or "" for a in p._actions}
    for opt in iter_options(cls):
        if not opt.flag:
            continue
        text = helps["opt:" + opt.name]
        assert "default" in text, (name, opt.name)
        if opt.unit:
            assert opt.unit in text, (name, opt.name)
